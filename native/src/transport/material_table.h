// The materials' lobes flattened for the hot loops (docs/design.md
// "Materials"), and how each material lets straight rays through:
//   Opaque       blocks shadow and gather rays
//   Transparent  every lobe is TRANSPARENT: a straight ray passes, weight
//                the lobes' summed tint
//   Pane         one smooth GLASS or REFRACTION lobe without dispersion: a
//                straight ray that enters one face and leaves by the next,
//                a parallel face turned the other way, passes with the
//                weight of the refraction in and out (transport/passage.h).
// A diffuse albedo beside these lobes does not change the passage (its light
// is reflected, not passed).
#pragma once

#include <cstdint>
#include <vector>

#include "scene/scene.h"
#include "transport/bsdf.h"

namespace plm {

enum class Passage : uint8_t { Opaque, Transparent, Pane };

struct MaterialLobes {
  uint32_t first = 0, count = 0;  // into MaterialTable::lobes
  Passage passage = Passage::Opaque;
  Vec3 pass_tint{0, 0, 0};  // Transparent: the lobes' tint; Pane: the lobe's
  float pane_ior = 1.0f;
  bool pane_fresnel = false;  // Pane: a GLASS lobe (Fresnel transmission); REFRACTION passes its tint
  bool dispersive = false;    // a lobe has abbe > 0
};

// Dispersion of a lobe with abbe > 0 (thesis appendix A.1): Cauchy's
// n(lambda) = a + b / lambda^2 through n_d = ior at 587.6 nm and the Abbe
// number V_d = (n_d - 1) / (n_F - n_C) (F 486.1 nm, C 656.3 nm).
struct Cauchy {
  float a = 1.0f, b = 0.0f;  // lambda in micrometres
  float at(float lambda_um) const { return a + b / (lambda_um * lambda_um); }
};
Cauchy cauchy_fit(float ior_d, float abbe);

class MaterialTable {
 public:
  MaterialTable() = default;
  explicit MaterialTable(const Scene& scene);

  bool any_lobes() const { return !lobes_.empty(); }
  bool any_passage() const { return any_passage_; }
  bool any_dispersion() const { return any_dispersion_; }
  // Material id -> its entry (the engine's grey default when the scene has no materials).
  const MaterialLobes& material(uint32_t id) const { return id < materials_.size() ? materials_[id] : none_; }
  const bsdf::LobeParams& lobe(uint32_t i) const { return lobes_[i]; }
  const Cauchy& cauchy(uint32_t i) const { return cauchy_[i]; }
  // A lobe's index at wavelength lambda (micrometres), its ior when it does not disperse.
  float ior(uint32_t i, float lambda_um) const {
    return cauchy_[i].b != 0.0f && lambda_um > 0.0f ? cauchy_[i].at(lambda_um) : lobes_[i].ior;
  }

 private:
  std::vector<bsdf::LobeParams> lobes_;
  std::vector<Cauchy> cauchy_;
  std::vector<MaterialLobes> materials_;
  MaterialLobes none_;
  bool any_passage_ = false, any_dispersion_ = false;
};

}  // namespace plm

// The materials' lobes flattened for the hot loops (docs/design/materials.md),
// and how each material lets straight rays through:
//   Opaque       blocks shadow and gather rays
//   Transparent  every lobe is TRANSPARENT: a straight ray passes, weight
//                the lobes' summed tint
//   Pane         one smooth GLASS or REFRACTION lobe without dispersion: a
//                straight ray that enters one face and leaves by the next,
//                a parallel face turned the other way, passes with the
//                weight of the refraction in and out (transport/rays/passage.h).
// A diffuse albedo beside these lobes does not change the passage (its light
// is reflected, not passed). SPECULAR lobes (Cycles 4's Principled layer) get
// their energy tables here, and their materials the diffuse part's scale.
#pragma once

#include <cstdint>
#include <vector>

#include "scene/scene.h"
#include "transport/materials/bsdf.h"

namespace plm {

enum class Passage : uint8_t { Opaque, Transparent, Pane };

struct MaterialLobes {
  uint32_t first = 0, count = 0;  // into MaterialTable::lobes
  Passage passage = Passage::Opaque;
  Vec3 pass_tint{0, 0, 0};  // Transparent: the lobes' tint; Pane: the lobe's
  float pane_ior = 1.0f;
  bool pane_fresnel = false;  // Pane: a GLASS lobe (Fresnel transmission); REFRACTION passes its tint
  bool dispersive = false;    // a lobe has abbe > 0
  // SPECULAR layers: the diffuse part is scaled by diffuse_scale(layer_scale,
  // cos out); layer_mean is that scale's cosine-weighted mean (for choosing
  // the diffuse part). No layer: no table, mean 1.
  uint32_t layer_scale = kNoLayer;
  float layer_mean = 1.0f;
  // The diffuse part's model: Burley's roughness (plm_scene_set_material_diffuse),
  // < 0 for Lambert, and the table of its directional albedo
  // (bsdf::make_burley_albedo). view_scale: the table of the diffuse part's
  // radiance leaving at cos v over albedo x the texel's value (the final
  // gather's lookups): the layers' 1 - A times Burley's R(v) / R(1) (light
  // taken as arriving evenly); kNoLayer where that is 1 (Lambert, no layers).
  float burley = -1.0f;
  uint32_t burley_albedo = kNoLayer, view_scale = kNoLayer;
  static constexpr uint32_t kNoLayer = ~0u;
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

  // Lobes or a diffuse part that is not Lambert's: photons take the lobe loop.
  bool any_lobes() const { return !lobes_.empty() || any_burley_; }
  bool any_view_scale() const { return !view_scales_.empty(); }
  bool any_passage() const { return any_passage_; }
  bool any_dispersion() const { return any_dispersion_; }
  // Material id -> its entry (the engine's grey default when the scene has no materials).
  const MaterialLobes& material(uint32_t id) const { return id < materials_.size() ? materials_[id] : none_; }
  const bsdf::LobeParams& lobe(uint32_t i) const { return lobes_[i]; }
  const Cauchy& cauchy(uint32_t i) const { return cauchy_[i]; }
  // A SPECULAR lobe's energy table (bsdf::LayerTable).
  const bsdf::LayerTable& layer(uint32_t lobe) const { return layers_[layer_of_[lobe]]; }
  // The factor on a layered material's diffuse part for light leaving at cos_o (MaterialLobes::layer_scale).
  float diffuse_scale(uint32_t table, float cos_o) const {
    return bsdf::layer_lookup(diffuse_scales_.data() + size_t(table) * bsdf::kLayerNodes, cos_o);
  }
  // Burley's directional albedo over Lambert's at cos (MaterialLobes::burley_albedo).
  float burley_albedo(uint32_t table, float cos) const {
    return bsdf::layer_lookup(burley_albedos_.data() + size_t(table) * bsdf::kLayerNodes, cos);
  }
  // The diffuse radiance's factor toward cos v (MaterialLobes::view_scale).
  float view_scale(uint32_t table, float cos_v) const {
    return bsdf::layer_lookup(view_scales_.data() + size_t(table) * bsdf::kLayerNodes, cos_v);
  }
  // A lobe's index at wavelength lambda (micrometres), its ior when it does not disperse.
  float ior(uint32_t i, float lambda_um) const {
    return cauchy_[i].b != 0.0f && lambda_um > 0.0f ? cauchy_[i].at(lambda_um) : lobes_[i].ior;
  }

 private:
  std::vector<bsdf::LobeParams> lobes_;
  std::vector<Cauchy> cauchy_;
  std::vector<MaterialLobes> materials_;
  std::vector<uint32_t> layer_of_;  // per lobe: its LayerTable (SPECULAR lobes only)
  std::vector<bsdf::LayerTable> layers_;
  std::vector<float> diffuse_scales_;  // kLayerNodes a layered material
  std::vector<float> burley_albedos_;  // kLayerNodes a Burley material
  std::vector<float> view_scales_;     // kLayerNodes a layered or Burley material
  MaterialLobes none_;
  bool any_passage_ = false, any_dispersion_ = false, any_burley_ = false;
};

}  // namespace plm

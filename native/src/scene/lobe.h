// Specular lobes of a material (photonlm.h "Specular lobes",
// docs/design/materials.md, "Materials"): what the user gave, validated on the
// way in. The transport reads them flattened (transport/materials/material_table.h).
#pragma once

#include <cstddef>
#include <string>

#include "photonlm/photonlm.h"
#include "util/math.h"

namespace plm {

constexpr size_t kMaxLobes = 8;

struct Lobe {
  plm_lobe_type type = PLM_LOBE_GLOSSY;
  Vec3 color{1, 1, 1};  // tint; FRESNEL, SPECULAR: F0
  float weight = 1.0f;  // mix factor
  float roughness = 0.0f;  // Blender's: GGX alpha = roughness^2
  float ior = 1.5f;
  float abbe = 0.0f;  // GLASS, REFRACTION: Abbe number V_d, 0 = no dispersion

  // Every lobe but FRESNEL and SPECULAR (layers on top of the diffuse part)
  // counts against the diffuse albedo's energy budget.
  bool budgeted() const { return type != PLM_LOBE_FRESNEL && type != PLM_LOBE_SPECULAR; }
  bool refracts() const { return type == PLM_LOBE_GLASS || type == PLM_LOBE_REFRACTION; }
};

// The lobe type's name as the bridge and scene files spell it ("glossy", ...), or "unknown".
const char* lobe_type_name(int32_t type);

// Blender's defaults for a lobe of the given type (plm_lobe_default).
plm_lobe default_lobe(plm_lobe_type type);

}  // namespace plm

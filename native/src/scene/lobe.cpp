#include "scene/lobe.h"

#include <cmath>

#include "scene/scene.h"
#include "util/error.h"

namespace plm {

const char* lobe_type_name(int32_t type) {
  switch (type) {
    case PLM_LOBE_GLOSSY: return "glossy";
    case PLM_LOBE_FRESNEL: return "fresnel";
    case PLM_LOBE_GLASS: return "glass";
    case PLM_LOBE_REFRACTION: return "refraction";
    case PLM_LOBE_TRANSPARENT: return "transparent";
    case PLM_LOBE_SPECULAR: return "specular";
  }
  return "unknown";
}

plm_lobe default_lobe(plm_lobe_type type) {
  plm_lobe l;
  l.struct_size = uint32_t(sizeof l);
  l.type = type;
  l.color[0] = l.color[1] = l.color[2] = 1.0f;
  l.roughness = 0.0f;
  l.ior = type == PLM_LOBE_GLASS || type == PLM_LOBE_REFRACTION ? 1.45f : 1.5f;
  l.abbe = 0.0f;
  l.weight = 1.0f;
  return l;
}

void Scene::add_material_lobe(uint32_t material, const plm_lobe& in) {
  if (material >= materials.size())
    fail(PLM_ERROR_INVALID_ARGUMENT, "material id ", material, " is out of range (the scene has ", materials.size(),
         " materials)");
  Material& m = materials[material];
  const std::string owner = "material '" + (m.name.empty() ? "#" + std::to_string(material) : m.name) + "'";
  const std::string lobe_name =
      owner + ": lobe " + std::to_string(m.lobes.size()) + " (" + lobe_type_name(in.type) + ")";
  if (in.type < PLM_LOBE_GLOSSY || in.type > PLM_LOBE_SPECULAR)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": lobe ", m.lobes.size(), " has the unknown type ", in.type,
         " (PLM_LOBE_GLOSSY .. PLM_LOBE_SPECULAR)");
  if (m.lobes.size() >= kMaxLobes)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": has ", kMaxLobes, " lobes already, the most a material may have");
  for (int c = 0; c < 3; ++c)
    if (!(in.color[c] >= 0.0f && in.color[c] <= 1.0f))
      fail(PLM_ERROR_INVALID_ARGUMENT, lobe_name, ": color[", c, "] = ", in.color[c], " is not in [0, 1]");
  if (!(in.weight >= 0.0f && in.weight <= 1.0f))
    fail(PLM_ERROR_INVALID_ARGUMENT, lobe_name, ": weight ", in.weight, " is not in [0, 1]");
  if (!(in.roughness >= 0.0f && in.roughness <= 1.0f))
    fail(PLM_ERROR_INVALID_ARGUMENT, lobe_name, ": roughness ", in.roughness, " is not in [0, 1]");
  // ior > 0 and finite for every type (plm_lobe_default fills it): NaN is a
  // program's error, not a value to ignore where the type does not use it.
  if (!(in.ior > 0.0f && in.ior < 1e6f))
    fail(PLM_ERROR_INVALID_ARGUMENT, lobe_name, ": ior ", in.ior, " must be > 0 and finite");
  if (!(in.abbe >= 0.0f && in.abbe < 1e6f))
    fail(PLM_ERROR_INVALID_ARGUMENT, lobe_name, ": abbe ", in.abbe, " must be >= 0 and finite (0: no dispersion)");
  Lobe lobe;
  lobe.type = plm_lobe_type(in.type);
  if (in.abbe > 0.0f && !lobe.refracts())
    fail(PLM_ERROR_INVALID_ARGUMENT, lobe_name, ": abbe ", in.abbe,
         " is for glass and refraction lobes only (0: no dispersion)");
  lobe.color = {in.color[0], in.color[1], in.color[2]};
  lobe.weight = in.weight;
  lobe.roughness = in.roughness;
  lobe.ior = in.ior;
  lobe.abbe = in.abbe;
  // Energy: diffuse + weight x colour of the budgeted lobes at most 1 per
  // channel (a little slack for sums of rounded mix factors).
  if (lobe.budgeted()) {
    Vec3 total = m.albedo + lobe.color * lobe.weight;
    for (const Lobe& l : m.lobes)
      if (l.budgeted()) total += l.color * l.weight;
    for (int c = 0; c < 3; ++c)
      if (total[c] > 1.0f + 1e-4f)
        fail(PLM_ERROR_INVALID_ARGUMENT, lobe_name, ": the diffuse albedo plus weight x color of the lobes is ",
             total[c], " in channel ", c, ", above 1 (the surface would create light; FRESNEL and SPECULAR lobes do not count)");
  }
  m.lobes.push_back(lobe);
}

}  // namespace plm

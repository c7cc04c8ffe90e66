#include "transport/plan/validate.h"

#include "transport/plan/memory.h"
#include "util/error.h"

namespace plm {
namespace {

std::string mesh_label(const Mesh& m) { return "mesh '" + m.name + "'"; }

}  // namespace

void add_mesh_warnings(const Mesh& mesh, const TexelAreas* areas, std::vector<std::string>& warnings) {
  uint32_t degenerate = 0, first = 0;
  for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
    if (degenerate_triangle(mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2)) && degenerate++ == 0) first = t;
  }
  const std::string m = mesh_label(mesh);
  if (degenerate)
    warnings.push_back(m + ": " + std::to_string(degenerate) + " degenerate (zero-area or needle) triangles are ignored (first: triangle " +
                       std::to_string(first) + ")");
  if (!areas) return;
  if (areas->zero_uv_triangles)
    warnings.push_back(m + ": " + std::to_string(areas->zero_uv_triangles) +
                       " triangles have zero lightmap UV area (first: triangle " +
                       std::to_string(areas->first_zero_uv_triangle) + "); light falling on them is not recorded");
  if (areas->outside_triangles)
    warnings.push_back(m + ": " + std::to_string(areas->outside_triangles) +
                       " triangles reach outside the [0, 1] lightmap UV square (first: triangle " +
                       std::to_string(areas->first_outside_triangle) + "); light falling outside it is not recorded");
  if (areas->overlapping_texels)
    warnings.push_back(m + ": lightmap UV islands overlap in " + std::to_string(areas->overlapping_texels) +
                       " texels (first: texel " + std::to_string(areas->first_overlapping_texel % mesh.lightmap_width) +
                       ", " + std::to_string(areas->first_overlapping_texel / mesh.lightmap_width) +
                       "); overlapping surfaces share one value");
}

void validate(const Scene& scene, const BakeSettings& s) {
  const bool steered = s.target_error > 0.0 || s.time_budget > 0.0;
  if (s.photon_count == 0 && !steered)
    fail(PLM_ERROR_INVALID_ARGUMENT, "settings: photon_count must be > 0 unless target_error or time_budget is set");
  if (s.photon_count > (uint64_t(1) << 40))
    fail(PLM_ERROR_INVALID_ARGUMENT, "settings: photon_count ", s.photon_count, " exceeds the limit 2^40");
  if (!(s.target_error >= 0.0 && s.target_error < 1.0))
    fail(PLM_ERROR_INVALID_ARGUMENT, "settings: target_error ", s.target_error, " must be in [0, 1) (e.g. 0.02 for 2%)");
  if (!(s.time_budget >= 0.0 && s.time_budget < 1e7))
    fail(PLM_ERROR_INVALID_ARGUMENT, "settings: time_budget ", s.time_budget, " must be a number of seconds >= 0");
  if (s.direct_samples > 65536)
    fail(PLM_ERROR_INVALID_ARGUMENT, "settings: direct_samples ", s.direct_samples, " exceeds 65536");
  if (s.filter_radius > 64) fail(PLM_ERROR_INVALID_ARGUMENT, "settings: filter_radius ", s.filter_radius, " exceeds 64 texels");
  if (s.texel_value > PLM_TEXEL_AREA)
    fail(PLM_ERROR_INVALID_ARGUMENT, "settings: texel_value ", s.texel_value, " is not PLM_TEXEL_CYCLES (0) or PLM_TEXEL_AREA (1)");
  if (s.sampler > PLM_SAMPLER_SOBOL)
    fail(PLM_ERROR_INVALID_ARGUMENT, "settings: sampler ", s.sampler, " is not PLM_SAMPLER_DEFAULT (0), _RANDOM (1) or _SOBOL (2)");
  if (s.dilation > 4096) fail(PLM_ERROR_INVALID_ARGUMENT, "settings: dilation ", s.dilation, " exceeds 4096 texels");
  if (scene.meshes.empty() && scene.lsystems.empty())
    fail(PLM_ERROR_INVALID_SCENE, "the scene has no meshes: nothing to bake");
  uint64_t texels = 0;
  bool ol_meshes = false;
  for (const Mesh& m : scene.meshes) {
    if (m.ol_group < 0 || scene.ol_groups[size_t(m.ol_group)].backup)
      texels += uint64_t(m.lightmap_width) * m.lightmap_height;
    ol_meshes = ol_meshes || m.ol_group >= 0;
  }
  if (texels == 0 && !ol_meshes && scene.lsystems.empty())
    fail(PLM_ERROR_INVALID_SCENE, "no mesh has a lightmap or an OL group: give at least one mesh a lightmap size and "
         "UVs, or put it into an orientation-lightmap group");
  if (texels == 0 && s.target_error > 0.0 && s.photon_count == 0 && s.time_budget <= 0.0)
    fail(PLM_ERROR_INVALID_ARGUMENT, "settings: target_error is measured over ordinary lightmap texels, and no "
         "mesh has one (orientation lightmaps do not steer the bake): set photon_count or time_budget");
  if (texels >= (uint64_t(1) << 31))
    fail(PLM_ERROR_INVALID_SCENE, "the lightmaps hold ", texels, " texels together; the limit is 2^31");
  // Light groups split the texels of ordinary lightmaps (docs/design/light-groups.md);
  // what stores light otherwise has no layers.
  if (!scene.light_groups.empty()) {
    const char* other = !scene.ol_groups.empty() ? "orientation-lightmap groups"
                        : !scene.csgs.empty()    ? "CSG solids"
                        : !scene.lsystems.empty() ? "L-system objects"
                                                  : nullptr;
    if (other)
      fail(PLM_ERROR_INVALID_SCENE, "light groups (", scene.light_groups.size(), " declared, the first '",
           scene.light_groups[0], "') split ordinary lightmaps only, and the scene has ", other,
           ": bake it without light groups, or those objects as meshes with lightmaps");
  }
  // Directional lightmaps keep the direction of ordinary lightmaps' light (docs/design/directional.md).
  if (s.directional) {
    const char* other = !scene.light_groups.empty() ? "light groups"
                        : !scene.ol_groups.empty()  ? "orientation-lightmap groups"
                        : !scene.csgs.empty()       ? "CSG solids"
                        : !scene.lsystems.empty()   ? "L-system objects"
                                                    : nullptr;
    if (other)
      fail(PLM_ERROR_INVALID_SCENE, "directional lightmaps are made for ordinary lightmaps only, and the scene has ",
           other, ": bake it without directional lightmaps",
           scene.light_groups.empty() ? ", or those objects as meshes with lightmaps" : " or without light groups");
  }
}

BakeSettings effective_settings(const Scene& scene, const BakeSettings& requested, std::vector<std::string>& warnings) {
  BakeSettings settings = requested;
  bool ordinary_texels = false;
  for (const Mesh& m : scene.meshes)
    ordinary_texels = ordinary_texels || scene.own_texels(m) || (m.has_lightmap() && m.csg_carrier >= 0);
  if (!ordinary_texels && settings.target_error > 0.0) {
    settings.target_error = 0.0;
    warnings.push_back("target_error ignored: it is measured over ordinary lightmap texels and every mesh "
                       "is lit through an orientation lightmap; the photon count or time budget decides");
  }
  return settings;
}

uint64_t check_memory(const Scene& scene, const BakeSettings& settings, std::vector<std::string>& warnings) {
  const MemoryEstimate memory = estimate_bake_memory(scene, settings.directional);
  if (const uint64_t free = available_memory()) {
    // The largest lightmap, if any (a scene of L-system objects alone has no mesh).
    std::string where, which;
    if (memory.largest_bytes > 0) {
      const Mesh& largest = scene.meshes[memory.largest_mesh];
      where = " (mesh '" + largest.name + "', " + std::to_string(largest.lightmap_width) + " x " +
              std::to_string(largest.lightmap_height) + " texels: about " + format_bytes(memory.largest_bytes) + ")";
      which = " of '" + largest.name + "'";
    }
    if (memory.bytes > free)
      fail(PLM_ERROR_OUT_OF_MEMORY, "the bake would need about ", format_bytes(memory.bytes), " of memory", where,
           " but only ", format_bytes(free), " are free: lower the lightmap resolution", which,
           " or bake fewer objects at once");
    if (double(memory.bytes) > 0.6 * double(free))
      warnings.push_back("the bake may need about " + format_bytes(memory.bytes) + " of memory" + where +
                         ", close to the " + format_bytes(free) + " free");
  }
  return memory.bytes;
}

}  // namespace plm

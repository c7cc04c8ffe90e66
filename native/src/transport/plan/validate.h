// What a bake checks before it starts: settings in range, a scene that can
// bake, memory enough for it; and the warnings of legal but odd meshes.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "lightmap/texel_area.h"
#include "photonlm/photonlm.h"
#include "scene/scene.h"
#include "transport/plan/settings.h"

namespace plm {

// Throws plm::Error (PLM_ERROR_INVALID_ARGUMENT or _INVALID_SCENE) naming
// the setting or what the scene lacks.
void validate(const Scene& scene, const BakeSettings& s);

// The settings the bake follows: orientation lightmaps do not steer, so with
// no ordinary texel a target error is dropped (with a warning) and the photon
// count or the time budget decides.
BakeSettings effective_settings(const Scene& scene, const BakeSettings& requested, std::vector<std::string>& warnings);

// Refuses (PLM_ERROR_OUT_OF_MEMORY) a bake whose estimated peak memory
// exceeds the memory free, naming the largest lightmap; warns past 60 % of
// it. Returns the estimate in bytes.
uint64_t check_memory(const Scene& scene, const BakeSettings& settings, std::vector<std::string>& warnings);

// A mesh's degenerate triangles and, given its texel areas, its lightmap UV
// problems (zero UV area, outside the UV square, overlapping islands).
void add_mesh_warnings(const Mesh& mesh, const TexelAreas* areas, std::vector<std::string>& warnings);

}  // namespace plm

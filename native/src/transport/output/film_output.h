// The lightmaps a bake returns: each texel from the final estimate, from its
// OL (a mesh in an OL group), from its CSG solid's texels (a carrier), or
// the estimate blended with its backup OL; then dilated over the island
// borders so that bilinear filtering mixes only real values, and stitched
// along seams, within a mesh and between meshes (lightmap/object_seams.h).
#pragma once

#include <tbb/task_arena.h>

#include <cstdint>
#include <string>
#include <vector>

#include "ol/orientation_lightmap.h"
#include "scene/scene.h"
#include "transport/output/film_estimate.h"
#include "transport/output/images.h"

namespace plm {

// One image per mesh (empty for meshes without a lightmap). The final
// estimate's images are moved out of `last`.
void write_lightmaps(tbb::task_arena& arena, const Scene& scene, const Estimator& est, uint64_t photons,
                     const std::vector<ol::OrientationLightmap>& ols, Estimate& last, uint32_t dilation,
                     std::vector<LightmapImage>& images, std::vector<std::string>& warnings);

}  // namespace plm

#include "transport/control/live_preview.h"

#include <algorithm>
#include <vector>

#include "lightmap/dilate.h"
#include "photonlm/photonlm.h"
#include "util/error.h"

namespace plm {

const Mesh& Snapshot::lightmap_mesh(uint32_t mesh) const {
  if (mesh >= scene_.meshes.size())
    fail(PLM_ERROR_INVALID_ARGUMENT, "mesh id ", mesh, " is out of range (the scene has ", scene_.meshes.size(),
         " meshes)");
  const Mesh& m = scene_.meshes[mesh];
  if (!m.has_lightmap()) fail(PLM_ERROR_INVALID_ARGUMENT, "mesh ", mesh, " has no lightmap");
  return m;
}

bool Snapshot::copy_lightmap(uint32_t mesh, float* rgb) const {
  const Mesh& m = lightmap_mesh(mesh);
  if (!scene_.own_texels(m)) return false;  // an OL group's or a CSG solid's texels
  EstimateBuffers b;
  arena_.execute([&] { est_.texels(mesh, photons_, b); });
  const std::vector<double>& value3 = b.value3;
  const size_t n = size_t(m.lightmap_width) * m.lightmap_height;
  const std::vector<double>& area = est_.space.areas[mesh].area;
  std::vector<float> values(3 * n, 0.0f);
  std::vector<uint8_t> filled(n, 0);
  for (size_t t = 0; t < n; ++t) {
    if (!(area[t] > 0.0)) continue;
    for (int c = 0; c < 3; ++c) values[3 * t + c] = float(value3[3 * t + c]);
    filled[t] = 1;
  }
  dilate(values, 3, filled, m.lightmap_width, m.lightmap_height, dilation_);
  std::copy(values.begin(), values.end(), rgb);
  return true;
}

void LivePreview::take(tbb::task_arena& arena, const Scene& scene, const Estimator& est, uint64_t photons,
                       uint32_t dilation, bool first) {
  if (!first && seconds_since(last_) < hook_->interval) return;
  const Snapshot snapshot(arena, scene, est, photons, dilation);
  if (!hook_->callback(snapshot)) fail(PLM_ERROR_CANCELLED, "the bake was cancelled");
  last_ = Clock::now();  // from the end of the host's copy: a copy of c s costs at most c / (c + interval)
}

}  // namespace plm

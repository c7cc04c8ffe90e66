// Light-group layers of a lightmap (docs/design/light-groups.md): each
// group's part of the final texel values, from the same photons and direct
// samples as the whole. A texel's value V is its direct light D plus its
// indirect light I = V - D; layer l takes of D the share its lights have in
// the texel's direct sums, and of I the share its photons have in the
// texel's photon flux pooled as the whole's reconstruction pools it. The
// shares of a texel add up to 1, so the layers add up to V (up to float
// rounding), whatever the gather and the pooling did to V.
#pragma once

#include <tbb/task_arena.h>

#include <cstddef>
#include <cstdint>
#include <vector>

#include "transport/output/film_estimate.h"

namespace plm {

// Per layer, mesh i's texels as R, G, B, error (4 floats a texel, 0 where
// uncovered) from its final texels `values` (the same layout) at `photons`
// photons. A layer's error: its part of the direct variance (a group whose
// lights give a share s of a texel's samples carries about s of it), of the
// indirect one (s^2 of it), and its shares' own noise (layers.cpp).
void layer_texels(const Estimator& est, size_t i, uint64_t photons, const std::vector<float>& values,
                  std::vector<std::vector<float>>& layers);

// Directional lightmaps (docs/design/directional.md): per world axis x, y, z,
// mesh i's texels' direction moment D as R, G, B, 0 (4 floats a texel, 0
// where uncovered), from its final texels `values`: a surface of unit normal
// n there receives V / 2 + D . n (V the texel's value). The direct light
// takes its moment from the direct sums' split, the indirect light from the
// photons' pooled as the whole's are and the final gather's, as the whole
// blends them.
void direction_texels(const Estimator& est, size_t i, uint64_t photons, const std::vector<float>& values,
                      std::vector<std::vector<float>>& axes);

// What the final gather's rays split their light by (GatherLookup::layer_shares):
// per mesh, per texel, each layer's share of the texel's light (3 per layer;
// of the estimate `values`, Estimate::values), from layer_texels.
std::vector<std::vector<float>> layer_shares(tbb::task_arena& arena, const Estimator& est, uint64_t photons,
                                             const std::vector<std::vector<float>>& values);

}  // namespace plm

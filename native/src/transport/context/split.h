// What a bake keeps of each sample's light besides a texel's sums: its part
// in each light-group layer (docs/design/light-groups.md) and, for
// directional lightmaps, its direction moment (docs/design/directional.md).
// The photon film, the direct pass and the final gather keep these per
// texel in slots of three numbers (R, G, B): one slot per layer, then with
// directional lightmaps one per world axis x, y, z.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "util/math.h"

namespace plm {

struct SplitLayout {
  uint32_t layers = 0;       // light-group layers (0 without groups)
  bool directional = false;  // the direction moment's three slots follow the layers
  uint32_t slots() const { return layers + (directional ? 3u : 0u); }
  uint32_t axis_slot(uint32_t axis) const { return layers + axis; }
};

// The direction moment's weight of light arriving from unit direction `dir`
// at a surface of unit normal n: dir / cos less n / 2, the cosine floored at
// kMinDirectionCos (directional.md: light weighed so is the first moment of
// the incoming radiance; the floor bounds the weight of grazing light).
constexpr float kMinDirectionCos = 0.1f;
inline Vec3 direction_weight(Vec3 dir, Vec3 n) {
  return dir * (1.0f / std::max(dot(dir, n), kMinDirectionCos)) - n * 0.5f;
}

// Adds `light` of layer `layer`, arriving with direction weight u, to a
// texel's split (3 x s.slots() floats; null: nothing is kept).
inline void add_split(float* split, const SplitLayout& s, uint32_t layer, Vec3 light, Vec3 u) {
  if (!split) return;
  if (s.layers)
    for (int c = 0; c < 3; ++c) split[3 * size_t(layer) + c] += light[c];
  if (s.directional) {
    float* d = split + 3 * size_t(s.layers);
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c < 3; ++c) d[3 * a + c] += light[c] * u[a];
  }
}

}  // namespace plm

// The memory a bake will need, estimated before it allocates anything, and the
// memory the machine has free: a bake that cannot fit is refused with a message
// instead of being killed half-way (a host such as Blender dies with it).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "scene/scene.h"

namespace plm {

struct MemoryEstimate {
  uint64_t bytes = 0;         // the whole bake, peak
  size_t largest_mesh = 0;    // the mesh whose lightmap needs the most
  uint64_t largest_bytes = 0; // ... and how much
};

// Per lightmap texel, per covered texel (estimated from the UV triangles'
// areas), per triangle and per texture pixel, measured on Release builds.
MemoryEstimate estimate_bake_memory(const Scene& scene, bool directional = false);

// Bytes this process can still allocate: MemAvailable, or the cgroup's limit
// less its use where that is lower; 0 where neither can be read.
uint64_t available_memory();

// "1.5 GB", "320 MB".
std::string format_bytes(uint64_t bytes);

}  // namespace plm

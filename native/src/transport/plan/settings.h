// The engine's bake settings: what the caller asked for (the C API's bake
// settings, read by api/settings.cpp) and what follows from it for this
// scene, decided once by decide() so that no stage derives it again
// (docs/design/README.md, "The bake context").
#pragma once

#include <cstdint>

#include "photonlm/photonlm.h"
#include "scene/scene.h"

namespace plm {

// The final gather runs only where max_bounces does not truncate light (the
// default is 1024): its lookups carry every bounce, so it would add one.
constexpr uint32_t kGatherMinBounces = 64;

struct BakeSettings {
  // As requested (photonlm.h, the C API's bake settings).
  uint64_t photon_count = 1000000;  // 0: as many as the target error or the time budget take
  uint32_t max_bounces = 1024;
  uint32_t seed = 0;
  uint32_t thread_count = 0;  // 0: every core
  uint32_t dilation = 8;
  double target_error = 0.0;  // dropped by effective_settings where no ordinary texel can steer it
  double time_budget = 0.0;
  uint32_t direct_samples = 64;
  uint32_t filter_radius = 2;
  uint32_t texel_value = PLM_TEXEL_CYCLES;
  uint32_t sampler = PLM_SAMPLER_DEFAULT;
  bool directional = false;  // SH L1 directional lightmaps (docs/design/directional.md)

  // Decided by decide().
  bool two_pass = true;       // a direct pass (direct_samples > 0), photons record from depth 1
  bool photon_pass = true;    // photons are traced (no direct pass, or max_bounces > 0)
  bool gather = false;        // the final gather runs (transport/gather/final_gather.h)
  bool cycles_window = true;  // texel values as Cycles bakes them (PLM_TEXEL_CYCLES)
  bool sobol = true;          // the direct pass and the gather use Sobol points (not PLM_SAMPLER_RANDOM)
  uint64_t photon_cap = 0;    // photons at most: photon_count, or 2^40 where it is 0

  bool targeted() const { return target_error > 0.0; }
  bool steered() const { return target_error > 0.0 || time_budget > 0.0; }

  // Sets the decided fields from the requested ones and the scene. The final
  // gather looks up radiosity on meshes: not in scenes with CSG solids or
  // L-systems, nor with few bounces.
  void decide(const Scene& scene);
};

}  // namespace plm

// A photon's random numbers. Group 0 is the light choice and the emission,
// group 1 + depth that bounce. By default the light choice follows a rotated
// van der Corput sequence over the photon index (stratified for any photon
// count) and the rest is pseudo-random (Sobol paths do not lower texel errors,
// see docs/design/direct.md, "Sobol points where they pay"); PLM_SAMPLER_SOBOL
// draws Sobol points keyed per batch, so batches stay independent replicates
// for the error estimate.
#pragma once

#include <cstdint>

#include "photonlm/photonlm.h"
#include "transport/plan/settings.h"
#include "util/rng.h"
#include "util/sobol.h"

namespace plm {

// Photons are traced in fixed batches; a batch's hits are merged in batch
// order, so sums are identical whatever the thread count.
constexpr uint32_t kBatchPhotons = 4096;

class PhotonSampler {
 public:
  PhotonSampler(uint64_t index, const BakeSettings& s, double pick_offset, Rng::SeedHash seed_hash)
      : rng_(seed_hash, index), global_(index), index_(uint32_t(index % kBatchPhotons)),
        key_(s.sampler == PLM_SAMPLER_SOBOL ? uint32_t(splitmix64((uint64_t(s.seed) << 32) ^ (index / kBatchPhotons))) : 0u),
        mode_(s.sampler),
        pick_offset_(pick_offset) {}
  // pick, then the four numbers of sample_emitter.
  void emission(float& pick, float u[4]) {
    if (mode_ == PLM_SAMPLER_SOBOL) {
      sobol_group(index_, key_, 0, 4, u);
      sobol_group(index_, key_ ^ 0x5bd1e995u, 0, 1, &pick);
      return;
    }
    if (mode_ == PLM_SAMPLER_RANDOM) {
      pick = rng_.next_float();
    } else {
      const double p = radical_inverse2(global_) + pick_offset_;
      pick = float(p >= 1.0 ? p - 1.0 : p);
      if (pick >= 1.0f) pick = 0.0f;  // float rounding
    }
    for (int d = 0; d < 4; ++d) u[d] = rng_.next_float();
  }
  // Two numbers for the direction, one for Russian roulette.
  void bounce(uint32_t depth, float u[3]) {
    if (mode_ == PLM_SAMPLER_SOBOL) return sobol_group(index_, key_, 1 + depth, 3, u);
    for (int d = 0; d < 3; ++d) u[d] = rng_.next_float();
  }

 private:
  Rng rng_;
  uint64_t global_;
  uint32_t index_, key_, mode_;
  double pick_offset_;
};

}  // namespace plm

#include "transport/plan/settings.h"

namespace plm {

void BakeSettings::decide(const Scene& scene) {
  two_pass = direct_samples > 0;
  photon_pass = !two_pass || max_bounces > 0;
  gather = photon_pass && two_pass && scene.csgs.empty() && scene.lsystems.empty() &&
           max_bounces >= kGatherMinBounces;
  cycles_window = texel_value == PLM_TEXEL_CYCLES;
  sobol = sampler != PLM_SAMPLER_RANDOM;
  photon_cap = photon_count ? photon_count : (uint64_t(1) << 40);
}

}  // namespace plm

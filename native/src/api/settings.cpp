#include "api/settings.h"

namespace plm {

plm_bake_settings default_settings() {
  plm_bake_settings s;
  s.struct_size = uint32_t(sizeof s);
  s.photon_count = 1000000;
  s.max_bounces = 1024;
  s.seed = 0;
  s.thread_count = 0;
  s.dilation = 8;
  s.target_error = 0.0;
  s.time_budget = 0.0;
  s.direct_samples = 64;
  s.filter_radius = 2;
  s.texel_value = PLM_TEXEL_CYCLES;
  s.sampler = PLM_SAMPLER_DEFAULT;
  s.directional = 0;
  return s;
}

namespace api {

BakeSettings engine_settings(const plm_bake_settings& c, const Scene& scene) {
  BakeSettings s;
  s.photon_count = c.photon_count;
  s.max_bounces = c.max_bounces;
  s.seed = c.seed;
  s.thread_count = c.thread_count;
  s.dilation = c.dilation;
  s.target_error = c.target_error;
  s.time_budget = c.time_budget;
  s.direct_samples = c.direct_samples;
  s.filter_radius = c.filter_radius;
  s.texel_value = c.texel_value;
  s.sampler = c.sampler;
  s.directional = c.directional != 0;
  s.decide(scene);
  return s;
}

plm_bake_settings c_settings(const BakeSettings& s) {
  plm_bake_settings c = default_settings();
  c.photon_count = s.photon_count;
  c.max_bounces = s.max_bounces;
  c.seed = s.seed;
  c.thread_count = s.thread_count;
  c.dilation = s.dilation;
  c.target_error = s.target_error;
  c.time_budget = s.time_budget;
  c.direct_samples = s.direct_samples;
  c.filter_radius = s.filter_radius;
  c.texel_value = s.texel_value;
  c.sampler = s.sampler;
  c.directional = s.directional ? 1 : 0;
  return c;
}

}  // namespace api
}  // namespace plm

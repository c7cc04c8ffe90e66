// The photon-lightmap bake (thesis 3.5.2): photons leave the lights in
// proportion to their power, bounce diffusely with Russian roulette, and every
// hit on a lightmapped surface adds its flux to the texel it lands in. A texel
// holds flux / (area * pi) = irradiance / pi.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "photonlm/photonlm.h"
#include "scene/scene.h"

namespace plm {

struct LightmapImage {
  uint32_t width = 0, height = 0;
  std::vector<float> rgb;       // 3 per texel, rows bottom first
  std::vector<float> error;     // standard error of the texel's mean RGB
  std::vector<float> hits;      // photon hits recorded
  std::vector<float> coverage;  // covered fraction (0 for dilated texels)
};

struct BakeOutput {
  std::vector<LightmapImage> lightmaps;  // one per mesh; empty for meshes without a lightmap
  std::vector<std::string> warnings;
  plm_bake_stats stats{};
};

// Returns false to cancel. Called from the baking thread only.
using ProgressFn = std::function<bool(double fraction, const char* stage)>;

plm_bake_settings default_settings();

// Throws plm::Error on invalid input and PLM_ERROR_CANCELLED on cancel.
BakeOutput bake(const Scene& scene, const plm_bake_settings& settings, const ProgressFn& progress);

}  // namespace plm

// What a bake returns, and its progress callback. The bake itself is a
// composition of stages (transport/jobs/bake_jobs.h, transport/control/stages.h).
//
// The photon-lightmap bake ([Thesis §3.5.2]): photons leave the lights in
// proportion to their power, bounce diffusely with Russian roulette, and every
// hit on a lightmapped surface adds its flux to the texel it lands in. A texel
// holds flux / (area * pi) = irradiance / pi.
//
// L-system objects (scene.h) have no texels either: every hit (at every
// depth, front side) goes to the object's root OL and to the stub OL of its
// instance at ol_level (LSystemOutput).
//
// Meshes in an orientation-lightmap group (scene.h OlGroup) have no texels:
// their front-side hits go to the group's OL bin of the triangle's normal
// (ol/orientation_lightmap.h), at every photon depth, since the per-texel
// direct pass cannot reach them. Their hits are merged in batch order like
// texel hits, so OLs too are independent of the thread count.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "photonlm/photonlm.h"
#include "scene/scene.h"
#include "transport/output/images.h"

namespace plm {

struct BakeOutput {
  std::vector<LightmapImage> lightmaps;  // one per mesh; empty for meshes without a lightmap
  std::vector<OlImage> ols;              // one per OL group
  std::vector<LSystemOutput> lsystems;   // one per L-system object
  std::vector<std::string> warnings;
  plm_bake_stats stats{};
  // With light groups: each layer's name (its group's; "default" for the
  // default group) and its estimated relative error over the covered
  // texels (sqrt(mean variance) / mean value, as the bake's own).
  std::vector<std::string> layer_names;
  std::vector<double> layer_errors;
  bool directional = false;  // the lightmaps carry direction moments (LightmapImage::direction_rgb)
};

// Returns false to cancel. Called from the baking thread only.
using ProgressFn = std::function<bool(double fraction, const char* stage)>;

}  // namespace plm

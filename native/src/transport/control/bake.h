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
};

// Returns false to cancel. Called from the baking thread only.
using ProgressFn = std::function<bool(double fraction, const char* stage)>;

plm_bake_settings default_settings();

struct PreviewHook;  // live_preview.h
struct ShardJob;     // transport/farm/shard.h

// Throws plm::Error on invalid input and PLM_ERROR_CANCELLED on cancel.
// preview (may be null): snapshots of the lightmaps while the bake runs.
// With a shard job the bake is one part of a sharded bake (transport/farm/shard.h):
// kTrace traces the shard's photon batches into job->segments and returns
// after them (no direct pass, no outputs); kMerge takes every shard's
// segments instead of tracing photons and bakes the rest as usual.
// The scene's pending subdivision cages are refined first (Scene::refine_cages,
// counted in the set-up time).
BakeOutput bake(Scene& scene, const plm_bake_settings& settings, const ProgressFn& progress,
                const PreviewHook* preview = nullptr, ShardJob* job = nullptr);

}  // namespace plm

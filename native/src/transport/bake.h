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
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "ol/orientation_lightmap.h"

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

// Bins per side of an OL group created with resolution 0: 16 x 16 bins of
// 4 pi / 256 sr each (~0.05 sr, a cone of ~7 degrees half-angle).
constexpr uint32_t kAutoOlResolution = 16;
// Independent photon groups of an OL, whose spread gives its error: photon
// batch b (kBatchPhotons photons) goes to group b % kOlBatches.
constexpr uint32_t kOlBatches = 16;

// One orientation lightmap: bin = row * resolution + column over the
// octahedral square (ol/octahedral.h), row 0 at v near 0.
struct OlImage {
  std::string name;
  uint32_t resolution = 0;
  std::vector<float> rgb;    // 3 per bin, irradiance / pi; 0 where the bin has no area
  std::vector<float> error;  // standard error of the bin's mean RGB
  std::vector<float> area;   // covered surface area whose normal falls in the bin (m^2)
  std::vector<float> hits;   // photon hits recorded in the bin
  plm_ol_stats stats{};
};

// The OLs of one L-system object ([Thesis ch. 7]): the root OL covers the
// whole object; a stub OL covers the primitives under one node instance at
// the object's ol_level, keyed by that instance's path key
// (lsystem/graph.h ancestor_key). Every hit goes to the root and to its
// stub; stubs exist for instances that received hits. Finalized when photons
// were traced.
struct LSystemOutput {
  std::shared_ptr<const lsystem::LSystemObject> object;
  std::unique_ptr<ol::OrientationLightmap> root;
  std::unordered_map<uint64_t, ol::OrientationLightmap> stubs;
  plm_lsystem_stats stats{};
  // The light (irradiance / pi) at surface point p with unit normal n: its
  // stub's OL where the stub holds enough hits in that bin (kStubMinHits),
  // else the root's; black before photons were traced.
  Vec3 light_at(Vec3d p, Vec3d n) const;
};

// A lookup uses a stub's bin when it holds at least this many hits, else the root.
constexpr uint64_t kStubMinHits = 16;

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
struct ShardJob;     // transport/shard.h

// Throws plm::Error on invalid input and PLM_ERROR_CANCELLED on cancel.
// preview (may be null): snapshots of the lightmaps while the bake runs.
// With a shard job the bake is one part of a sharded bake (transport/shard.h):
// kTrace traces the shard's photon batches into job->segments and returns
// after them (no direct pass, no outputs); kMerge takes every shard's
// segments instead of tracing photons and bakes the rest as usual.
// The scene's pending subdivision cages are refined first (Scene::refine_cages,
// counted in the set-up time).
BakeOutput bake(Scene& scene, const plm_bake_settings& settings, const ProgressFn& progress,
                const PreviewHook* preview = nullptr, ShardJob* job = nullptr);

}  // namespace plm

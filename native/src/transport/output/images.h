// What a bake returns besides its statistics (transport/control/bake.h,
// BakeOutput): one image per lightmap, one per OL group, and each L-system
// object's OLs.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "ol/orientation_lightmap.h"
#include "photonlm/photonlm.h"
#include "scene/scene.h"
#include "util/math.h"

namespace plm {

struct LightmapImage {
  uint32_t width = 0, height = 0;
  std::vector<float> rgb;       // 3 per texel, rows bottom first
  std::vector<float> error;     // standard error of the texel's mean RGB
  std::vector<float> hits;      // photon hits recorded
  std::vector<float> coverage;  // covered fraction (0 for dilated texels)
  // With light groups: per layer, its part of rgb (3 per texel) and that
  // part's error (transport/output/layers.h); they add up to rgb.
  std::vector<std::vector<float>> layer_rgb, layer_error;
  // Directional lightmaps (docs/design/directional.md): per world axis x,
  // y, z, the direction moment D (3 per texel): a surface of unit normal n
  // at the texel receives rgb / 2 + D . n.
  std::vector<std::vector<float>> direction_rgb;
};

// Directional lightmaps' SH L1 in Godot 4's layout (photonlm.h, "Directional
// lightmaps"): band 0 is L0, bands 1, 2, 3 are L1 along y, z, x; a surface of
// unit normal n receives kShEval0 L0 + kShEval1 (L1 . n). kShEval0 is Y00,
// kShEval1 the first band's Y1 times the cosine lobe's 2/3.
constexpr double kShEval0 = 0.28209479177387814, kShEval1 = 0.32573500793527993;
// Band `band` of img's SH into rgb (3 floats per texel).
void sh_band(const LightmapImage& img, uint32_t band, float* rgb);

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
// (lsystem/graph/graph.h ancestor_key). Every hit goes to the root and to its
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

}  // namespace plm

// Everything that emits light, flattened for photon emission: Blender lights,
// emissive triangles and the world. A closed set dispatched on a tag.
#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "scene/scene.h"
#include "transport/lights/footprint.h"
#include "util/math.h"

namespace plm {

class EnvironmentMap;

enum class EmitterKind : uint8_t { Point, Spot, Sun, AreaRect, AreaDisk, Triangle, World };

// An opening through which sun and sky light enter (PLM_LIGHT_PORTAL): a
// parallelogram centre +- half_u +- half_v, inward = unit normal into the interior.
struct Portal {
  Vec3 center, half_u, half_v, inward;
  float area;
};

struct Emitter {
  EmitterKind kind;
  Vec3 flux;        // total emitted RGB flux (W)
  Vec3 scale;       // per-sample RGB weight before angular factors (see sample_emitter)
  Vec3 origin;      // point/spot/area centre, triangle vertex 0
  Vec3 axis_u, axis_v;  // area: half extents; triangle: edges; sun/world: frame
  Vec3 normal;      // area/triangle: emitting side; spot: cone axis; sun: travel direction
  Vec3 frame_t, frame_b;  // area/triangle/spot: make_frame(normal), once per emitter (build_emitters)
  float radius = 0;     // point/spot: light radius
  float cos_half = 1;   // spot: cos(spot_size / 2); sun: cos(angle / 2)
  float spot_smooth = 0;
  bool spot_cosine = true;  // spot: the falloff carries cos(angle from the axis) (Cycles 3.4)
  // For direct lighting: intensity (point/spot, W/sr), irradiance (sun),
  // radiance (area, triangle, world); and the emitting area (area, triangle).
  Vec3 radiance;
  float area = 0;
  uint32_t mesh = 0, triangle = 0;  // Triangle: where it is in the scene
  uint32_t material = 0;            // Triangle: its material
  // Triangle with an emission texture: radiance (and flux) are the texture's
  // mean over the triangle; a sample's own radiance is the texture at its
  // point (TextureSet::emission at EmitterSample / DirectSample bu, bv).
  bool textured = false;
  // Its light group (Scene::light_groups index + 1, 0: the default) and that
  // group's layer of the bake (assign_layers; 0 without groups).
  uint32_t group = 0, layer = 0;
  float pick = 0;   // the emitter's share of photons is proportional to this (its mean flux by default)
  // Sun and world with portals: a share of the photons (and of the sky's
  // direct samples) go through the portals, chosen by portal_pick; the
  // weights use the mixture's density, so the sum stays unbiased.
  std::vector<Portal> portals;
  std::vector<float> portal_pick;
  float portal_share = 0;
  // World with an environment map (owned by the scene): radiance, photon
  // directions and sky samples come from the map's part map_part (0: all of
  // it; a map with a sun is two emitters, 1: its bright cells, 2: the rest);
  // radiance above is the part's mean. Null for the uniform world, whose code
  // paths do not look at it.
  const EnvironmentMap* map = nullptr;
  int map_part = 0;
  // Sun and world: where their photons start (transport/lights/footprint.h), one
  // for all of them; null for the other emitters.
  std::shared_ptr<const Footprint> footprint;
};

struct EmitterSample {
  Vec3 origin, direction;
  Vec3 weight;  // flux carried by the sample, before dividing by the sample count and pick probability
  // Point/spot lights of radius r (Cycles 3.4): a disk of radius r facing the
  // receiver, which receives I cos / (d^2 + r^2) at distance d from the centre.
  // The first hit scales the flux by d^2 / (d^2 + r^2); 0 = no scaling.
  float radius2 = 0.0f;
  Vec3 center;
  float bu = 0.0f, bv = 0.0f;  // Triangle: barycentrics of origin (Embree's u, v)
};

// Cycles' spot falloff for a unit direction at cosine c from the axis:
// smoothstep((c - cos_half) / spot_smooth), times c where `cosine` (Cycles
// 3.4; Cycles 4 has the smoothstep alone).
float spot_attenuation(float c, float cos_half, float spot_smooth, bool cosine = true);

// Where sun and world photons start in `scene`, whose geometry lies in
// [lo, hi]: aimed at the box around what records photons (meshes with a
// lightmap or an OL group, CSG solids, L-system objects), kFootprintAim of
// them where that box is much smaller than the scene's.
Footprint photon_footprint(const Scene& scene, Vec3 lo, Vec3 hi);

// Flattens lights, emissive triangles and the world. Sun and world photons
// start on `footprint` (its scene box grows to hold the portals). textures
// (null for none) give emissive triangles their texture's mean over the
// triangle (their power, by which they are picked) and mark them textured.
class TextureSet;
std::vector<Emitter> build_emitters(const Scene& scene, Footprint footprint, const TextureSet* textures = nullptr);

// The layers of a bake with light groups (docs/design/light-groups.md), as
// the groups they hold (0: the default group): the default group first where
// an emitter is in it, then every declared group; each emitter's `layer` set.
// Empty, and the layers untouched, for a scene without declared groups.
std::vector<uint32_t> assign_layers(const Scene& scene, std::vector<Emitter>& emitters);
// The same with photons over the box [center - radius, center + radius].
std::vector<Emitter> build_emitters(const Scene& scene, Vec3 scene_center, float scene_radius,
                                    const TextureSet* textures = nullptr);

// Chooses emitters in proportion to their power (mean RGB flux).
class EmitterTable {
 public:
  // skip (empty, or one flag per emitter): emitters never chosen (probability 0).
  explicit EmitterTable(const std::vector<Emitter>& emitters, const std::vector<uint8_t>& skip = {});
  // The emitter for a uniform number u in [0, 1).
  size_t choose(double u) const {
    if (cdf_.size() <= 1) return 0;  // one light: no search per photon
    return std::min<size_t>(std::upper_bound(cdf_.begin(), cdf_.end(), u) - cdf_.begin(), cdf_.size() - 1);
  }
  float probability(size_t k) const { return pick_[k]; }

 private:
  std::vector<double> cdf_;
  std::vector<float> pick_;
};

// Samples an origin and a direction from four uniform numbers in [0, 1).
EmitterSample sample_emitter(const Emitter& e, const float u[4]);

// Direct light at surface point p with unit normal n (the side it faces):
// an unbiased sample of the irradiance this emitter gives p if the shadow ray
// (p towards dir, up to distance; infinite for sun and world) is unblocked.
struct DirectSample {
  Vec3 irradiance;
  Vec3 dir;
  float distance;
  // Triangle: the sampled point's barycentrics (Embree's u, v) and irradiance
  // per unit radiance there (cos_l cos_s A / d^2; a textured triangle's
  // irradiance is its radiance at (bu, bv) times this).
  float bu, bv, geometry;
};
DirectSample sample_direct(const Emitter& e, Vec3 p, Vec3 n, const float u[3]);

// A cheap guess of the irradiance (mean of RGB) e gives p if nothing is in the
// way, from the light's centre: for choosing lights per point, not a value.
// 0 where it cannot reach p from its centre (it may still reach p by its rim).
float unoccluded_irradiance(const Emitter& e, Vec3 p, Vec3 n);

}  // namespace plm

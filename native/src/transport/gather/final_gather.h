// The final gather: a texel's indirect light estimated from the texels its
// rays see. From the direct pass's points (transport/direct/texel_points.h), cosine rays look
// up albedo x radiosity (direct + photon estimate) of the texel they hit;
// rays that leave the scene count 0 (the sky is direct light). Where the
// indirect light is a small part of the light (an open sunlit scene) this
// needs far fewer rays per texel than photons need photons. The estimator
// (transport/output/film_estimate.h) weighs it against the photons' estimate by variance.
#pragma once

#include <tbb/task_arena.h>

#include <cstdint>
#include <functional>
#include <limits>
#include <vector>

#include "lightmap/texel_area.h"
#include "photonlm/photonlm.h"
#include "transport/context/bake_scene.h"
#include "transport/direct/stratified_sums.h"
#include "transport/direct/texel_points.h"
#include "transport/film/film.h"
#include "transport/plan/settings.h"
#include "transport/materials/material_table.h"
#include "transport/rays/passage.h"
#include "transport/rays/tracing.h"

namespace plm {

// Per covered texel: sums of the gather's samples (albedo x radiosity / pi of
// what each ray sees). Their variance of the mean takes the gather's typical
// sample as the phantom (StratifiedSums::variance_of_mean).
struct GatherSums : StratifiedSums {};

// What a texel's gather met, besides its sums.
struct GatherInfo {
  uint32_t unknown = 0;   // rays that hit what the source cannot look up
  uint32_t dark = 0;      // rays that met a dark back: known zeros
  // The gather's error from the source's own (per ray, albedo x the looked-up
  // texel's error; the means are over the rays), all squared. Of the local
  // parts: the mean as if all were one error (lookup_all), the sum over cells
  // of the pooling's reach of each cell's share squared (lookup_cells: rays
  // that look up one cell share its error), and the sum of each ray's share
  // squared (lookup_rays). The three give how much of a texel's rays look up
  // the same error (Estimator: the lookups' correlation). Of the wide parts:
  // the mean, squared (one error everywhere).
  double lookup_all = 0.0, lookup_cells = 0.0, lookup_rays = 0.0, lookup_wide = 0.0;
  // The harmonic mean of the rays' hit distances, rays that leave the scene
  // counted as infinitely far (Ward's irradiance-cache radius): how far the
  // bounce light stays smooth.
  float hit_distance = std::numeric_limits<float>::infinity();
  // At calibration texels (gather_calibration_step), where both have pairs: the
  // squared difference between the mean and an independent replicate's, and
  // the sum of their pair estimates of the variance of the mean; else 0.
  float calibration_measured = 0.0f, calibration_estimated = 0.0f;
};

// What the gather's rays look up.
struct GatherSource {
  const float* radiosity = nullptr;  // 3 per global texel: irradiance / pi, direct + indirect (0 where uncovered)
  // 1 per global texel each: the error of its mean RGB that lookups see, local and wide (reconstruct.h: LookupError)
  const float* local = nullptr;
  const float* wide = nullptr;
  const std::vector<std::vector<Vec3>>* albedo = nullptr;  // per mesh, per triangle
  const uint8_t* back_lit = nullptr;  // per mesh: a photon reached its back (else its backs are dark)
  const float* open = nullptr;        // per global texel: FinalGather::open_share (null: 1 everywhere)
  // With light groups: per global texel, each layer's share of its radiosity
  // (3 per layer: texel t's layer l at 3 * (t * layers + l)), or null.
  const float* layer_share = nullptr;
  uint32_t layers = 0;
  bool directional = false;  // directional lightmaps: the rays' direction moments are kept (split.h)
};

class FinalGather {
 public:
  // From the context: in scenes with passable materials its rays go on
  // through them (transport/rays/passage.h); in scenes with lobes a ray
  // meeting the front of a surface without a diffuse part (glass, metal)
  // counts a known 0 even where that surface has no lightmap; where some
  // material's diffuse radiance depends on where it leaves
  // (MaterialLobes::view_scale: layers, Burley), the table says how.
  explicit FinalGather(const BakeScene& ctx);

  // Adds `samples` (rounded up to a square) cosine-distributed rays from the
  // direct pass's points of texel `texel` of mesh `mesh` (meshes only). Each
  // sample is the light reflected by the surface it hits, albedo x that
  // texel's radiosity; 0 for rays that leave the scene, and for the back of a
  // surface no photon reached from behind (the inside of a box standing on
  // the ground is dark), and so for backs that photons reached unless more
  // than a quarter of the rays see such backs (lightmaps are one-sided). A ray
  // that hits what the source cannot look up (a mesh without its own texels,
  // a CSG solid, such backs) counts in info.unknown: such a texel's gather is
  // not used. Thread-safe for distinct texels.
  // With the source's layer shares or directional lightmaps, split
  // (transport/context/split.h: the source's layers, then the direction moment)
  // gets the split of the sums' rgb.
  void sample_texel(uint32_t mesh, uint32_t texel, uint32_t round, uint32_t samples, const GatherSource& source,
                    GatherSums& sums, GatherInfo& info, float* split = nullptr) const;

  // The share of a texel's points (those its value is the mean over) that
  // light can reach: neither inside a closed object standing on the surface
  // (a ray along the normal meets the back of a mesh whose backs no photon
  // reached: back_lit, per mesh) nor pressed against another face
  // (in_contact). A floor texel half under a box holds half the light of
  // its lit part, where a gather ray lands.
  float open_share(uint32_t mesh, uint32_t texel, const uint8_t* back_lit) const;

 private:
  // sample_texel without (kPassage false: the loop as in scenes without
  // passable materials) or with rays through passages.
  template <bool kPassage>
  void sample(uint32_t mesh, uint32_t texel, uint32_t round, uint32_t samples, const GatherSource& source,
              GatherSums& sums, GatherInfo& info, float* split) const;
  // The albedo where a ray lands on a mesh triangle: the texture's there, else the triangle's.
  Vec3 albedo_at(const SurfaceHit& h, const GatherSource& source) const;
  // Lane l's hit, continued through passable surfaces; through: their weight.
  SurfaceHit passed(const RayPacket& packet, unsigned l, Vec3 dir, Vec3& through) const;

  RTCScene rtc_;
  const SurfaceMap& surfaces_;
  const std::vector<MeshView>& views_;
  const std::vector<TexelAreas>& areas_;
  TexelPoints points_;
  uint32_t seed_;
  float offset_scale_;
  uint32_t cell_side_;  // texels: the side of the cells whose texels share photon errors
  const PassageTracer* passage_;
  bool black_known_;
  const MaterialTable* materials_;
  const TextureSet* textures_;  // null without image textures
};

// The gather of every covered texel, in the film's covered order.
// FinalGather::open_share per global texel, kept between the gathers of one
// bake and made again only when the meshes whose backs photons reached
// change; empty where no texel can be partly closed (every mesh's backs lit,
// no faces in contact).
struct OpenShares {
  std::vector<uint8_t> back_lit;  // per mesh, as the shares were made for
  std::vector<float> share;
};
// Makes `open` again where back_lit (per mesh) differs from what it was made for.
void update_open_shares(tbb::task_arena& arena, const FinalGather& gather, const TexelSpace& space,
                        const uint8_t* back_lit, OpenShares& open);

struct GatherResult {
  std::vector<GatherSums> sums;  // empty: no gather
  std::vector<GatherInfo> info;
  // With light groups or directional lightmaps: per covered texel, the split
  // of sums' rgb (transport/context/split.h: 3 floats per slot; texel k's slot l
  // at 3 * (k * slots + l)).
  std::vector<float> split_rgb;
  uint32_t slots = 0;
  double typical = 0.0;  // the phantom sample (typical_sample)
  double scale = 1.0;    // what makes the pair estimates honest (gather_scale)
};

// Every this-th texel of the covered order is a calibration texel (GatherInfo).
size_t gather_calibration_step(size_t covered);

// The scale of the gather's pair estimates of the variance from its
// calibration texels (calibration_ratio). A cosine-weighted gather over
// stratified directions and points varies far less than the pairs of
// neighbouring strata say: 0.2-0.7 on the benchmark scenes.
double gather_scale(const std::vector<GatherInfo>& info);

// Runs the gather with `samples` rays per covered texel (meshes only) in the
// context's arena, looking up `images` (per mesh: R, G, B, error per texel, as transport/output/film_estimate.h's
// Estimate holds them) and `local` and `wide` (per mesh, the error per texel
// that lookups see: Estimate::lookup_local, lookup_wide) with each
// triangle's `albedo` and the meshes whose backs photons reached
// (`back_lit`). Calibration texels are gathered once more, independently
// (GatherInfo), and give the result's scale. after_group() runs on the
// calling thread between groups of texels; false stops the gather (texels
// left without rays keep the photon estimate). Over the covered texels of
// `slice` (all by default; the sums then start at its first): a texel's rays
// depend on it and the images alone, so slices give the same sums as one run
// (the scale is recomputed over all of them: join_gather).
struct GatherLookup {
  const std::vector<std::vector<float>>& images;
  const std::vector<std::vector<float>>& local;
  const std::vector<std::vector<float>>& wide;
  const std::vector<std::vector<Vec3>>& albedo;
  const uint8_t* back_lit;
  // With light groups: per mesh, per texel, each layer's share of its light
  // (3 floats per layer), or null.
  const std::vector<std::vector<float>>* layer_shares = nullptr;
};
// A gather after the first (transport/plan/scheduler.h, plan_regather): the
// texels of the judged groups marked in `groups` are gathered again; the
// others, and those the time budget leaves no time for, keep what they had in
// `before` (the same slice's result, moved from).
struct Regather {
  const std::vector<uint8_t>* groups = nullptr;  // null: every texel is gathered
  GatherResult* before = nullptr;
};
GatherResult run_final_gather(const BakeScene& ctx, const FinalGather& gather, const GatherLookup& lookup,
                              OpenShares& open, uint32_t samples, const std::function<bool()>& after_group,
                              CoveredSlice slice = {}, Regather again = {});

}  // namespace plm

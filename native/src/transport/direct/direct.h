// The direct pass ([Thesis §3.5.2], two-pass use of lightmaps): each texel's
// direct light is estimated from stratified points inside the part of the
// texel its triangles cover, shadow rays from each point towards every light
// or a chosen one (see all_lights_). The points come from texel_points.h; the
// rounds that give noisy texels more samples are in direct_rounds.h.
#pragma once

#include <cstdint>
#include <vector>

#include "lightmap/texel_area.h"
#include "scene/texture.h"
#include "transport/context/bake_scene.h"
#include "transport/direct/stratified_sums.h"
#include "transport/direct/texel_points.h"
#include "transport/lights/emitters.h"
#include "transport/rays/passage.h"
#include "transport/rays/tracing.h"
#include "util/rng.h"
#include "util/sobol.h"

namespace plm {

// What the texels' direct variances need beyond their own sums.
struct DirectNoise {
  double typical = 0.0;  // RMS of all direct samples of all texels (the phantom sample, see below)
  double scale = 1.0;    // true / pair-difference variance, measured with independent replicates:
                         // below 1 for Sobol points, whose pairs differ more than their means vary
  double sky_scale = 1.0, other_scale = 1.0;  // the same for the world's part and the rest (DirectSums::sky_rgb)
};

// Per covered texel: sums of (irradiance / pi) samples.
struct DirectSums : StratifiedSums {
  double choice_sq = 0; // with one light chosen per sample: the spread of the lights' sample counts
                        // (n^2 x its variance of the mean), summed over rounds
  // Where every sample sends a shadow ray to every light (DirectPass::all_lights_)
  // and the world lights the scene: the world's part of the samples (its sky
  // light), which the estimate pools over neighbouring texels (direct_pool.h).
  float sky_rgb[3] = {0, 0, 0};
  float sky_pair_sq = 0, other_pair_sq = 0;  // pair differences of the world's part and of the rest
  uint32_t sky_rays = 0;       // the world's shadow rays (0: the samples are not split)
  // Round 0's world rays that something blocks, and the sum of 1 / distance to it.
  uint32_t sky_blocked = 0;
  float sky_inv_distance = 0;
  // Squared standard error of the mean, noise.typical as the phantom sample
  // (StratifiedSums::variance_of_mean), with choice_sq and noise.scale.
  double variance_of_mean(const DirectNoise& noise) const {
    return StratifiedSums::variance_of_mean(noise.typical, choice_sq, noise.scale);
  }
  // The phantom sample's part of it (all of it without pairs).
  double phantom_variance_of_mean(const DirectNoise& noise) const;
  // The same from the stratum pairs and choice_sq alone (0 without pairs), unscaled.
  double pair_variance_of_mean() const;
  // The same of the world's part and of the rest (with choice_sq) of split samples.
  double sky_pair_variance_of_mean() const;
  double other_pair_variance_of_mean() const;
  // Mean RGB of the world's part.
  double sky_mean() const { return count ? (double(sky_rgb[0]) + sky_rgb[1] + sky_rgb[2]) / (3.0 * count) : 0.0; }
  // Adds another set of samples of the same texel.
  void merge(const DirectSums& o);
};

class DirectPass {
 public:
  explicit DirectPass(const BakeScene& ctx);

  // Adds `samples` (rounded up to a square) stratified samples of round `round`
  // to texel `texel` of mesh `mesh`; mesh = mesh count + c means sub-texel
  // `texel` of CSG solid c. Thread-safe for distinct texels. With light
  // groups or directional lightmaps, split (3 x split().slots() floats, or null) gets
  // the samples' light split by the lights' layers and its direction moment
  // (transport/context/split.h; the same light as sums.rgb).
  void sample_texel(uint32_t mesh, uint32_t texel, uint32_t round, uint32_t samples, DirectSums& sums,
                    float* split = nullptr) const;
  const SplitLayout& split() const { return split_; }
  // Whether a sample sends one shadow ray to a light chosen at random (more than kAllLights lights).
  bool chooses_lights() const { return !all_lights_; }
  static bool chooses_lights(size_t emitters) { return emitters > kAllLights; }

 private:
  // sample_texel without (kPassage false: as in scenes without passable
  // materials) or with shadow and MIS rays through passages.
  template <bool kPassage>
  void sample(uint32_t mesh, uint32_t texel, uint32_t round, uint32_t samples, DirectSums& sums,
              float* split) const;
  // Shares of the local choice among `count` candidate lights at point p,
  // normal n: share[i] = 0.9 x candidate i's unoccluded irradiance / their
  // sum. Returns the local part, 0.9, or 0 if no candidate lights p.
  float local_shares(Vec3 p, Vec3 n, const uint32_t* candidates, size_t count, float* share) const;
  // Per-thread scratch of sample_texel's light choice.
  struct ChoiceScratch {
    struct Tally {  // one light's samples in the current texel
      double sum = 0.0, unpaired = 0.0;
      uint32_t count = 0;
    };
    std::vector<Tally> tallies;
    std::vector<uint32_t> touched;  // lights with a tally
    std::vector<int32_t> slot_of;   // light -> candidate slot, -1 if none
    std::vector<float> guess;
    std::vector<uint32_t> order;
    std::vector<uint32_t> others;      // the lights with power that are not candidates,
    std::vector<double> others_cdf;    // and their cumulative choice probability
  };
  // Fills chosen[0 .. kCandidates) with the lights of most unoccluded
  // irradiance at p (normal n) and scratch's slot_of, others and others_cdf.
  void select_candidates(Vec3 p, Vec3 n, uint32_t* chosen, ChoiceScratch& scratch) const;
  // The light of the local choice whose interval holds u_pick.
  size_t choose_local(float u_pick, const uint32_t* candidates, size_t count, const float* share, float local,
                      bool select, const ChoiceScratch& scratch) const;
  // choice_sq from the texel's per-light tallies (selected: candidates were selected).
  static void add_choice_spread(ChoiceScratch& scratch, bool selected, const uint32_t* chosen, DirectSums& sums);
  // A sample between the tracing of its shadow rays and its sums.
  struct PendingSample {
    Vec3 origin, normal, shading, e;  // normal: geometric; shading: the interpolated one (smooth meshes)
    Vec3 sky;                         // the world's part of e (split_sky_)
    float v[2];                       // the cosine-sampled (MIS) direction's numbers
    float burley;                     // the point's Burley roughness, < 0 for Lambert
    size_t k;                         // the light chosen
    uint32_t tri;
    bool inside, contact;
  };
  // What a texel's samples draw their numbers from: Sobol dimensions or the
  // stream, and the texel's strata (m x m = n over the window at origin, side wide).
  struct SampleNumbers {
    SobolGroup light, mis, piece, surface;
    uint32_t pick_key, n, m;
    float origin_x, origin_y, side;
    bool sparse;
  };
  void draw(const SampleNumbers& d, uint32_t j, Rng& rng, float& x, float& y, float& u_pick, float* u, float* v,
            float* w) const;
  // A texel's running pairs: of successive strata, and of the world's part and the rest.
  struct TexelTally {
    StratumPairs pairs, split_pairs;
    double previous_sky = 0.0, previous_other = 0.0;
  };
  void add_sample(uint32_t j, const PendingSample& ps, bool split_sky, TexelTally& tally, ChoiceScratch& scratch,
                  DirectSums& sums) const;
  // Shadow rays of a chunk of samples, traced in packets.
  struct ShadowRays {
    RayPacket packet;
    Vec3 value[RayPacket::kLanes];  // a lane's irradiance if nothing blocks it
    uint32_t sample[RayPacket::kLanes];
    uint32_t layer[RayPacket::kLanes];  // the light's layer (light groups)
    Vec3 u[RayPacket::kLanes] = {};     // the ray's direction weight (directional lightmaps)
    uint32_t sky_lanes = 0;  // bit l: lane l is a ray to the world's smooth part (split_sky_)
  };
  template <bool kPassage>
  void trace_shadow_rays(ShadowRays& rays, PendingSample* chunk, bool measure_reach, DirectSums& sums,
                         float* split) const;
  // The MIS ray's light at a sample (probability(k): light k's choice probability).
  template <bool kPassage, class Probability>
  // The light also goes to the texel's split (add_split).
  Vec3 cosine_ray_light(const PendingSample& ps, TraceContext& tc, bool smooth, const Probability& probability,
                        float* split) const;

  RTCScene rtc_;
  const SurfaceMap& surfaces_;
  const std::vector<MeshView>& views_;
  const std::vector<CsgView>& csgs_;
  const std::vector<Emitter>& emitters_;
  // Emissive triangles are also found by cosine-sampled rays, combined with
  // light sampling by multiple importance sampling (balance heuristic): near
  // a large emitter light sampling alone has a heavy-tailed 1/d^2 variance.
  std::vector<std::vector<int32_t>> triangle_emitter_;  // [mesh][triangle] -> emitter or -1
  bool has_triangle_emitters_ = false;
  // Emission textures: a textured emitter's radiance is looked up at the
  // sampled (or hit) point. Null, and has_textured_emitters_ false, without.
  const TextureSet* textures_;
  bool has_textured_emitters_ = false;
  // Scenes with passable materials (transport/rays/passage.h): shadow rays and
  // the MIS rays pass through them with a weight. Null otherwise.
  const PassageTracer* passage_;
  TexelPoints points_;
  uint32_t seed_;
  bool sobol_;
  float offset_scale_;
  // Which light a sample's shadow ray goes to. Up to kAllLights emitters:
  // every sample point sends one to each (a sun and a sky: 2 rays, and no
  // noise from choosing between them). More: one,
  // chosen 90 % in proportion to the candidates' unoccluded irradiance at the
  // texel's first point (local_shares) and 10 % by power (every light keeps a
  // share: no bias). The candidates are all lights up to kCandidates, else
  // the kCandidates brightest there (a cost of O(lights) per texel). Beyond
  // kMaxLocalChoice lights (emissive meshes), one chosen by power.
  // With a choice, a sun and the world (up to kAllLights of them: distant_)
  // still get a ray from every sample, and the choice is among the other
  // lights: the unoccluded irradiance of a sun or a sky says nothing of
  // shade, so in a building's shadow a sun among the choices would take most
  // of the samples and give nothing, while the lamps there would seldom be
  // chosen.
  std::vector<uint32_t> distant_;
  std::vector<uint8_t> is_distant_;  // per emitter (empty without distant_)
  EmitterTable table_;               // by power, the distant_ lights left out
  static constexpr size_t kAllLights = 4, kCandidates = 32, kMaxLocalChoice = 256;
  bool all_lights_;
  // All lights, a world among them, no passable materials: each sample's
  // world part is kept apart (DirectSums::sky_rgb), and its shadow rays are
  // intersected for their distance (the reach of the pooling). is_sky_[k]:
  // emitter k is the world's smooth part (not a map's sun, which is sharp).
  bool split_sky_ = false;
  std::vector<uint8_t> is_sky_;
  bool local_choice_;
  // The candidates when there are at most kCandidates (every light not in
  // distant_), and each emitter's place among them (-1: none).
  std::vector<uint32_t> all_candidates_;
  std::vector<int32_t> all_slot_;
  SplitLayout split_;
};

}  // namespace plm

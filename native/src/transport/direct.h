// The direct pass (thesis 3.5.2, two-pass use of lightmaps): each texel's
// direct light is estimated from stratified points inside the part of the
// texel its triangles cover, shadow rays from each point towards every light
// or a chosen one (see all_lights_). Rounds can be added to texels that stay
// noisy.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "lightmap/texel_area.h"
#include "texture/texture.h"
#include "transport/emitters.h"
#include "transport/tracing.h"

namespace plm {

// What the texels' direct variances need beyond their own sums.
struct DirectNoise {
  double typical = 0.0;  // RMS of all direct samples of all texels (the phantom sample, see below)
  double scale = 1.0;    // true / pair-difference variance, measured with independent replicates:
                         // below 1 for Sobol points, whose pairs differ more than their means vary
};

// Per covered texel: sums of (irradiance / pi) samples.
struct DirectSums {
  double rgb[3] = {0, 0, 0};
  double sum_sq = 0;    // sum of squared mean-RGB samples
  double pair_sq = 0;   // sum over neighbouring stratum pairs of squared mean-RGB differences
  uint32_t paired = 0;  // samples in those pairs
  double choice_sq = 0; // with one light chosen per sample: the spread of the lights' sample counts
                        // (n^2 x its variance of the mean), summed over rounds
  uint32_t count = 0;
  double mean() const { return count ? (rgb[0] + rgb[1] + rgb[2]) / (3.0 * count) : 0.0; }
  // Squared standard error of the mean. noise.typical enters as one phantom
  // sample, so that a texel whose samples all missed a rarely visible light
  // (the sky through a window) does not look exact. With no pair yet, 100%
  // uncertain.
  double variance_of_mean(const DirectNoise& noise) const;
  // The phantom sample's part of it (all of it without pairs).
  double phantom_variance_of_mean(const DirectNoise& noise) const;
  // The same from the stratum pairs and choice_sq alone (0 without pairs), unscaled.
  double pair_variance_of_mean() const;
  void add(const DirectSums& o);
};

class DirectPass {
 public:
  DirectPass(RTCScene rtc, const std::vector<MeshView>& views, const std::vector<CsgView>& csgs,
             const std::vector<TexelAreas>& areas, const std::vector<Emitter>& emitters,
             const plm_bake_settings& settings, float scene_extent, const TextureSet* textures = nullptr);

  // Adds `samples` (rounded up to a square) stratified samples of round `round`
  // to texel `texel` of mesh `mesh`; mesh = mesh count + c means sub-texel
  // `texel` of CSG solid c. Thread-safe for distinct texels.
  void sample_texel(uint32_t mesh, uint32_t texel, uint32_t round, uint32_t samples, DirectSums& sums) const;

  // Final gather (see GatherSource): adds `samples` (rounded up to a
  // square) cosine-distributed rays from the same points as sample_texel's;
  // each sample is the light reflected by the surface it hits, albedo x that
  // texel's radiosity (0 for rays that leave the scene: the sky is direct
  // light); 0 also for the back of a surface (the inside of a box standing on
  // the ground is dark: no photon reaches the back of its faces), and so
  // does the back of a surface lit from behind unless more than a quarter of
  // the rays see such backs (lightmaps are one-sided). A ray that hits what
  // the source cannot look up (a mesh without its own texels, a CSG solid,
  // such backs) counts in `unknown`: such a texel's gather is not used.
  // Meshes only (mesh < mesh count). Thread-safe for distinct texels.
  struct GatherSource {
    const float* radiosity = nullptr;  // 3 per global texel: irradiance / pi, direct + indirect (0 where uncovered)
    const float* error = nullptr;      // 1 per global texel: the estimated error of its mean RGB
    const std::vector<std::vector<Vec3>>* albedo = nullptr;  // per mesh, per triangle
    const uint8_t* back_lit = nullptr;  // per mesh: a photon reached its back (else its backs are dark)
  };
  // What a texel's gather met, besides its sums.
  struct GatherInfo {
    uint32_t unknown = 0;   // rays that hit what the source cannot look up
    uint32_t dark = 0;      // rays that met a dark back: known zeros
    // The mean over the samples of albedo x the looked-up texel's error, the
    // gather's error from the source's own errors (taken as fully
    // correlated: the source is a pooled photon estimate, and a texel's rays
    // hit neighbouring texels).
    double lookup_error = 0.0;
    // The harmonic mean of the rays' hit distances, rays that leave the scene
    // counted as infinitely far (Ward's irradiance-cache radius): how far the
    // bounce light stays smooth.
    float hit_distance = std::numeric_limits<float>::infinity();
  };
  void gather_texel(uint32_t mesh, uint32_t texel, uint32_t round, uint32_t samples, const GatherSource& source,
                    DirectSums& sums, GatherInfo& info) const;

 private:
  bool surface_point(uint32_t mesh, uint32_t texel, float x, float y, Vec3& p, Vec3& n, uint32_t& tri) const;
  bool point_in_pieces(uint32_t mesh, uint32_t texel, const float u[3], Vec3& p, Vec3& n, uint32_t& tri) const;
  int64_t centre_owner(uint32_t mesh, uint32_t texel) const;
  Vec3 mirrored_point(uint32_t mesh, uint32_t tri, float x, float y) const;
  // If the square [ox, ox + size]^2 of texel coordinates lies inside triangle
  // tri's UVs (mirrored_point is then the point itself): the point at (ox, oy)
  // and its change per texel in x and y, so a sample costs two multiply-adds.
  bool window_map(uint32_t mesh, uint32_t tri, float ox, float oy, float size, Vec3& base, Vec3& du, Vec3& dv) const;
  // Where a texel's sample points lie: its strata cover the texel (origin,
  // side per stratum), or with PLM_TEXEL_CYCLES its central half if a
  // triangle (owner) covers the centre; points there are folded into the
  // owner as Cycles does (mirrored_point), or mapped affinely when the window
  // lies inside it. Barely covered texels (sparse) sample their covered
  // pieces directly.
  struct TexelWindow {
    float origin_x = 0.0f, origin_y = 0.0f, side = 1.0f;
    int64_t owner = -1;
    bool sparse = false, affine = false;
    Vec3 base, du, dv;
  };
  TexelWindow texel_window(uint32_t mesh, uint32_t texel, uint32_t strata_per_side) const;
  // The point for texel coordinates (x, y) (or, sparse, the piece numbers
  // w); false outside the islands.
  bool texel_point(const TexelWindow& tw, uint32_t mesh, uint32_t texel, float x, float y, const float w[3], Vec3& p,
                   Vec3& n, uint32_t& tri) const;
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

  RTCScene rtc_;
  const std::vector<MeshView>& views_;
  const std::vector<CsgView>& csgs_;
  const std::vector<TexelAreas>& areas_;
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
  uint32_t seed_;
  bool cycles_window_;  // sample the texel's central half (PLM_TEXEL_CYCLES), not all of it
  bool sobol_;
  float offset_scale_;
  EmitterTable table_;
  // Which light a sample's shadow ray goes to. Up to kAllLights emitters:
  // every sample point sends one to each (a sun and a sky: 2 rays, and no
  // noise from choosing between them; on the open benchmark scene 2.0 % error
  // at 16 samples against 3.9 % for one ray to a chosen light). More: one,
  // chosen 90 % in proportion to the candidates' unoccluded irradiance at the
  // texel's first point (local_shares) and 10 % by power (every light keeps a
  // share: no bias). The candidates are all lights up to kCandidates, else
  // the kCandidates brightest there (a cost of O(lights) per texel). Beyond
  // kMaxLocalChoice lights (emissive meshes), one chosen by power.
  static constexpr size_t kAllLights = 4, kCandidates = 32, kMaxLocalChoice = 256;
  bool all_lights_;
  bool local_choice_;
  std::vector<uint32_t> all_candidates_;  // 0 .. lights - 1 when there are at most kCandidates
};

}  // namespace plm

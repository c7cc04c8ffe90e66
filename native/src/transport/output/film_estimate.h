// The estimate of every texel at one state of the bake: the photons'
// reconstruction (lightmap/reconstruct.h), blended with the final gather by
// variance, plus the direct light, with each texel's estimated error. One
// estimate serves three uses: the error check that steers the photon pass,
// the final gather's lookups and the final images.
#pragma once

#include <tbb/task_arena.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "lightmap/reconstruct.h"
#include "transport/direct/direct_pool.h"
#include "transport/direct/direct_rounds.h"
#include "transport/film/film.h"
#include "transport/gather/final_gather.h"
#include "transport/plan/scheduler.h"

namespace plm {

// Buffers an estimate reuses from lightmap to lightmap (one set per thread):
// a lightmap's texels, the photons' guide, and what combining them with the
// gather works in.
struct EstimateBuffers {
  std::vector<double> value3, variance;
  LookupError lookup;
  std::vector<double> guide;
  std::vector<double> g_guide, g_mean, g_var, g_value, g_fit_var, lookup_rays, rays_fit, fit1, var1, rays1;
  std::vector<double> excess, bias_sq, v_photons, v_gather;
  std::vector<uint8_t> usable, radius;
  // Per texel, the photons' weight w in the indirect light's blend with the
  // final gather (combine_gather; 1 where the gather is not used); empty
  // without a gather.
  std::vector<double> photon_weight;
};

// The photons' reconstruction of every lightmap at one photon count, per
// covered texel in covered order (reconstruct_indirect's value, error and
// lookup errors): the estimate after a final gather reuses it.
struct PhotonPart {
  uint64_t photons = ~uint64_t(0);  // ~0: none
  std::vector<double> value3, mse, local, wide;
};

// Sums of the final gather's part of texels' variances: all of it, and its
// rays' own noise (what more rays lower; the rest is what they looked up).
struct GatherPart {
  double all = 0.0, rays = 0.0;
  GatherPart& operator+=(const GatherPart& o) {
    all += o.all, rays += o.rays;
    return *this;
  }
};

// Everything the estimate of a texel needs.
struct Estimator {
  const TexelSpace& space;
  const DirectValues& direct;  // per covered texel (transport/direct/direct_pool.h), or empty
  const Accumulators& acc;
  uint32_t filter_radius;
  const GatherResult* gather = nullptr;  // per covered texel (empty sums without a gather)
  // Whether estimates also give the error the final gather's lookups see (Estimate::lookup_local, lookup_wide).
  bool lookups = false;
  // With light groups: the direct pass's sums, per layer too (DirectResult::layer_rgb), or null.
  const DirectResult* direct_result = nullptr;
  // The share of each texel that light can reach, in the global texel order
  // (the final gather's OpenShares::share), or null / empty: all open. The
  // error counts texels by it: a texel inside another object is never seen.
  const std::vector<float>* open_share = nullptr;
  // The direct light and the gather sample texels' central squares (texel
  // value CYCLES), the photons the whole texel: near walls they differ.
  bool central_window = false;
  // Texel t of mesh i's open share (1 without shares).
  double open_weight(size_t i, size_t t) const;
  // The relative variance of the level of mesh i's indirect light, sum k^2 /
  // (sum k)^2 over the photons that left k hits on its group: each photon's
  // hits share its fate, so a mean over many of its texels -- what the final
  // gather's rays look up from afar -- varies by that much, whatever the
  // hits' own spread says (Accumulators::group_hits). A wide error of every
  // lookup (0 without the sums).
  double level_variance(size_t i) const;

  // The guide of mesh i's photon reconstruction (its texels' direct light,
  // lightmap/reconstruct.h ReconstructParams::guide) in `buffer`; null
  // without a direct pass.
  const double* guide(size_t i, std::vector<double>& buffer) const;

  // Sub-texel `sub` of CSG solid c: irradiance / pi (3 values) and its
  // estimated mean squared error. No pooling: the photon estimate of the
  // sub-texel alone (cut sub-texels may be tiny, and their neighbours on
  // other faces or primitives), plus its direct light.
  double csg_texel(size_t c, uint32_t sub, uint64_t photons, double value3[3]) const;

  // Per texel of mesh i: irradiance / pi (3 values) and its estimated mean
  // squared error; the final gather's part of the variances is added to
  // *gather_part (all of it, and the rays' own noise). With `lookup`, also
  // the mean squared error that the final gather's lookups see
  // (reconstruct.h: LookupError).
  // In `b`: value3 and variance; with `lookups`, b.lookup too. With `part`,
  // the photons' reconstruction is read from it if it holds `photons`, else
  // written to it (the caller then sets part->photons).
  void texels(size_t i, uint64_t photons, EstimateBuffers& b, GatherPart* gather_part = nullptr, bool lookups = false,
              PhotonPart* part = nullptr) const;

 private:
  void combine_gather(size_t i, EstimateBuffers& b, GatherPart* gather_part, LookupError* lookup) const;
  void add_caustics(size_t i, uint64_t photons, std::vector<double>& value3, std::vector<double>& variance,
                    LookupError* lookup) const;
};

// Estimated error over all covered texels: sqrt(mean variance) / mean value,
// texels weighted equally; direct and gather: the same with the direct
// variance alone and with the final gather's part alone. The target judges
// each group of TexelSpace::judged apart: the same three relative to the
// group's own mean. Texels count by the share of them light can reach (once
// a final gather has found it: Estimator::open_share). A group whose mean is
// at most kDarkGroupShare x the whole's is dark, like one without light: an
// object buried in others (or shut away from every light) holds only
// rounding residue and light leaked along the seams, and its texels without a
// photon keep the variance of one (the phantom hit), so relative to its own
// mean it would hold the bake to the photon cap for what nobody sees (10
// stops below the scene's mean).
constexpr double kDarkGroupShare = 1e-3;
struct ErrorEstimate : ErrorParts {
  // Per judged group; the whole's parts alone where there are none (every
  // texel resolved from an OL or a CSG solid without a carrier).
  std::vector<ErrorParts> groups;
  uint32_t worst = kNoGroup;       // the group with the largest relative error (kNoGroup: none)
  double median = 0.0, p95 = 0.0;  // of the per-texel relative errors
  std::vector<double> per_texel;    // the per-texel relative errors (of texels with light)
  size_t dark_texels = 0;           // covered texels with no light (no relative error)
};

// The relative error of the worst judged group (the whole's without groups).
inline double worst_relative(const ErrorEstimate& e) {
  return e.worst == kNoGroup ? e.relative : e.groups[e.worst].relative;
}

// The ordinary lightmaps' texels at one state of the bake: per mesh with own
// texels R, G, B and error per texel (the images before dilation, 0 where
// uncovered), and the error over all texels. Each costs a reconstruction of
// every lightmap, so the bake keeps the latest and reuses it while nothing
// changed.
struct Estimate {
  uint64_t photons = ~uint64_t(0);  // the state it was made from (~0: none yet)
  size_t gather_size = 0;
  ErrorEstimate error;
  std::vector<std::vector<float>> values;
  // Per mesh and texel, where the estimator has lookups: the error the final
  // gather's lookups see, local and wide (Estimator::texels).
  std::vector<std::vector<float>> lookup_local, lookup_wide;
  PhotonPart photon_part;  // from before the first gather to the next photons (estimate)

  bool current(uint64_t p, const GatherResult& gather) const {
    return photons == p && gather_size == gather.sums.size();
  }
};

void estimate(tbb::task_arena& arena, const Estimator& est, uint64_t photons, Estimate& out);

// The share of texels whose relative error is above `threshold` (dark texels count as below).
double share_above(const ErrorEstimate& e, double threshold);

// Texel t of a lightmap image (R, G, B, error: 4 floats a texel) from an
// estimate's value3 / variance.
inline void store_texel(const std::vector<double>& value3, const std::vector<double>& variance, size_t t,
                        float* image) {
  for (int c = 0; c < 3; ++c) image[4 * t + c] = float(value3[3 * t + c]);
  image[4 * t + 3] = float(std::sqrt(variance[t]));
}

}  // namespace plm

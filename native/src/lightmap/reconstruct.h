// Reconstruction of the photon (indirect) part of a lightmap. A texel's
// estimate may pool the photon sums of the neighbouring texels that continue
// the same surface (never other islands or across creases) within a square of
// radius r. Pooling trades variance for bias, and both are estimated:
//   variance  from the squared hit fluxes of the pooled region;
//   bias^2    from the change against the texel's own estimate,
//             (v_r - v_0)^2 - (var_0 - var_r): unbiased for the squared bias,
//             but noisy, so only its mean over a lightmap is used.
// With a guide (the direct light), texels also pool only with neighbours of
// similar direct light: contact shadows and shadow edges, where indirect light
// changes too, are not blurred across.
// Each lightmap gets the radius with the smallest estimated mean squared
// error over its texels (averaged over many texels, the choice is not fooled
// by noise), and each texel reports sqrt(its variance + the lightmap's mean
// squared bias) as its error, so the bake's error estimate and steering stay
// honest.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "lightmap/texel_area.h"

namespace plm {

struct PhotonSums {
  const double* flux;    // 3 per texel: sum of hit flux (not yet divided by the photon count)
  const double* sq;      // 1 per texel: sum of squared mean-RGB hit flux
  const uint32_t* hits;  // 1 per texel
};

struct ReconstructParams {
  uint32_t max_radius = 2;     // texels; 0 = each texel alone (barely covered ones still pool)
  double photons = 1.0;        // photons traced: sums are divided by it
  double phantom_sq = 0.0;     // squared flux of one average hit, added (per texel's worth of
                               // covered area) to every variance so that texels with few hits
                               // do not look exact
  float min_coverage = 0.25f;  // texels below it always pool with their neighbours (radius >= 1)
  // Optional guide per texel (the direct light): texels pool only with
  // neighbours of similar guide, so indirect light does not leak across the
  // contact shadows and shadow edges that the direct light shows.
  // A texel whose guide is negative (or NaN) pools with no other.
  const double* guide = nullptr;
  // >= 0: pool at this radius, chosen elsewhere (a light group's share pools as
  // its bake's whole did), with no bias estimate.
  int32_t fixed_radius = -1;
};

// The lightmap's texel side in world units: sqrt(total area / total
// coverage); 0 when nothing is covered.
double texel_width(const TexelAreas& ta);

// True if texel b continues texel a's surface: normals within ~25 degrees,
// world positions within `reach` (m).
bool same_surface(const TexelAreas& ta, uint32_t a, uint32_t b, float reach, float min_cos = 0.9f);

// Texels m and t pool only where their guides (the direct light) differ by at
// most half the larger one plus `floor`; a negative (or NaN) guide pools with none.
bool similar_guide(const double* guide, uint32_t m, uint32_t t, double floor);

// 5 % of the guide's mean over the n covered texels (negative guides left out):
// similar_guide's floor.
double guide_floor_of(const TexelAreas& ta, const double* guide, size_t n);

// The error that the final gather's lookups see per texel (squared), in two
// parts by how far it is shared: `local` by the texels within a pool's reach
// (the photons' noise, the direct light's), `wide` by the whole lightmap (the
// pooling's bias, and what a gather carries in from the far texels it looked
// up). A mean over lookups in many places averages the local part down and
// keeps the wide part whole.
struct LookupError {
  std::vector<double> local, wide;
};

// Writes per texel the indirect irradiance / pi (3 values) and its estimated
// mean squared error (variance + squared bias); texels without area get 0.
// With `lookup`, also the error that a mean over many lookups (the final
// gather's) sees: locally the mean of the pool's squared hits and the phantom
// hit times the hits the pool can expect at the lightmap's mean density (two
// estimates of the pool's variance, the second never 0), and widely the
// lightmap's mean squared bias. A pool that photons reach once in ten bakes
// is off by a hit once in ten; the whole phantom, which bounds one texel's
// error, overstates such lookups tenfold in variance where photons are sparse.
// Returns the radius chosen for the lightmap.
uint32_t reconstruct_indirect(const TexelAreas& ta, uint32_t width, uint32_t height, const PhotonSums& sums,
                              const ReconstructParams& params, std::vector<double>& value3,
                              std::vector<double>& mse, LookupError* lookup = nullptr);

// Per texel, a local linear fit (weighted by texel area) of per-texel means
// `mean3` (3 per texel, independent estimates of variance `variance`) over
// the same-surface, similar-guide texels within `radius`: its value at the
// texel's centre, and that value's variance. Unlike a mean, a linear fit has
// no first-order bias where the neighbourhood is one-sided (a wall's foot).
// The fits are scaled to keep the lightmap's total (sum of area x value,
// per channel): one-sided windows and changing radii weigh some texels more
// than others, which moves the total of a field that curves near the edges.
// `texel_radius` (optional) caps the radius per texel; min_cos is the least
// cosine between the normals of texels that fit together (same_surface).
// With variance2 (optional), var2_out gets the fit's variance for those
// per-texel variances too (another part of the means' error, same weights).
void reconstruct_linear(const TexelAreas& ta, uint32_t width, uint32_t height, const double* mean3,
                        const double* variance, const double* guide, uint32_t radius, std::vector<double>& value3,
                        std::vector<double>& var_out, const uint8_t* texel_radius = nullptr, float min_cos = 0.9f,
                        const double* variance2 = nullptr, std::vector<double>* var2_out = nullptr);

// The squared bias of local linear fits (reconstruct_linear) by radius (0 at
// radius 0), from the fits of radius 1 and 2 and their variances (value3 and
// var_out of each) over the n texels where takes_part(t) holds: those whose
// reach allows radius 2. A linear fit's bias over a window of radius r grows
// as r^2 (the curvature it cannot follow), so the two fits differ by 3/4 of
// the larger one's bias: E (f2 - f1)^2 = (3/4 b2)^2 + var1 - var2 (nested
// windows). Averaged over many texels the difference is far steadier than
// a comparison with one texel's own noisy mean. `texels`: how many took part.
struct FitBias {
  double sq[3] = {0.0, 0.0, 0.0};
  size_t texels = 0;
};
template <typename TakesPart>
FitBias linear_fit_bias(const std::vector<double>& fit1, const std::vector<double>& var1,
                        const std::vector<double>& fit2, const std::vector<double>& var2, size_t n,
                        TakesPart takes_part) {
  FitBias out;
  double excess = 0.0;
  for (size_t t = 0; t < n; ++t) {
    if (!takes_part(t)) continue;
    ++out.texels;
    const double d =
        (fit2[3 * t] + fit2[3 * t + 1] + fit2[3 * t + 2] - fit1[3 * t] - fit1[3 * t + 1] - fit1[3 * t + 2]) / 3.0;
    excess += d * d - std::max(0.0, var1[t] - var2[t]);
  }
  if (out.texels == 0) return out;
  out.sq[1] = std::max(0.0, excess / double(out.texels)) / 9.0;  // (4/3)^2 / 16 of the mean excess
  out.sq[2] = 16.0 * out.sq[1];
  return out;
}

// The radius of linear fits (0: the texels' own means, 1 or 2) of least
// estimated error over the n texels where takes_part(t): the fits' variances
// (variance(r, t)) summed, plus each texel's squared bias at the radius its
// reach allows (reach[t] caps the radius; bias from linear_fit_bias).
template <typename TakesPart, typename Variance>
uint32_t least_error_radius(size_t n, const uint8_t* reach, const FitBias& bias, TakesPart takes_part,
                            Variance variance) {
  double var[3] = {0.0, 0.0, 0.0};
  size_t reach1 = 0, reach2 = 0;  // texels whose reach allows radius 1, 2
  for (size_t t = 0; t < n; ++t) {
    if (!takes_part(t)) continue;
    for (uint32_t r = 0; r < 3; ++r) var[r] += variance(r, t);
    reach1 += reach[t] >= 1, reach2 += reach[t] >= 2;
  }
  const double mse[3] = {var[0], var[1] + double(reach1) * bias.sq[1],
                         var[2] + double(reach2) * bias.sq[2] + double(reach1 - reach2) * bias.sq[1]};
  return uint32_t(std::min_element(mse, mse + 3) - mse);
}

}  // namespace plm

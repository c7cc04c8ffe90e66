#include "transport/direct/direct_pool.h"

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "lightmap/reconstruct.h"

namespace plm {
namespace {

bool split(const DirectSums& d) { return d.sky_rays > 0 && d.paired > 0 && d.count > 0; }

// One lightmap's texels (t, mesh-local) in the slice with split samples:
// sky3 their world part's mean, var their pair variance of it, phantom their
// phantom sample's variance, guide their direct mean (-1 for the others, which
// pool with none), radius the reach of their fit; and the fits of radius 1
// and 2. One per thread, reused from lightmap to lightmap.
struct SkyMap {
  std::vector<double> sky3, var, phantom, guide;
  std::vector<uint8_t> radius;
  size_t pooled = 0;
  std::vector<double> fit1, var1, phantom1, fit2, var2, phantom2;
};

}  // namespace

DirectValues pool_direct(const TexelSpace& space, const std::vector<DirectSums>& sums, size_t first,
                         const DirectNoise& noise) {
  DirectValues out;
  const size_t end = first + sums.size();
  out.value3.resize(3 * sums.size());
  out.variance.resize(sums.size());
  out.phantom.resize(sums.size());
  for (size_t j = 0; j < sums.size(); ++j) {  // the texels' own values, replaced below where pooled
    const DirectSums& d = sums[j];
    for (int c = 0; c < 3; ++c) out.value3[3 * j + c] = d.count ? d.rgb[c] / d.count : 0.0;
    out.variance[j] = d.variance_of_mean(noise);
    out.phantom[j] = d.phantom_variance_of_mean(noise);
  }
  // Split texels test every lamp with every sample (a sun behind a blocker
  // is a known zero): only the world can be missed by all of a texel's samples
  // (through a window), so their phantom is a typical world part, the RMS of
  // the split texels' world means, not a typical sample, which the sun makes
  // 3x larger in an open scene (the sky-lit side of a sphere reported 2.4x its
  // error).
  double sky_sq = 0.0, sky_texels = 0.0;
  for (const DirectSums& d : sums)
    if (split(d)) sky_sq += d.sky_mean() * d.sky_mean(), sky_texels += 1.0;
  const double typical_sky = sky_texels > 0.0 ? std::sqrt(sky_sq / sky_texels) : 0.0;
  // Lightmaps in parallel (for_lightmaps; each writes its own texels, its
  // fits run in parallel too), so that many small ones keep every core busy.
  tbb::enumerable_thread_specific<SkyMap> maps;
  for_lightmaps(space.views.size(), [&](size_t i) { return space.areas[i].area.size(); }, [&](size_t i) {
    if (!space.views[i].texel_area) return;
    SkyMap& m = maps.local();
    std::vector<double> &fit1 = m.fit1, &var1 = m.var1, &phantom1 = m.phantom1;
    std::vector<double> &fit2 = m.fit2, &var2 = m.var2, &phantom2 = m.phantom2;
    const TexelAreas& ta = space.areas[i];
    const size_t n = ta.area.size(), k0 = space.covered_begin[i];
    m.sky3.assign(3 * n, 0.0);
    m.var.assign(n, 0.0);
    m.phantom.assign(n, 0.0);
    m.guide.assign(n, -1.0);
    m.radius.assign(n, 0);
    m.pooled = 0;
    const double width = texel_width(ta);
    for (size_t t = 0, k = k0; t < n; ++t) {
      if (!(ta.area[t] > 0.0)) continue;
      const size_t kk = k++;
      if (kk < first || kk >= end || !split(sums[kk - first])) continue;
      const DirectSums& d = sums[kk - first];
      for (int c = 0; c < 3; ++c) m.sky3[3 * t + c] = double(d.sky_rgb[c]) / d.count;
      // A split texel's world part and rest each have their own pairs and
      // calibration (the light choice's spread goes with the rest).
      m.var[t] = noise.sky_scale * d.sky_pair_variance_of_mean();
      const double missed = typical_sky - d.sky_mean();
      m.phantom[t] = noise.scale * missed * missed / (double(d.count) * d.count);
      m.guide[t] = d.mean();
      // Ambient occlusion changes over about the distance to what blocks the
      // sky: the harmonic mean of the blocked rays' distances.
      const double reach = d.sky_blocked ? kSkyReach * double(d.sky_blocked) / double(d.sky_inv_distance)
                                         : std::numeric_limits<double>::infinity();
      m.radius[t] = uint8_t(std::min(double(kSkyRadius), std::floor(reach / std::max(width, 1e-30))));
      ++m.pooled;
    }
    if (m.pooled < kMinPooledTexels) return;
    const uint32_t w = space.views[i].mesh->lightmap_width, h = space.views[i].mesh->lightmap_height;
    // The radius with the least estimated mean squared error over the
    // lightmap's split texels: a fit's variance plus its squared bias
    // (linear_fit_bias, over the texels whose reach allows radius 2; a
    // texel's own mean is too noisy to compare with, its variance estimate
    // rough: Sobol pairs, one calibration for all). Radius 0 keeps the own
    // means, exact in mean. Each pooled texel's variance takes the squared
    // bias of its radius.
    static_assert(kSkyRadius == 2, "the bias estimate compares the fits of radius 1 and 2");
    const double* sky3 = m.sky3.data();
    reconstruct_linear(ta, w, h, sky3, m.var.data(), m.guide.data(), 1, fit1, var1, m.radius.data(), kSkyMinCos,
                       m.phantom.data(), &phantom1);
    reconstruct_linear(ta, w, h, sky3, m.var.data(), m.guide.data(), 2, fit2, var2, m.radius.data(), kSkyMinCos,
                       m.phantom.data(), &phantom2);
    const FitBias fit_bias =
        linear_fit_bias(fit1, var1, fit2, var2, n, [&](size_t t) { return m.guide[t] >= 0.0 && m.radius[t] >= 2; });
    if (fit_bias.texels < kMinPooledTexels / 4) return;  // too few texels to estimate the bias by
    const double* bias = fit_bias.sq;
    const std::vector<double>* vars[3] = {&m.var, &var1, &var2};
    const uint32_t best_r = least_error_radius(
        n, m.radius.data(), fit_bias, [&](size_t t) { return m.guide[t] >= 0.0; },
        [&](uint32_t r, size_t t) { return (*vars[r])[t]; });
    if (best_r == 0) return;
    const std::vector<double>& best3 = best_r == 1 ? fit1 : fit2;
    const std::vector<double>& best_var = best_r == 1 ? var1 : var2;
    const std::vector<double>& best_phantom = best_r == 1 ? phantom1 : phantom2;
    for (size_t t = 0, k = k0; t < n; ++t) {
      if (!(ta.area[t] > 0.0)) continue;
      const size_t kk = k++;
      if (m.guide[t] < 0.0) continue;
      const DirectSums& d = sums[kk - first];
      double* value = &out.value3[3 * (kk - first)];
      // Light is not negative: a linear fit can dip below 0 where the sky
      // falls steeply (at a contact), the rest by float rounding where it is 0.
      for (int c = 0; c < 3; ++c)
        value[c] = std::max(0.0, (d.rgb[c] - double(d.sky_rgb[c])) / d.count) + std::max(0.0, best3[3 * t + c]);
      out.phantom[kk - first] = best_phantom[t];
      const double bias_sq = bias[std::min<uint32_t>(m.radius[t], best_r)];
      out.variance[kk - first] =
          noise.other_scale * d.other_pair_variance_of_mean() + best_var[t] + best_phantom[t] + bias_sq;
    }
  });
  return out;
}

}  // namespace plm

#include "lightmap/reconstruct.h"

#include <algorithm>
#include <cmath>

namespace plm {

bool same_surface(const TexelAreas& ta, uint32_t a, uint32_t b, float reach) {
  if (!(ta.area[b] > 0.0)) return false;
  const Vec3 gap = ta.position[b] - ta.position[a];
  return dot(ta.normal[a], ta.normal[b]) >= 0.9f && dot(gap, gap) <= reach * reach;
}

namespace {

constexpr uint32_t kMaxRadius = 16;

struct Pooled {
  double flux[3] = {0, 0, 0};
  double sq = 0, area = 0;
};

// Pools texel t with its same-surface neighbours ring by ring up to radius
// r_max; calls at(r, pooled) after each radius.
template <typename At>
void pool_rings(const TexelAreas& ta, uint32_t width, uint32_t height, const PhotonSums& s, uint32_t t,
                uint32_t r_max, float texel_width, const double* guide, double guide_floor, At&& at) {
  const uint32_t x = t % width, y = t / width;
  Pooled p;
  for (int c = 0; c < 3; ++c) p.flux[c] = s.flux[3 * size_t(t) + c];
  p.sq = s.sq[t];
  p.area = ta.area[t];
  at(0u, p);
  for (uint32_t r = 1; r <= r_max; ++r) {
    const float reach = 1.5f * float(r + 1) * texel_width;
    const int64_t x0 = int64_t(x) - r, x1 = int64_t(x) + r, y0 = int64_t(y) - r, y1 = int64_t(y) + r;
    for (int64_t yy = std::max<int64_t>(y0, 0); yy <= std::min<int64_t>(y1, int64_t(height) - 1); ++yy) {
      const bool edge_row = yy == y0 || yy == y1;
      for (int64_t xx = x0; xx <= x1; xx += edge_row ? 1 : (x1 - x0)) {
        if (xx < 0 || xx >= int64_t(width)) continue;
        const uint32_t m = uint32_t(yy) * width + uint32_t(xx);
        if (!same_surface(ta, t, m, reach)) continue;
        if (guide && std::fabs(guide[m] - guide[t]) > 0.5 * std::max(guide[m], guide[t]) + guide_floor) continue;
        for (int c = 0; c < 3; ++c) p.flux[c] += s.flux[3 * size_t(m) + c];
        p.sq += s.sq[m];
        p.area += ta.area[m];
      }
    }
    at(r, p);
  }
}

}  // namespace

uint32_t reconstruct_indirect(const TexelAreas& ta, uint32_t width, uint32_t height, const PhotonSums& sums,
                              const ReconstructParams& params, std::vector<double>& value3,
                              std::vector<double>& mse) {
  const size_t n = size_t(width) * height;
  value3.assign(3 * n, 0.0);
  mse.assign(n, 0.0);
  double total_area = 0.0, total_cover = 0.0;
  for (size_t t = 0; t < n; ++t) {
    total_area += ta.area[t];
    total_cover += ta.coverage[t];
  }
  if (!(total_cover > 0.0)) return 0;
  const float texel_width = float(std::sqrt(total_area / total_cover));
  const double to_value = 1.0 / (kPiD * params.photons);
  const uint32_t r_max = std::min(params.max_radius, kMaxRadius);
  double guide_floor = 0.0;  // guide differences below 5% of its mean always pool
  if (params.guide) {
    double sum = 0.0, count = 0.0;
    for (size_t t = 0; t < n; ++t)
      if (ta.area[t] > 0.0) sum += params.guide[t], count += 1.0;
    guide_floor = count > 0.0 ? 0.05 * sum / count : 0.0;
  }

  auto mean_value = [&](const Pooled& p) { return (p.flux[0] + p.flux[1] + p.flux[2]) / 3.0 * to_value / p.area; };
  auto variance = [&](const Pooled& p) {
    const double k = to_value / p.area;
    return (p.sq + params.phantom_sq) * k * k;
  };
  // Unbiased estimate of a pooled texel's squared bias; noisy, negative at
  // times: only sums over many texels are used.
  auto bias_sq = [&](const Pooled& p, double v0, double var0) {
    const double d = mean_value(p) - v0;
    return d * d - std::max(0.0, var0 - variance(p));
  };
  auto is_sparse = [&](size_t t) { return ta.coverage[t] < params.min_coverage; };

  // Pass 1: the estimated mean squared error of the whole lightmap per radius.
  double total_var[kMaxRadius + 1] = {}, total_bias[kMaxRadius + 1] = {};
  double counted = 0.0;
  for (uint32_t t = 0; t < n; ++t) {
    if (!(ta.area[t] > 0.0) || is_sparse(t)) continue;
    counted += 1.0;
    double v0 = 0.0, var0 = 0.0;
    pool_rings(ta, width, height, sums, t, r_max, texel_width, params.guide, guide_floor, [&](uint32_t r, const Pooled& p) {
      if (r == 0) {
        v0 = mean_value(p);
        var0 = variance(p);
      }
      total_var[r] += variance(p);
      total_bias[r] += bias_sq(p, v0, var0);
    });
  }
  uint32_t chosen = 0;
  auto total_mse = [&](uint32_t r) { return total_var[r] + std::max(0.0, total_bias[r]); };
  for (uint32_t r = 1; r <= r_max; ++r)
    if (total_mse(r) < total_mse(chosen)) chosen = r;
  const double mean_bias_sq = counted > 0.0 ? std::max(0.0, total_bias[chosen]) / counted : 0.0;

  // Pass 2: every texel at the chosen radius (barely covered ones at least 1);
  // its error: its own variance plus the lightmap's mean squared bias.
  for (uint32_t t = 0; t < n; ++t) {
    if (!(ta.area[t] > 0.0)) continue;
    const uint32_t r_t = is_sparse(t) ? std::max(chosen, 1u) : chosen;
    pool_rings(ta, width, height, sums, t, r_t, texel_width, params.guide, guide_floor, [&](uint32_t r, const Pooled& p) {
      if (r != r_t) return;
      const double k = to_value / p.area;
      for (int c = 0; c < 3; ++c) value3[3 * size_t(t) + c] = p.flux[c] * k;
      mse[t] = variance(p) + mean_bias_sq;
    });
  }
  return chosen;
}

}  // namespace plm

#include "lightmap/reconstruct.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace plm {

double texel_width(const TexelAreas& ta) {
  double total_area = 0.0, total_cover = 0.0;
  for (size_t t = 0; t < ta.area.size(); ++t) total_area += ta.area[t], total_cover += ta.coverage[t];
  return total_cover > 0.0 ? std::sqrt(total_area / total_cover) : 0.0;
}

bool same_surface(const TexelAreas& ta, uint32_t a, uint32_t b, float reach, float min_cos) {
  if (!(ta.area[b] > 0.0)) return false;
  const Vec3 gap = ta.position[b] - ta.position[a];
  return dot(ta.normal[a], ta.normal[b]) >= min_cos && dot(gap, gap) <= reach * reach;
}

bool similar_guide(const double* guide, uint32_t m, uint32_t t, double floor) {
  return guide[m] >= 0.0 && guide[t] >= 0.0 &&
         std::fabs(guide[m] - guide[t]) <= 0.5 * std::max(guide[m], guide[t]) + floor;
}

double guide_floor_of(const TexelAreas& ta, const double* guide, size_t n) {
  double sum = 0.0, count = 0.0;
  for (size_t t = 0; t < n; ++t)
    if (ta.area[t] > 0.0 && guide[t] >= 0.0) sum += guide[t], count += 1.0;
  return count > 0.0 ? 0.05 * sum / count : 0.0;
}

namespace {

constexpr uint32_t kMaxRadius = 16;

// Rows of texels per parallel task. Sums over texels add up per block of
// rows, then the blocks in order: the same result for any thread count.
constexpr uint32_t kBlockRows = 4;

template <typename Row>
void for_rows(uint32_t height, Row&& row) {
  tbb::parallel_for(uint32_t(0), (height + kBlockRows - 1) / kBlockRows, [&](uint32_t b) {
    for (uint32_t y = b * kBlockRows; y < std::min(height, (b + 1) * kBlockRows); ++y) row(b, y);
  });
}

struct Pooled {
  double flux[3] = {0, 0, 0};
  double sq = 0, area = 0;
  double cover = 0;  // covered fraction, in texels
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
  p.cover = ta.coverage[t];
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
        if (guide && !similar_guide(guide, m, t, guide_floor)) continue;
        for (int c = 0; c < 3; ++c) p.flux[c] += s.flux[3 * size_t(m) + c];
        p.sq += s.sq[m];
        p.area += ta.area[m];
        p.cover += ta.coverage[m];
      }
    }
    at(r, p);
  }
}

}  // namespace

uint32_t reconstruct_indirect(const TexelAreas& ta, uint32_t width, uint32_t height, const PhotonSums& sums,
                              const ReconstructParams& params, std::vector<double>& value3,
                              std::vector<double>& mse, LookupError* lookup) {
  const size_t n = size_t(width) * height;
  value3.assign(3 * n, 0.0);
  mse.assign(n, 0.0);
  if (lookup) lookup->local.assign(n, 0.0), lookup->wide.assign(n, 0.0);
  const float texel_width = float(plm::texel_width(ta));
  if (!(texel_width > 0.0f)) return 0;
  const double to_value = 1.0 / (kPiD * params.photons);
  const uint32_t r_max = std::min(params.max_radius, kMaxRadius);
  // guide differences below 5% of its mean always pool
  const double guide_floor = params.guide ? guide_floor_of(ta, params.guide, n) : 0.0;

  auto mean_value = [&](const Pooled& p) { return (p.flux[0] + p.flux[1] + p.flux[2]) / 3.0 * to_value / p.area; };
  // The phantom is one average hit per texel's worth of area: a pool that
  // covers a fraction c of a texel gets c of it. A hit lands in a sliver c
  // times as often as in a whole texel, so its variance grows as 1 / area,
  // not 1 / area^2 (one whole phantom hit on a 1 % sliver overstates its
  // error 100x, since photons hit it 100x less often than a texel).
  auto variance = [&](const Pooled& p) {
    const double k = to_value / p.area;
    return (p.sq + params.phantom_sq * std::min(1.0, p.cover)) * k * k;
  };
  // Unbiased estimate of a pooled texel's squared bias; noisy, negative at
  // times: only sums over many texels are used.
  // The variances here are the hits' own, without the phantom hit: E[(v_r -
  // v_0)^2] = bias^2 + Var v_0 - Var v_r for the true variances, which the
  // squared hit fluxes estimate without bias; the phantom would overstate Var
  // v_0 of texels with few hits and hide the bias (open scene: reported 0.63 x
  // the measured photon error at 0.8 M photons).
  auto hit_variance = [&](const Pooled& p) {
    const double k = to_value / p.area;
    return p.sq * k * k;
  };
  auto bias_sq = [&](const Pooled& p, double v0, double var0) {
    const double d = mean_value(p) - v0;
    return d * d - std::max(0.0, var0 - hit_variance(p));
  };
  auto is_sparse = [&](size_t t) { return ta.coverage[t] < params.min_coverage; };

  // Pass 1: the estimated mean squared error of the whole lightmap per radius
  // (none at a fixed radius).
  struct Totals {
    double var[kMaxRadius + 1] = {}, bias[kMaxRadius + 1] = {};
    double counted = 0.0;
  };
  std::vector<Totals> blocks((height + kBlockRows - 1) / kBlockRows);
  if (params.fixed_radius >= 0) blocks.clear();
  for_rows(blocks.empty() ? 0 : height, [&](uint32_t b, uint32_t y) {
    Totals& s = blocks[b];
    for (uint32_t t = y * width; t < (y + 1) * width; ++t) {
      if (!(ta.area[t] > 0.0) || is_sparse(t)) continue;
      s.counted += 1.0;
      double v0 = 0.0, var0 = 0.0;
      pool_rings(ta, width, height, sums, t, r_max, texel_width, params.guide, guide_floor, [&](uint32_t r, const Pooled& p) {
        if (r == 0) {
          v0 = mean_value(p);
          var0 = hit_variance(p);
        }
        s.var[r] += variance(p);
        s.bias[r] += bias_sq(p, v0, var0);
      });
    }
  });
  double total_var[kMaxRadius + 1] = {}, total_bias[kMaxRadius + 1] = {};
  double counted = 0.0;
  for (const Totals& s : blocks) {
    for (uint32_t r = 0; r <= r_max; ++r) total_var[r] += s.var[r], total_bias[r] += s.bias[r];
    counted += s.counted;
  }
  uint32_t chosen = 0;
  auto total_mse = [&](uint32_t r) { return total_var[r] + std::max(0.0, total_bias[r]); };
  for (uint32_t r = 1; r <= r_max; ++r)
    if (total_mse(r) < total_mse(chosen)) chosen = r;
  if (params.fixed_radius >= 0) chosen = std::min(uint32_t(params.fixed_radius), kMaxRadius);
  const double mean_bias_sq = counted > 0.0 ? std::max(0.0, total_bias[chosen]) / counted : 0.0;

  // Hits per texel's worth of covered area, for the lookups' local error.
  double density = 0.0;
  if (lookup) {
    double hits = 0.0, cover = 0.0;
    for (size_t t = 0; t < n; ++t)
      if (ta.area[t] > 0.0) hits += sums.hits[t], cover += ta.coverage[t];
    density = cover > 0.0 ? hits / cover : 0.0;
  }

  // Pass 2: every texel at the chosen radius (barely covered ones at least 1);
  // its error: its own variance plus the lightmap's mean squared bias.
  for_rows(height, [&](uint32_t, uint32_t y) {
    for (uint32_t t = y * width; t < (y + 1) * width; ++t) {
      if (!(ta.area[t] > 0.0)) continue;
      const uint32_t r_t = is_sparse(t) ? std::max(chosen, 1u) : chosen;
      pool_rings(ta, width, height, sums, t, r_t, texel_width, params.guide, guide_floor, [&](uint32_t r, const Pooled& p) {
        if (r != r_t) return;
        const double k = to_value / p.area;
        for (int c = 0; c < 3; ++c) value3[3 * size_t(t) + c] = p.flux[c] * k;
        mse[t] = variance(p) + mean_bias_sq;
        if (lookup) {
          lookup->local[t] = 0.5 * (p.sq + params.phantom_sq * p.cover * density) * k * k;
          lookup->wide[t] = mean_bias_sq;
        }
      });
    }
  });
  return chosen;
}

void reconstruct_linear(const TexelAreas& ta, uint32_t width, uint32_t height, const double* mean3,
                        const double* variance, const double* guide, uint32_t radius, std::vector<double>& value3,
                        std::vector<double>& var_out, const uint8_t* texel_radius, float min_cos,
                        const double* variance2, std::vector<double>* var2_out) {
  const size_t n = size_t(width) * height;
  value3.assign(3 * n, 0.0);
  var_out.assign(n, 0.0);
  if (var2_out) var2_out->assign(n, 0.0);
  const float texel_width = float(plm::texel_width(ta));
  if (!(texel_width > 0.0f)) return;
  const float reach = 1.5f * float(radius + 1) * texel_width;
  const double floor = guide ? guide_floor_of(ta, guide, n) : 0.0;
  const uint32_t r_max = std::min(radius, kMaxRadius);
  auto radius_of = [&](uint32_t t) -> int64_t { return texel_radius ? std::min<uint32_t>(texel_radius[t], r_max) : r_max; };
  // Texel k takes part in t's fit.
  auto pools = [&](uint32_t t, uint32_t k) {
    return k == t || (same_surface(ta, t, k, reach, min_cos) && (!guide || similar_guide(guide, k, t, floor)));
  };
  // Per texel, the fit's intercept weights (first row of the inverse of the
  // normal equations): texel k's weight in t's value is area_k (e0 + e1 dx + e2 dy).
  std::vector<double> coef(3 * n, 0.0);
  for_rows(height, [&](uint32_t, uint32_t row) {
    for (uint32_t t = row * width; t < (row + 1) * width; ++t) {
      if (!(ta.area[t] > 0.0)) continue;
      const int64_t r = radius_of(t);
      const int64_t x = t % width, y = t / width;
      // Normal equations of the fit v = a + b dx + c dy, weights = texel areas;
      // the texels that take part, in row order, for the second loop.
      double m[6] = {0, 0, 0, 0, 0, 0};  // s1, sx, sy, sxx, sxy, syy
      uint32_t part[(2 * kMaxRadius + 1) * (2 * kMaxRadius + 1)];
      size_t parts = 0;
      for (int64_t yy = std::max<int64_t>(y - r, 0); yy <= std::min<int64_t>(y + r, int64_t(height) - 1); ++yy)
        for (int64_t xx = std::max<int64_t>(x - r, 0); xx <= std::min<int64_t>(x + r, int64_t(width) - 1); ++xx) {
          const uint32_t k = uint32_t(yy * width + xx);
          if (!pools(t, k)) continue;
          part[parts++] = k;
          const double w = ta.area[k], dx = double(xx - x), dy = double(yy - y);
          m[0] += w, m[1] += w * dx, m[2] += w * dy, m[3] += w * dx * dx, m[4] += w * dx * dy, m[5] += w * dy * dy;
        }
      // First row of the inverse (cofactors / determinant): the weights of the intercept.
      const double c0 = m[3] * m[5] - m[4] * m[4], c1 = m[2] * m[4] - m[1] * m[5], c2 = m[1] * m[4] - m[2] * m[3];
      const double det = m[0] * c0 + m[1] * c1 + m[2] * c2;
      // An ill-posed fit (neighbours along a line, or none): the weighted mean.
      const bool linear = det > 1e-6 * m[0] * m[0] * m[0];
      double* e = &coef[3 * size_t(t)];
      e[0] = linear ? c0 / det : 1.0 / m[0], e[1] = linear ? c1 / det : 0.0, e[2] = linear ? c2 / det : 0.0;
      double sum3[3] = {0, 0, 0}, var = 0.0, var2 = 0.0;
      for (size_t j = 0; j < parts; ++j) {
        const uint32_t k = part[j];
        const int64_t xx = k % width, yy = k / width;
        const double l = ta.area[k] * (e[0] + e[1] * double(xx - x) + e[2] * double(yy - y));
        for (int c = 0; c < 3; ++c) sum3[c] += l * mean3[3 * size_t(k) + c];
        var += l * l * variance[k];
        if (var2_out) var2 += l * l * variance2[k];
      }
      for (int c = 0; c < 3; ++c) value3[3 * size_t(t) + c] = sum3[c];
      var_out[t] = var;
      if (var2_out) (*var2_out)[t] = var2;
    }
  });
  // The fits' total over the lightmap, sum_t area_t value_t, is sum_k area_k
  // mean_k C_k with C_k = sum_t area_t (e0 + e1 dx + e2 dy) over the fits k
  // takes part in: 1 where the windows are whole, not at a surface's edges
  // or where the radius changes. There a field that curves (bounce light
  // peaking inside a room's ceiling and falling to its edges) loses or gains
  // light: the surfaces of a room lit through a window 1-4 %. So the fit is
  // scaled to keep the total, with its own values standing in for the means'
  // expectations (their noise would carry into the scale).
  std::vector<double> column(n, 0.0);
  for_rows(height, [&](uint32_t, uint32_t row) {
    for (uint32_t k = row * width; k < (row + 1) * width; ++k) {
      if (!(ta.area[k] > 0.0)) continue;
      const int64_t x = k % width, y = k / width;
      for (int64_t yy = std::max<int64_t>(y - r_max, 0); yy <= std::min<int64_t>(y + r_max, int64_t(height) - 1); ++yy)
        for (int64_t xx = std::max<int64_t>(x - r_max, 0); xx <= std::min<int64_t>(x + r_max, int64_t(width) - 1); ++xx) {
          const uint32_t t = uint32_t(yy * width + xx);
          if (!(ta.area[t] > 0.0)) continue;
          const int64_t r = radius_of(t);
          if (std::abs(xx - x) > r || std::abs(yy - y) > r || !pools(t, k)) continue;
          const double* e = &coef[3 * size_t(t)];
          column[k] += ta.area[t] * (e[0] + e[1] * double(x - xx) + e[2] * double(y - yy));
        }
    }
  });
  double kept[3] = {0, 0, 0}, expected[3] = {0, 0, 0};
  for (size_t t = 0; t < n; ++t)
    for (int c = 0; c < 3; ++c) {
      kept[c] += ta.area[t] * value3[3 * t + c];
      expected[c] += ta.area[t] * column[t] * value3[3 * t + c];
    }
  for (int c = 0; c < 3; ++c) {
    const double s = expected[c] > 0.0 ? kept[c] / expected[c] : 1.0;
    if (!(s > 0.5 && s < 2.0)) continue;  // (a fit of mostly zeros, or of texels of mixed sign)
    for (size_t t = 0; t < n; ++t) value3[3 * t + c] *= s;
  }
}

}  // namespace plm

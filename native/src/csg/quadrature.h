// Gauss-Legendre nodes on [-1, 1], for the world areas of curved faces under
// non-uniform scale (no closed form: e.g. the ellipsoid).
#pragma once

#include <cmath>

namespace plm::csg {

struct GaussLegendre {
  static constexpr int n = 64;
  double x[n], w[n];
};

// Newton on the Legendre polynomial P_n from Chebyshev-like starting points.
inline GaussLegendre make_gauss_legendre() {
  GaussLegendre g{};
  const int n = GaussLegendre::n;
  for (int i = 0; i < n; ++i) {
    double x = std::cos(3.14159265358979323846 * (i + 0.75) / (n + 0.5)), dp = 1;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1, p1 = x;  // recurrence for P_n(x)
      for (int k = 2; k <= n; ++k) {
        const double p2 = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = n * (x * p1 - p0) / (x * x - 1);
      const double dx = p1 / dp;
      x -= dx;
      if (std::fabs(dx) < 1e-16) break;
    }
    g.x[i] = x;
    g.w[i] = 2 / ((1 - x * x) * dp * dp);
  }
  return g;
}

// Computed once (thread-safe static), then shared read-only.
inline const GaussLegendre& gauss_legendre_64() {
  static const GaussLegendre g = make_gauss_legendre();
  return g;
}

}  // namespace plm::csg

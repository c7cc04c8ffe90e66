// Real roots of low-degree polynomials on a bounded interval, for the torus
// quartic. Closed-form quartic solvers lose roots at grazing rays (two roots
// merging) and can return NaN; isolating roots between the critical points
// (the roots of the derivative, found the same way one degree lower) gives
// monotone pieces where a sign change brackets exactly one root, and a
// safeguarded Newton iteration then polishes it to full double precision.
#pragma once

#include <cmath>

namespace plm::csg {

// c[0] + c[1] x + ... + c[deg] x^deg.
inline double horner(const double* c, int deg, double x) {
  double r = c[deg];
  for (int i = deg - 1; i >= 0; --i) r = r * x + c[i];
  return r;
}

// The root in (a, b) of a polynomial that is monotone there with f(a) = fa and
// f(b) of the other sign: Newton steps, bisection whenever Newton leaves the bracket.
inline double bracketed_root(const double* c, int deg, double a, double b, double fa) {
  double dc[8];
  for (int i = 0; i < deg; ++i) dc[i] = (i + 1) * c[i + 1];
  const bool rising = fa < 0;
  double x = 0.5 * (a + b);
  const double tol = 4e-16 * (std::fabs(a) + std::fabs(b)) + 1e-300;
  for (int it = 0; it < 100; ++it) {
    const double f = horner(c, deg, x);
    if (f == 0) return x;
    if ((f < 0) == rising) a = x;
    else b = x;
    const double df = horner(dc, deg - 1, x);
    double next = df != 0 ? x - f / df : a;
    if (!(next > a && next < b)) next = 0.5 * (a + b);  // Newton left the bracket (or NaN)
    if (std::fabs(next - x) <= tol || b - a <= tol) return next;
    x = next;
  }
  return x;
}

// Real roots of the polynomial c (degree deg <= 7, c[deg] != 0) in [lo, hi],
// ascending; returns their number (<= deg). A root of even multiplicity is
// reported only if the value at a critical point is exactly zero.
inline int polynomial_roots(const double* c, int deg, double lo, double hi, double* roots) {
  if (deg == 1) {
    const double x = -c[0] / c[1];
    if (!(x >= lo && x <= hi)) return 0;
    roots[0] = x;
    return 1;
  }
  double dc[8], crit[8];
  for (int i = 0; i < deg; ++i) dc[i] = (i + 1) * c[i + 1];
  const int nc = polynomial_roots(dc, deg - 1, lo, hi, crit);
  crit[nc] = hi;
  int n = 0;
  double x0 = lo, f0 = horner(c, deg, lo);
  for (int i = 0; i <= nc; ++i) {
    const double x1 = crit[i], f1 = horner(c, deg, x1);
    if (f0 == 0) {
      if (n == 0 || roots[n - 1] < x0) roots[n++] = x0;
    } else if ((f0 < 0) != (f1 < 0) && f1 != 0) {
      roots[n++] = bracketed_root(c, deg, x0, x1, f0);
    }
    x0 = x1;
    f0 = f1;
  }
  if (f0 == 0 && (n == 0 || roots[n - 1] < x0)) roots[n++] = x0;
  return n;
}

}  // namespace plm::csg

#include "transport/materials/spectrum.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace plm {
namespace {

// A Gaussian with different widths left and right of its peak.
double lobe(double x, double mu, double s_left, double s_right) {
  const double t = (x - mu) / (x < mu ? s_left : s_right);
  return std::exp(-0.5 * t * t);
}

constexpr int kSteps = 400;  // table entries at 1 nm, midpoints

struct WeightTable {
  std::array<Vec3, kSteps + 1> w;  // at 380 + i nm
  WeightTable() {
    std::array<double, 3> mean{0, 0, 0};
    std::array<std::array<double, 3>, kSteps + 1> rgb;
    for (int i = 0; i <= kSteps; ++i) {
      const Vec3 xyz = cie_xyz(kLambdaMinNm + float(i));
      // XYZ -> linear sRGB (IEC 61966-2-1, D65 white).
      const double r = 3.2404542 * xyz.x - 1.5371385 * xyz.y - 0.4985314 * xyz.z;
      const double g = -0.9692660 * xyz.x + 1.8760108 * xyz.y + 0.0415560 * xyz.z;
      const double b = 0.0556434 * xyz.x - 0.2040259 * xyz.y + 1.0572252 * xyz.z;
      rgb[size_t(i)] = {std::max(r, 0.0), std::max(g, 0.0), std::max(b, 0.0)};
      // The mean over [380, 780] by the trapezoid rule: the same rule as the
      // linear interpolation rgb_weight uses, so the mean of the table is 1.
      const double trapezoid = (i == 0 || i == kSteps) ? 0.5 : 1.0;
      for (int c = 0; c < 3; ++c) mean[size_t(c)] += trapezoid * rgb[size_t(i)][size_t(c)] / kSteps;
    }
    for (int i = 0; i <= kSteps; ++i)
      w[size_t(i)] = {float(rgb[size_t(i)][0] / mean[0]), float(rgb[size_t(i)][1] / mean[1]),
                      float(rgb[size_t(i)][2] / mean[2])};
  }
};

}  // namespace

Vec3 cie_xyz(float lambda_nm) {
  const double l = lambda_nm;
  const double x = 1.056 * lobe(l, 599.8, 37.9, 31.0) + 0.362 * lobe(l, 442.0, 16.0, 26.7) -
                   0.065 * lobe(l, 501.1, 20.4, 26.2);
  const double y = 0.821 * lobe(l, 568.8, 46.9, 40.5) + 0.286 * lobe(l, 530.9, 16.3, 31.1);
  const double z = 1.217 * lobe(l, 437.0, 11.8, 36.0) + 0.681 * lobe(l, 459.0, 26.0, 13.8);
  return {float(x), float(y), float(z)};
}

Vec3 rgb_weight(float lambda_nm) {
  static const WeightTable table;
  const float x = lambda_nm - kLambdaMinNm;
  if (!(x >= 0.0f && x <= float(kSteps))) return {0, 0, 0};
  const int i = std::min(int(x), kSteps - 1);
  const float f = x - float(i);
  return table.w[size_t(i)] * (1.0f - f) + table.w[size_t(i + 1)] * f;
}

}  // namespace plm

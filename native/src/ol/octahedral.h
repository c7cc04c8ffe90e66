// Equal-area octahedral map of the sphere of directions onto [0,1]^2
// (Clarberg 2008, "Fast equal-area mapping of the (hemi)sphere using SIMD";
// the same map as pbrt-v4's EqualAreaSquareToSphere). The upper hemisphere
// fills the inner diamond |u'|+|v'| <= 1 (u' = 2u - 1), the lower one the four
// corner triangles, folded over the diamond's edges like an octahedron.
//
// Why this map: it has no singular point (unlike latitude-longitude, whose
// poles squeeze a whole row of bins into a point), it is continuous across
// the fold once the square's edges are glued (see OctGrid::wrap), and equal
// uv areas cover equal solid angles, so an N x N grid has bins of 4 pi / N^2
// each: bin areas and photon counts per bin are comparable everywhere.
// Measured (ol_octahedral_test): the ratio of the largest to the smallest
// numerically integrated bin solid angle is 1.0005 at N = 8 and 32, 1.002 at
// N = 128 (that residue is the geodesic-edge error of the integration, not
// the map), and the bins sum to 4 pi within 1e-13. What varies is bin shape
// (bins near the square's corners are longer than wide), not bin size.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "util/math.h"

namespace plm::ol {

// Largest grid side: 1024^2 bins of per-batch sums already take ~130 MB.
constexpr uint32_t kMaxOlResolution = 1024;

// Unit direction d -> (u, v) in [0,1]^2. d must be unit length (not checked).
inline void oct_encode(Vec3d d, double& u, double& v) {
  const double ax = std::fabs(d.x), ay = std::fabs(d.y), az = std::fabs(d.z);
  // 1 - |z| without cancellation near the poles: (x^2 + y^2) / (1 + |z|).
  const double r = std::sqrt((ax * ax + ay * ay) / (1.0 + az));
  const double phi = std::atan2(ay, ax) * (2.0 / kPiD);  // 0 on the x axis, 1 on the y axis
  double b = phi * r, a = r - b;
  if (d.z < 0) {  // fold into the corner triangle
    const double t = a;
    a = 1.0 - b;
    b = 1.0 - t;
  }
  u = 0.5 * (std::copysign(a, d.x) + 1.0);
  v = 0.5 * (std::copysign(b, d.y) + 1.0);
}

// (u, v) in [0,1]^2 -> unit direction.
inline Vec3d oct_decode(double u, double v) {
  const double a = 2.0 * u - 1.0, b = 2.0 * v - 1.0;
  const double ap = std::fabs(a), bp = std::fabs(b);
  const double sd = 1.0 - (ap + bp);  // > 0 inside the diamond: upper hemisphere
  const double r = 1.0 - std::fabs(sd);
  const double phi = (r == 0.0 ? 1.0 : (bp - ap) / r + 1.0) * (kPiD / 4.0);
  const double z = std::copysign(1.0 - r * r, sd);
  const double s = r * std::sqrt(std::fmax(0.0, 2.0 - r * r));
  return {std::copysign(std::cos(phi), a) * s, std::copysign(std::sin(phi), b) * s, z};
}

// The four bins a bilinear interpolation at a direction reads, and their
// weights (>= 0, summing to 1 up to rounding): the bins whose centres
// surround the direction's (u, v), found across the fold (OctGrid::wrap)
// within half a bin of the square's edge. A bin may appear twice there (the
// fold's mirror neighbour), and every tap is bin 0 at N = 1.
struct Taps {
  uint32_t bin[4];
  double weight[4];
};

// An N x N grid of bins over the octahedral square; bin = row * N + column,
// row along v. Holds the exact solid angle of every bin.
class OctGrid {
 public:
  // Throws plm::Error unless 1 <= resolution <= kMaxOlResolution.
  explicit OctGrid(uint32_t resolution);

  uint32_t resolution() const { return n_; }
  size_t bins() const { return size_t(n_) * n_; }

  // Bin of a unit direction (not checked; see OrientationLightmap for checks).
  uint32_t bin(Vec3d d) const {
    double u, v;
    oct_encode(d, u, v);
    return index(cell(u), cell(v));
  }
  uint32_t index(uint32_t column, uint32_t row) const { return row * n_ + column; }
  Vec3d centre(uint32_t bin) const {
    return oct_decode((bin % n_ + 0.5) / n_, (bin / n_ + 0.5) / n_);
  }
  double solid_angle(uint32_t bin) const { return omega_[bin]; }

  // Bilinear taps of a unit direction (not checked): bin centres sit at
  // integer (u N - 1/2, v N - 1/2), so a centre has weight 1 on its own bin.
  Taps taps(Vec3d d) const {
    double u, v;
    oct_encode(d, u, v);
    const double s = u * n_ - 0.5, t = v * n_ - 0.5;
    const double i0 = std::floor(s), j0 = std::floor(t);
    const double fx = s - i0, fy = t - j0;
    Taps out;
    for (int k = 0; k < 4; ++k) {
      const int di = k & 1, dj = k >> 1;
      out.weight[k] = (di ? fx : 1.0 - fx) * (dj ? fy : 1.0 - fy);
      out.bin[k] = wrap(int64_t(i0) + di, int64_t(j0) + dj);
    }
    return out;
  }

  // Bin of column i, row j, where i and j may lie one step outside [0, N):
  // the square's edges are glued as the octahedron folds, (0, v) to (0, 1 - v)
  // and (u, 0) to (1 - u, 0) (same for the far edges), so the neighbour across
  // an edge is the mirrored bin on the same edge.
  uint32_t wrap(int64_t i, int64_t j) const {
    const int64_t n = n_;
    if (i < 0) {
      i = -i - 1;
      j = n - 1 - j;
    } else if (i >= n) {
      i = 2 * n - 1 - i;
      j = n - 1 - j;
    }
    if (j < 0) {
      i = n - 1 - i;
      j = -j - 1;
    } else if (j >= n) {
      i = n - 1 - i;
      j = 2 * n - 1 - j;
    }
    return index(uint32_t(i), uint32_t(j));
  }

 private:
  uint32_t cell(double u) const {
    const double c = std::fmax(0.0, u) * n_;
    return c >= n_ ? n_ - 1 : uint32_t(c);
  }

  uint32_t n_;
  std::vector<double> omega_;
};

}  // namespace plm::ol

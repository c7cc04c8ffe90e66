// Template part of texel_area.h: Sutherland-Hodgman clipping of a triangle
// against horizontal strips and then texel cells. A convex polygon clipped by
// at most four axis-aligned lines has at most 7 vertices.
#pragma once

#include <algorithm>
#include <cmath>

namespace plm {
namespace detail {

constexpr int kMaxPolygon = 12;

// Keeps the part of polygon `in` with sign * (coord[axis] - bound) <= 0.
inline int clip_polygon(const double* in, int n, int axis, double bound, double sign, double* out) {
  int m = 0;
  for (int i = 0; i < n; ++i) {
    const double* a = in + 2 * i;
    const double* b = in + 2 * ((i + 1) % n);
    const double da = sign * (a[axis] - bound), db = sign * (b[axis] - bound);
    if (da <= 0.0) {
      out[2 * m] = a[0];
      out[2 * m + 1] = a[1];
      ++m;
    }
    if ((da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0)) {
      const double t = da / (da - db);
      out[2 * m] = a[0] + t * (b[0] - a[0]);
      out[2 * m + 1] = a[1] + t * (b[1] - a[1]);
      out[2 * m + axis] = bound;  // exact on the clip line
      ++m;
    }
  }
  return m;
}

}  // namespace detail

template <typename Add>
void clip_triangle_to_grid(const double tri[6], uint32_t width, uint32_t height, Add&& add) {
  using detail::clip_polygon;
  const double ymin = std::min({tri[1], tri[3], tri[5]}), ymax = std::max({tri[1], tri[3], tri[5]});
  const double xmin = std::min({tri[0], tri[2], tri[4]}), xmax = std::max({tri[0], tri[2], tri[4]});
  const int64_t row0 = std::max<int64_t>(0, static_cast<int64_t>(std::floor(ymin)));
  const int64_t row1 = std::min<int64_t>(int64_t(height) - 1, static_cast<int64_t>(std::floor(ymax)));
  const int64_t col0 = std::max<int64_t>(0, static_cast<int64_t>(std::floor(xmin)));
  const int64_t col1 = std::min<int64_t>(int64_t(width) - 1, static_cast<int64_t>(std::floor(xmax)));
  double strip_a[2 * detail::kMaxPolygon], strip[2 * detail::kMaxPolygon];
  double cell_a[2 * detail::kMaxPolygon], cell[2 * detail::kMaxPolygon];
  for (int64_t row = row0; row <= row1; ++row) {
    int n = clip_polygon(tri, 3, 1, double(row), -1.0, strip_a);       // y >= row
    n = clip_polygon(strip_a, n, 1, double(row + 1), 1.0, strip);      // y <= row + 1
    if (n < 3) continue;
    double sx0 = strip[0], sx1 = strip[0];
    for (int i = 1; i < n; ++i) {
      sx0 = std::min(sx0, strip[2 * i]);
      sx1 = std::max(sx1, strip[2 * i]);
    }
    const int64_t c0 = std::max<int64_t>(col0, static_cast<int64_t>(std::floor(sx0)));
    const int64_t c1 = std::min<int64_t>(col1, static_cast<int64_t>(std::floor(sx1)));
    for (int64_t col = c0; col <= c1; ++col) {
      int m = clip_polygon(strip, n, 0, double(col), -1.0, cell_a);  // x >= col
      m = clip_polygon(cell_a, m, 0, double(col + 1), 1.0, cell);    // x <= col + 1
      if (m < 3) continue;
      const double a = polygon_area(cell, m);
      if (a > 0.0) {
        // Vertex average: inside the convex piece, good enough to locate it in the world.
        double cx = 0.0, cy = 0.0;
        for (int i = 0; i < m; ++i) {
          cx += cell[2 * i];
          cy += cell[2 * i + 1];
        }
        add(static_cast<uint32_t>(row * int64_t(width) + col), a, cx / m, cy / m);
      }
    }
  }
}

}  // namespace plm

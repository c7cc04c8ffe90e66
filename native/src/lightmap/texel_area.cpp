#include "lightmap/texel_area.h"

#include <algorithm>
#include <utility>

namespace plm {

double polygon_area(const double* xy, int n) {
  // Relative to the first vertex: tiny polygons far from (0, 0) keep their digits.
  double twice = 0.0;
  for (int i = 1; i + 1 < n; ++i) {
    const double ax = xy[2 * i] - xy[0], ay = xy[2 * i + 1] - xy[1];
    const double bx = xy[2 * i + 2] - xy[0], by = xy[2 * i + 3] - xy[1];
    twice += ax * by - bx * ay;
  }
  return 0.5 * std::fabs(twice);
}

TexelAreas compute_texel_areas(const Mesh& mesh) {
  TexelAreas out;
  const uint32_t w = mesh.lightmap_width, h = mesh.lightmap_height;
  out.area.assign(size_t(w) * h, 0.0);
  out.coverage.assign(size_t(w) * h, 0.0f);
  std::vector<double> cover(size_t(w) * h, 0.0);
  std::vector<double> where(3 * size_t(w) * h, 0.0), facing(3 * size_t(w) * h, 0.0);
  std::vector<std::pair<uint32_t, uint32_t>> touches;  // (texel, triangle)
  for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
    const Vec3 p0 = mesh.vertex(t, 0), p1 = mesh.vertex(t, 1), p2 = mesh.vertex(t, 2);
    if (degenerate_triangle(p0, p1, p2)) continue;  // never shaded: counted as degenerate
    // World area in double: sliver triangles lose everything in float.
    const double e1[3] = {double(p1.x) - p0.x, double(p1.y) - p0.y, double(p1.z) - p0.z};
    const double e2[3] = {double(p2.x) - p0.x, double(p2.y) - p0.y, double(p2.z) - p0.z};
    const double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2],
                 cz = e1[0] * e2[1] - e1[1] * e2[0];
    const double world_area = 0.5 * std::sqrt(cx * cx + cy * cy + cz * cz);
    if (!(world_area > 0.0)) continue;  // degenerate: never hit, counted elsewhere
    double tri[6];
    bool outside = false;
    for (int k = 0; k < 3; ++k) {
      const double u = mesh.uv[6 * t + 2 * k], v = mesh.uv[6 * t + 2 * k + 1];
      outside |= u < 0.0 || u > 1.0 || v < 0.0 || v > 1.0;
      tri[2 * k] = u * w;
      tri[2 * k + 1] = v * h;
    }
    if (outside && out.outside_triangles++ == 0) out.first_outside_triangle = t;
    const double uv_area = polygon_area(tri, 3);
    if (!(uv_area > 0.0)) {
      if (out.zero_uv_triangles++ == 0) out.first_zero_uv_triangle = t;
      continue;
    }
    const double scale = world_area / uv_area;
    const double n[3] = {cx / (2 * world_area), cy / (2 * world_area), cz / (2 * world_area)};
    // Barycentric coordinates of a UV point, to place each piece in the world.
    const double d = (tri[2] - tri[0]) * (tri[5] - tri[1]) - (tri[4] - tri[0]) * (tri[3] - tri[1]);
    clip_triangle_to_grid(tri, w, h, [&](uint32_t texel, double a, double x, double y) {
      const double wa = a * scale;
      touches.emplace_back(texel, t);
      out.area[texel] += wa;
      cover[texel] += a;
      const double b1 = ((x - tri[0]) * (tri[5] - tri[1]) - (tri[4] - tri[0]) * (y - tri[1])) / d;
      const double b2 = ((tri[2] - tri[0]) * (y - tri[1]) - (x - tri[0]) * (tri[3] - tri[1])) / d;
      for (int c = 0; c < 3; ++c) {
        where[3 * size_t(texel) + c] += wa * (double(p0[c]) + b1 * e1[c] + b2 * e2[c]);
        facing[3 * size_t(texel) + c] += wa * n[c];
      }
    });
  }
  std::sort(touches.begin(), touches.end());
  out.tri_begin.assign(cover.size() + 1, 0);
  out.tri_ids.resize(touches.size());
  for (size_t k = 0; k < touches.size(); ++k) {
    ++out.tri_begin[touches[k].first + 1];
    out.tri_ids[k] = touches[k].second;
  }
  for (size_t i = 0; i < cover.size(); ++i) out.tri_begin[i + 1] += out.tri_begin[i];
  out.position.resize(cover.size());
  out.normal.resize(cover.size());
  for (size_t i = 0; i < cover.size(); ++i) {
    // Slivers below 0.1% of a texel come from UV rounding at island borders:
    // such texels are left to dilation instead of being estimated on a
    // sliver that may lie exactly on another face's edge.
    if (cover[i] < kMinCoverage) {
      cover[i] = 0.0;
      out.area[i] = 0.0;
    }
    out.coverage[i] = static_cast<float>(cover[i]);
    if (out.area[i] > 0.0) {
      const double* p = &where[3 * i];
      const double* f = &facing[3 * i];
      const double len = std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
      out.position[i] = Vec3(float(p[0] / out.area[i]), float(p[1] / out.area[i]), float(p[2] / out.area[i]));
      if (len > 0.0) out.normal[i] = Vec3(float(f[0] / len), float(f[1] / len), float(f[2] / len));
    }
    if (cover[i] > 1.0 + 1e-4 && out.overlapping_texels++ == 0) out.first_overlapping_texel = uint32_t(i);
  }
  return out;
}

}  // namespace plm

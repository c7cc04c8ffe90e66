#include "lightmap/texel_area.h"

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
  for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
    const Vec3 p0 = mesh.vertex(t, 0), p1 = mesh.vertex(t, 1), p2 = mesh.vertex(t, 2);
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
    clip_triangle_to_grid(tri, w, h, [&](uint32_t texel, double a) {
      out.area[texel] += a * scale;
      cover[texel] += a;
    });
  }
  for (size_t i = 0; i < cover.size(); ++i) {
    out.coverage[i] = static_cast<float>(cover[i]);
    if (cover[i] > 1.0 + 1e-4 && out.overlapping_texels++ == 0) out.first_overlapping_texel = uint32_t(i);
  }
  return out;
}

}  // namespace plm

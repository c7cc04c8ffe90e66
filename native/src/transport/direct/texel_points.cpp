#include "transport/direct/texel_points.h"

#include <algorithm>
#include <cmath>

namespace plm {
namespace {

// Barycentric coordinates (b1, b2 of corners 1 and 2) of texel coordinates
// (x, y) in triangle t's lightmap UVs; false if the triangle has no UV area.
bool uv_barycentric(const Mesh& mesh, uint32_t t, double x, double y, double& b1, double& b2) {
  const float* uv = &mesh.uv[6 * size_t(t)];
  const double w = mesh.lightmap_width, h = mesh.lightmap_height;
  const double ax = uv[0] * w, ay = uv[1] * h;
  const double e1x = uv[2] * w - ax, e1y = uv[3] * h - ay, e2x = uv[4] * w - ax, e2y = uv[5] * h - ay;
  const double det = e1x * e2y - e2x * e1y;
  if (det == 0.0) return false;
  b1 = ((x - ax) * e2y - e2x * (y - ay)) / det;
  b2 = (e1x * (y - ay) - (x - ax) * e1y) / det;
  return true;
}

}  // namespace

// The shading normal at point p of triangle tri of a smooth mesh, from p's
// barycentric coordinates.
Vec3 shading_normal_at(const Mesh& mesh, uint32_t tri, Vec3 p, Vec3 geometric) {
  const Vec3 p0 = mesh.vertex(tri, 0), e1 = mesh.vertex(tri, 1) - p0, e2 = mesh.vertex(tri, 2) - p0, d = p - p0;
  const float d11 = dot(e1, e1), d12 = dot(e1, e2), d22 = dot(e2, e2), d1 = dot(d, e1), d2 = dot(d, e2);
  const float det = d11 * d22 - d12 * d12;
  if (!(det > 0.0f)) return geometric;
  const float b1 = (d22 * d1 - d12 * d2) / det, b2 = (d11 * d2 - d12 * d1) / det;
  return mesh.shading_normal(tri, std::clamp(b1, 0.0f, 1.0f), std::clamp(b2, 0.0f, 1.0f), geometric);
}

TexelPoints::TexelPoints(const std::vector<MeshView>& views, const std::vector<TexelAreas>& areas,
                         const BakeSettings& settings)
    : views_(views), areas_(areas), cycles_window_(settings.cycles_window) {}
// The surface point at texel coordinates (x, y) (texel units), if a triangle covers it.
bool TexelPoints::surface_point(uint32_t mesh_id, uint32_t texel, float x, float y, Vec3& p, Vec3& n,
                               uint32_t& tri) const {
  const Mesh& mesh = *views_[mesh_id].mesh;
  const TexelAreas& ta = areas_[mesh_id];
  for (uint32_t k = ta.tri_begin[texel]; k < ta.tri_begin[texel + 1]; ++k) {
    const uint32_t t = ta.tri_ids[k];
    double b1, b2;
    const double eps = -1e-6;
    if (!uv_barycentric(mesh, t, x, y, b1, b2) || b1 < eps || b2 < eps || b1 + b2 > 1.0 - eps) continue;
    const Vec3 p0 = mesh.vertex(t, 0), p1 = mesh.vertex(t, 1), p2 = mesh.vertex(t, 2);
    p = p0 + (p1 - p0) * float(b1) + (p2 - p0) * float(b2);
    n = views_[mesh_id].normals[t];
    tri = t;
    return true;
  }
  return false;
}

// A point uniform over the part of texel (tx, ty) that the mesh covers:
// clip each touching triangle to the texel square, pick a piece by area, then
// a fan triangle of it by area, then a uniform point. For barely covered
// texels, where stratified points in the square would almost all miss.
bool TexelPoints::point_in_pieces(uint32_t mesh_id, uint32_t texel, const float u[3], Vec3& p, Vec3& n,
                                 uint32_t& tri) const {
  const Mesh& mesh = *views_[mesh_id].mesh;
  const TexelAreas& ta = areas_[mesh_id];
  const double w = mesh.lightmap_width, h = mesh.lightmap_height;
  const double tx = texel % mesh.lightmap_width, ty = texel / mesh.lightmap_width;
  double pieces[16][2 * detail::kMaxPolygon];
  int sizes[16];
  double piece_area[16];
  uint32_t piece_tri[16];
  int count = 0;
  double total = 0.0;
  for (uint32_t k = ta.tri_begin[texel]; k < ta.tri_begin[texel + 1] && count < 16; ++k) {
    const uint32_t t = ta.tri_ids[k];
    const float* uv = &mesh.uv[6 * size_t(t)];
    const double corners[6] = {uv[0] * w, uv[1] * h, uv[2] * w, uv[3] * h, uv[4] * w, uv[5] * h};
    double a[2 * detail::kMaxPolygon], b[2 * detail::kMaxPolygon];
    int m = detail::clip_polygon(corners, 3, 0, tx, -1.0, a);
    m = detail::clip_polygon(a, m, 0, tx + 1.0, 1.0, b);
    m = detail::clip_polygon(b, m, 1, ty, -1.0, a);
    m = detail::clip_polygon(a, m, 1, ty + 1.0, 1.0, pieces[count]);
    if (m < 3) continue;
    const double area = polygon_area(pieces[count], m);
    if (!(area > 0.0)) continue;
    sizes[count] = m;
    piece_area[count] = area;
    piece_tri[count] = t;
    total += area;
    ++count;
  }
  if (count == 0) return false;
  double pick = u[0] * total;
  int c = 0;
  while (c + 1 < count && pick > piece_area[c]) pick -= piece_area[c++];
  const double* poly = pieces[c];
  // Fan triangle (0, i, i + 1) chosen by area, reusing the remainder of the pick.
  double fan_pick = pick;
  int i = 1;
  double fan[6];
  for (;; ++i) {
    fan[0] = poly[0], fan[1] = poly[1], fan[2] = poly[2 * i], fan[3] = poly[2 * i + 1];
    fan[4] = poly[2 * i + 2], fan[5] = poly[2 * i + 3];
    const double a = polygon_area(fan, 3);
    if (i + 2 >= sizes[c] || fan_pick <= a) break;
    fan_pick -= a;
  }
  double s = u[1], t = u[2];
  if (s + t > 1.0) {
    s = 1.0 - s;
    t = 1.0 - t;
  }
  const float x = float(fan[0] + s * (fan[2] - fan[0]) + t * (fan[4] - fan[0]));
  const float y = float(fan[1] + s * (fan[3] - fan[1]) + t * (fan[5] - fan[1]));
  // Barycentric coordinates in the chosen triangle, clamped against rounding.
  const uint32_t tt = piece_tri[c];
  const float* uv = &mesh.uv[6 * size_t(tt)];
  const float ax = uv[0] * float(w), ay = uv[1] * float(h);
  const float e1x = uv[2] * float(w) - ax, e1y = uv[3] * float(h) - ay;
  const float e2x = uv[4] * float(w) - ax, e2y = uv[5] * float(h) - ay;
  const float det = e1x * e2y - e2x * e1y;
  float b1 = ((x - ax) * e2y - e2x * (y - ay)) / det, b2 = (e1x * (y - ay) - (x - ax) * e1y) / det;
  b1 = std::clamp(b1, 0.0f, 1.0f);
  b2 = std::clamp(b2, 0.0f, 1.0f - b1);
  const Vec3 p0 = mesh.vertex(tt, 0), p1 = mesh.vertex(tt, 1), p2 = mesh.vertex(tt, 2);
  p = p0 + (p1 - p0) * b1 + (p2 - p0) * b2;
  n = views_[mesh_id].normals[tt];
  tri = tt;
  return true;
}

// The triangle Blender's bake rasterizer gives a texel: the last one (in
// triangle order) that covers its centre, edges included; -1 for none.
int64_t TexelPoints::centre_owner(uint32_t mesh_id, uint32_t texel) const {
  const Mesh& mesh = *views_[mesh_id].mesh;
  const TexelAreas& ta = areas_[mesh_id];
  const double x = double(texel % mesh.lightmap_width) + 0.5, y = double(texel / mesh.lightmap_width) + 0.5;
  int64_t owner = -1;
  for (uint32_t k = ta.tri_begin[texel]; k < ta.tri_begin[texel + 1]; ++k) {
    const uint32_t t = ta.tri_ids[k];
    double b1, b2;
    const double eps = 1e-9;
    if (uv_barycentric(mesh, t, x, y, b1, b2) && b1 >= -eps && b2 >= -eps && b1 + b2 <= 1.0 + eps) owner = t;
  }
  return owner;
}

// The point Cycles 3.4 bakes for texel coordinates (x, y) of a texel owned by
// triangle tri: the barycentric coordinates (u of corner 0, v of corner 1) of
// (x, y), folded back into the triangle by mirror repeat, u into [0, 1] and
// then v into [0, 1 - u] (Cycles' bake_clamp_mirror_repeat). Inside the
// triangle this is the point itself; a window that crosses an edge samples
// the owner's side twice instead of the neighbour's.
Vec3 TexelPoints::mirrored_point(uint32_t mesh_id, uint32_t tri, float x, float y) const {
  const Mesh& mesh = *views_[mesh_id].mesh;
  double b1 = 0.0, b2 = 0.0;
  uv_barycentric(mesh, tri, x, y, b1, b2);  // the owner has UV area: it covers the centre
  auto mirror = [](double t, double range) {
    if (!(range > 0.0)) return 0.0;
    const double q = t / range, f = std::floor(q), r = q - f;
    return (int64_t(f) & 1 ? 1.0 - r : r) * range;
  };
  const double u = mirror(1.0 - b1 - b2, 1.0);
  const double v = mirror(b1, 1.0 - u);
  const Vec3 p0 = mesh.vertex(tri, 0), p1 = mesh.vertex(tri, 1), p2 = mesh.vertex(tri, 2);
  return p0 * float(u) + p1 * float(v) + p2 * float(1.0 - u - v);
}

bool TexelPoints::window_map(uint32_t mesh_id, uint32_t tri, float ox, float oy, float size, Vec3& base, Vec3& du,
                            Vec3& dv) const {
  const Mesh& mesh = *views_[mesh_id].mesh;
  double a1, a2, x1, x2, y1, y2;  // barycentrics at (ox, oy), (ox + 1, oy), (ox, oy + 1)
  if (!uv_barycentric(mesh, tri, ox, oy, a1, a2) || !uv_barycentric(mesh, tri, double(ox) + 1.0, oy, x1, x2) ||
      !uv_barycentric(mesh, tri, ox, double(oy) + 1.0, y1, y2))
    return false;
  const double d1x = x1 - a1, d2x = x2 - a2, d1y = y1 - a1, d2y = y2 - a2;
  for (int c = 0; c < 4; ++c) {
    const double cx = c & 1 ? size : 0.0, cy = c & 2 ? size : 0.0;
    const double b1 = a1 + d1x * cx + d1y * cy, b2 = a2 + d2x * cx + d2y * cy;
    if (!(b1 >= 0.0 && b2 >= 0.0 && b1 + b2 <= 1.0)) return false;
  }
  const Vec3 p0 = mesh.vertex(tri, 0), p1 = mesh.vertex(tri, 1), p2 = mesh.vertex(tri, 2);
  const Vec3d q0 = to_double(p0), e1 = to_double(p1) - q0, e2 = to_double(p2) - q0;
  base = to_float(q0 + e1 * a1 + e2 * a2);
  du = to_float(e1 * d1x + e2 * d2x);
  dv = to_float(e1 * d1y + e2 * d2y);
  return true;
}

TexelPoints::TexelWindow TexelPoints::texel_window(uint32_t mesh_id, uint32_t texel, uint32_t m) const {
  const uint32_t width = views_[mesh_id].mesh->lightmap_width;
  const float x0 = float(texel % width), y0 = float(texel / width);
  TexelWindow tw;
  tw.owner = cycles_window_ && areas_[mesh_id].coverage[texel] >= 0.5f ? centre_owner(mesh_id, texel) : -1;
  const bool window = tw.owner >= 0;
  tw.origin_x = window ? x0 + 0.25f : x0, tw.origin_y = window ? y0 + 0.25f : y0;
  tw.side = window ? 0.5f / float(m) : 1.0f / float(m);
  tw.sparse = !window && areas_[mesh_id].coverage[texel] < 0.5f;
  tw.affine = window && window_map(mesh_id, uint32_t(tw.owner), tw.origin_x, tw.origin_y, 0.5f, tw.base, tw.du, tw.dv);
  return tw;
}

}  // namespace plm

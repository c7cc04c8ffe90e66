// Geometry shared by the L-system graph and placed L-system objects:
// axis-aligned boxes of turtle primitives (double, padded; float,
// rounded outward) and the CSG shape of a turtle shape.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>

#include "csg/primitive.h"
#include "lsystem/language/turtle.h"
#include "util/math.h"

namespace plm::lsystem {

constexpr double kInf = std::numeric_limits<double>::infinity();

inline csg::Shape csg_shape(ShapeKind k) {
  switch (k) {
    case ShapeKind::Cylinder: return csg::Shape::Cylinder;
    case ShapeKind::Sphere: return csg::Shape::Sphere;
    case ShapeKind::Cone: return csg::Shape::Cone;
    case ShapeKind::Box: return csg::Shape::Box;
  }
  return csg::Shape::Box;
}

inline bool box_empty(Vec3d lo, Vec3d hi) { return !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z); }

inline void grow(Vec3d& lo, Vec3d& hi, Vec3d a, Vec3d b) {
  lo = min(lo, a);
  hi = max(hi, b);
}

// Pads a non-empty box by 1e-9 relative.
inline void pad_box(Vec3d& lo, Vec3d& hi) {
  if (box_empty(lo, hi)) return;
  const double pad = 1e-9 * (max_abs_component(lo) + max_abs_component(hi)) + 1e-300;
  lo = lo - Vec3d{pad, pad, pad};
  hi = hi + Vec3d{pad, pad, pad};
}

// The box (lo, hi) mapped by t (its 8 corners), padded by 1e-9 relative.
inline void transform_box(const Affine3d& t, Vec3d lo, Vec3d hi, Vec3d* out_lo,
                          Vec3d* out_hi) {
  Vec3d a{kInf, kInf, kInf}, b{-kInf, -kInf, -kInf};
  if (box_empty(lo, hi)) {
    *out_lo = a;
    *out_hi = b;
    return;
  }
  for (int k = 0; k < 8; ++k) {
    const Vec3d c{(k & 1) ? hi.x : lo.x, (k & 2) ? hi.y : lo.y, (k & 4) ? hi.z : lo.z};
    const Vec3d w = t.point(c);
    a = min(a, w);
    b = max(b, w);
  }
  const double pad = 1e-9 * (max_abs_component(a) + max_abs_component(b)) + 1e-300;
  *out_lo = a - Vec3d{pad, pad, pad};
  *out_hi = b + Vec3d{pad, pad, pad};
}

// The exact box of a turtle primitive whose local->frame map is m
// (primitive_extent: a cone by its cylinder hull, as the turtle bounds it). Not padded.
inline void prim_box(ShapeKind shape, const Affine3d& m, Vec3d* lo, Vec3d* hi) {
  for (int r = 0; r < 3; ++r) {
    const double e = primitive_extent(shape, m.m, r);
    (*lo)[r] = m.m[4 * r + 3] - e;
    (*hi)[r] = m.m[4 * r + 3] + e;
  }
}

// The ray segment [t0, t1] of o + t d meets the closed box (double, exact slabs).
inline bool box_hit(Vec3d lo, Vec3d hi, Vec3d o, Vec3d d, double t0, double t1) {
  for (int a = 0; a < 3; ++a) {
    if (!(lo[a] <= hi[a])) return false;
    if (d[a] == 0) {
      if (o[a] < lo[a] || o[a] > hi[a]) return false;
      continue;
    }
    const double inv = 1.0 / d[a];
    double ta = (lo[a] - o[a]) * inv, tb = (hi[a] - o[a]) * inv;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  return true;
}

// v as a float rounded toward -inf / +inf (out of range: -inf / FLT_MAX, -FLT_MAX / +inf).
inline float float_down(double v) {
  float f = float(v);
  if (double(f) > v) {  // f is not -inf; f == -0 only for v < 0
    uint32_t b;
    std::memcpy(&b, &f, sizeof b);
    b = f > 0 ? b - 1 : b + 1;
    std::memcpy(&f, &b, sizeof b);
  }
  return f;
}
inline float float_up(double v) {
  float f = float(v);
  if (double(f) < v) {  // f is not +inf and not -0
    uint32_t b;
    std::memcpy(&b, &f, sizeof b);
    b = f >= 0 ? b + 1 : b - 1;
    std::memcpy(&f, &b, sizeof b);
  }
  return f;
}

}  // namespace plm::lsystem

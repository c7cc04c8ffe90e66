// Double-precision vectors and 3x4 affine maps for the CSG module. CSG rays are
// solved in double so that coplanar faces, grazing rays and objects far from
// the origin keep a defined answer; the float Vec3 of util/math.h is for meshes.
#pragma once

#include <cmath>

namespace plm::csg {

struct DVec3 {
  double x = 0, y = 0, z = 0;
  DVec3() = default;
  constexpr DVec3(double x_, double y_, double z_) : x(x_), y(y_), z(z_) {}
  double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  double& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
};

inline DVec3 operator+(DVec3 a, DVec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline DVec3 operator-(DVec3 a, DVec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline DVec3 operator-(DVec3 a) { return {-a.x, -a.y, -a.z}; }
inline DVec3 operator*(DVec3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
inline DVec3 operator*(double s, DVec3 a) { return a * s; }
inline DVec3 operator/(DVec3 a, double s) { return a * (1.0 / s); }
inline double dot(DVec3 a, DVec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline DVec3 cross(DVec3 a, DVec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double length(DVec3 a) { return std::sqrt(dot(a, a)); }
inline DVec3 normalize(DVec3 a) { return a / length(a); }
inline double max_abs(DVec3 a) { return std::fmax(std::fabs(a.x), std::fmax(std::fabs(a.y), std::fabs(a.z))); }
inline bool is_finite(DVec3 a) { return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z); }
inline DVec3 min(DVec3 a, DVec3 b) { return {std::fmin(a.x, b.x), std::fmin(a.y, b.y), std::fmin(a.z, b.z)}; }
inline DVec3 max(DVec3 a, DVec3 b) { return {std::fmax(a.x, b.x), std::fmax(a.y, b.y), std::fmax(a.z, b.z)}; }

// Row-major 3x4 affine map: rows are (m[4r], m[4r+1], m[4r+2] | m[4r+3]),
// the top three rows of Blender's matrix_world.
struct Affine {
  double m[12];
  DVec3 point(DVec3 p) const { return vector(p) + DVec3{m[3], m[7], m[11]}; }
  DVec3 vector(DVec3 v) const {
    return {m[0] * v.x + m[1] * v.y + m[2] * v.z, m[4] * v.x + m[5] * v.y + m[6] * v.z,
            m[8] * v.x + m[9] * v.y + m[10] * v.z};
  }
  // The transposed linear part times v: maps local normals of the inverse map
  // to world normals (the inverse-transpose rule).
  DVec3 transpose_vector(DVec3 v) const {
    return {m[0] * v.x + m[4] * v.y + m[8] * v.z, m[1] * v.x + m[5] * v.y + m[9] * v.z,
            m[2] * v.x + m[6] * v.y + m[10] * v.z};
  }
  DVec3 column(int c) const { return {m[c], m[4 + c], m[8 + c]}; }
  double det() const { return dot(column(0), cross(column(1), column(2))); }
};

// The inverse of a (non-singular) affine map, by the adjugate.
inline Affine inverse(const Affine& a) {
  const DVec3 c0 = a.column(0), c1 = a.column(1), c2 = a.column(2);
  const DVec3 r0 = cross(c1, c2), r1 = cross(c2, c0), r2 = cross(c0, c1);  // rows of the adjugate
  const double inv_det = 1.0 / dot(c0, r0);
  Affine b;
  const DVec3 rows[3] = {r0 * inv_det, r1 * inv_det, r2 * inv_det};
  const DVec3 t = a.column(3);
  for (int r = 0; r < 3; ++r) {
    b.m[4 * r] = rows[r].x;
    b.m[4 * r + 1] = rows[r].y;
    b.m[4 * r + 2] = rows[r].z;
    b.m[4 * r + 3] = -dot(rows[r], t);
  }
  return b;
}

// Shirley-Chiu concentric map of [0,1]^2 onto the unit disk: equal-area (pi
// per unit square), so uniform points map to uniform points and strata stay
// compact. Face charts (csg_lightmap) and face sampling (primitive) share it.
inline void square_to_disk(double s, double t, double& x, double& y) {
  constexpr double kPi = 3.14159265358979323846;
  const double a = 2 * s - 1, b = 2 * t - 1;
  if (a == 0 && b == 0) {
    x = y = 0;
    return;
  }
  double r, phi;
  if (std::fabs(a) > std::fabs(b)) {
    r = a;
    phi = (kPi / 4) * (b / a);
  } else {
    r = b;
    phi = kPi / 2 - (kPi / 4) * (a / b);
  }
  x = r * std::cos(phi);
  y = r * std::sin(phi);
}

}  // namespace plm::csg

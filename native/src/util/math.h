// Small vector math for the engine: one 3-vector and one 3x4 affine map, in
// float for meshes and radiance, in double for CSG and L-system rays and for
// sums over millions of terms (orientation-lightmap set-up).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

namespace plm {

constexpr float kPi = 3.14159265358979323846f;
constexpr double kPiD = 3.14159265358979323846;
template <typename T>
inline constexpr T kPiT = T(kPiD);
static_assert(kPiT<float> == kPi, "pi rounds to the same float either way");

// Coordinates beyond this (m) are rejected: photons start up to a few scene
// radii out, and Embree accepts ray origins only up to ~1.8e18.
constexpr float kMaxCoordinate = 1e12f;

// A scalar parameter that takes no part in deduction: v * 2 or v / n convert
// the number to v's precision, as a plain float or double overload would.
template <typename T>
struct ScalarOf {
  using type = T;
};
template <typename T>
using Scalar = typename ScalarOf<T>::type;

template <typename T>
struct Vec3T {
  T x = 0, y = 0, z = 0;
  Vec3T() = default;
  constexpr Vec3T(T x_, T y_, T z_) : x(x_), y(y_), z(z_) {}
  T operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  T& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
};
using Vec3 = Vec3T<float>;
using Vec3d = Vec3T<double>;

// The only conversions between the two precisions (to float rounds each component).
inline Vec3d to_double(Vec3 v) { return {v.x, v.y, v.z}; }
inline Vec3 to_float(Vec3d v) { return {float(v.x), float(v.y), float(v.z)}; }

template <typename T>
inline Vec3T<T> operator+(Vec3T<T> a, Vec3T<T> b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
template <typename T>
inline Vec3T<T> operator-(Vec3T<T> a, Vec3T<T> b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
template <typename T>
inline Vec3T<T> operator-(Vec3T<T> a) { return {-a.x, -a.y, -a.z}; }
template <typename T>
inline Vec3T<T> operator*(Vec3T<T> a, Scalar<T> s) { return {a.x * s, a.y * s, a.z * s}; }
template <typename T>
inline Vec3T<T> operator*(Scalar<T> s, Vec3T<T> a) { return a * s; }
template <typename T>
inline Vec3T<T> operator*(Vec3T<T> a, Vec3T<T> b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
template <typename T>
inline Vec3T<T> operator/(Vec3T<T> a, Scalar<T> s) { return a * (T(1) / s); }
template <typename T>
inline Vec3T<T>& operator+=(Vec3T<T>& a, Vec3T<T> b) { return a = a + b; }
template <typename T>
inline Vec3T<T>& operator*=(Vec3T<T>& a, Vec3T<T> b) { return a = a * b; }
template <typename T>
inline Vec3T<T>& operator*=(Vec3T<T>& a, Scalar<T> s) { return a = a * s; }
template <typename T>
inline T dot(Vec3T<T> a, Vec3T<T> b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
template <typename T>
inline Vec3T<T> cross(Vec3T<T> a, Vec3T<T> b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
template <typename T>
inline T length(Vec3T<T> a) { return std::sqrt(dot(a, a)); }
template <typename T>
inline Vec3T<T> normalize(Vec3T<T> a) { return a / length(a); }
template <typename T>
inline T max_component(Vec3T<T> a) { return std::fmax(a.x, std::fmax(a.y, a.z)); }
template <typename T>
inline T max_abs_component(Vec3T<T> a) {
  return std::fmax(std::fabs(a.x), std::fmax(std::fabs(a.y), std::fabs(a.z)));
}
template <typename T>
inline T average(Vec3T<T> a) { return (a.x + a.y + a.z) * (T(1) / T(3)); }
template <typename T>
inline bool is_finite(Vec3T<T> a) { return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z); }
template <typename T>
inline Vec3T<T> min(Vec3T<T> a, Vec3T<T> b) { return {std::fmin(a.x, b.x), std::fmin(a.y, b.y), std::fmin(a.z, b.z)}; }
template <typename T>
inline Vec3T<T> max(Vec3T<T> a, Vec3T<T> b) { return {std::fmax(a.x, b.x), std::fmax(a.y, b.y), std::fmax(a.z, b.z)}; }

// Row-major 3x4 affine map: rows are (m[4r], m[4r+1], m[4r+2] | m[4r+3]),
// the top three rows of Blender's matrix_world. Not initialised by default
// (maps are built in loops that set every entry): identity() or from_array.
template <typename T>
struct Affine3T {
  T m[12];
  static constexpr Affine3T identity() { return {{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}}; }
  // The first 12 entries of a row-major 3x4 or 4x4 matrix, in this precision.
  template <typename U>
  static Affine3T from_array(const U* a) {
    Affine3T t;
    for (int i = 0; i < 12; ++i) t.m[i] = T(a[i]);
    return t;
  }
  Vec3T<T> point(Vec3T<T> p) const { return vector(p) + column(3); }
  Vec3T<T> vector(Vec3T<T> v) const {
    return {m[0] * v.x + m[1] * v.y + m[2] * v.z, m[4] * v.x + m[5] * v.y + m[6] * v.z,
            m[8] * v.x + m[9] * v.y + m[10] * v.z};
  }
  // The transposed linear part times v: maps local normals of the inverse map
  // to world normals (the inverse-transpose rule).
  Vec3T<T> transpose_vector(Vec3T<T> v) const {
    return {m[0] * v.x + m[4] * v.y + m[8] * v.z, m[1] * v.x + m[5] * v.y + m[9] * v.z,
            m[2] * v.x + m[6] * v.y + m[10] * v.z};
  }
  Vec3T<T> column(int c) const { return {m[c], m[4 + c], m[8 + c]}; }
  T det() const { return dot(column(0), cross(column(1), column(2))); }
};
using Affine3f = Affine3T<float>;
using Affine3d = Affine3T<double>;

// The inverse of a (non-singular) affine map, by the adjugate.
template <typename T>
inline Affine3T<T> inverse(const Affine3T<T>& a) {
  const Vec3T<T> c0 = a.column(0), c1 = a.column(1), c2 = a.column(2);
  const Vec3T<T> r0 = cross(c1, c2), r1 = cross(c2, c0), r2 = cross(c0, c1);  // rows of the adjugate
  const T inv_det = T(1) / dot(c0, r0);
  Affine3T<T> b;
  const Vec3T<T> rows[3] = {r0 * inv_det, r1 * inv_det, r2 * inv_det};
  const Vec3T<T> t = a.column(3);
  for (int r = 0; r < 3; ++r) {
    b.m[4 * r] = rows[r].x;
    b.m[4 * r + 1] = rows[r].y;
    b.m[4 * r + 2] = rows[r].z;
    b.m[4 * r + 3] = -dot(rows[r], t);
  }
  return b;
}

// a after b: (a b)(x) = a(b(x)).
template <typename T>
inline Affine3T<T> compose(const Affine3T<T>& a, const Affine3T<T>& b) {
  Affine3T<T> c;
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 4; ++k) {
      T v = a.m[4 * r] * b.m[k] + a.m[4 * r + 1] * b.m[4 + k] + a.m[4 * r + 2] * b.m[8 + k];
      if (k == 3) v += a.m[4 * r + 3];
      c.m[4 * r + k] = v;
    }
  }
  return c;
}

// An orthonormal frame around a unit normal n (Duff et al. 2017, branchless).
inline void make_frame(Vec3 n, Vec3& t, Vec3& b) {
  const float sign = std::copysign(1.0f, n.z);
  const float a = -1.0f / (sign + n.z);
  const float c = n.x * n.y * a;
  t = {1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x};
  b = {c, sign + n.y * n.y * a, -n.y};
}

// Per octant o of the turn (sincos_2pi): the fold f = m[0] + m[1] g of the
// octant's fraction g to quarter turns in [0, 1/2], and the signed swap
// s = sp m[2] + cp m[3], c = sp m[4] + cp m[5] (padded to 8 floats).
alignas(32) inline constexpr float kSinCosOctant[8][8] = {
    {0.0f, 0.5f, 1, 0, 0, 1, 0, 0},  {0.5f, -0.5f, 0, 1, 1, 0, 0, 0},   {0.0f, 0.5f, 0, 1, -1, 0, 0, 0},
    {0.5f, -0.5f, 1, 0, 0, -1, 0, 0}, {0.0f, 0.5f, -1, 0, 0, -1, 0, 0}, {0.5f, -0.5f, 0, -1, -1, 0, 0, 0},
    {0.0f, 0.5f, 0, -1, 1, 0, 0, 0}, {0.5f, -0.5f, -1, 0, 0, 1, 0, 0}};

// sin and cos of 2 pi u for u in [0, 1) without a libm call (a hot loop's
// sincosf): the octant comes exactly from u, then the minimax polynomials of
// Cephes' sinf / cosf on [0, pi/4] (error near float rounding). No branches
// (a random octant would mispredict half the time) and no trips through
// integer registers: the fold is exact arithmetic and the swaps and signs
// are products with 0 or +-1 from a table row (22 % faster than bit selects
// on the integer side). Agrees with std::sin / std::cos of 2 pi u to a few
// float ulps; exact at multiples of pi/2.
inline void sincos_2pi(float u, float& s, float& c) {
  const float y = 8.0f * u;                   // exact
  const uint32_t o = uint32_t(y);             // octant
  const float g = y - float(o);               // in [0, 1), exact
  const float* m = kSinCosOctant[o & 7u];
  const float f = m[0] + m[1] * g;            // g / 2 or (1 - g) / 2, both exact
  const float t = f * (0.5f * kPi);
  const float t2 = t * t;
  const float sp = t + t * t2 * (-1.6666654611e-1f + t2 * (8.3321608736e-3f + t2 * -1.9515295891e-4f));
  const float cp = 1.0f - 0.5f * t2 + t2 * t2 * (4.166664568298827e-2f + t2 * (-1.388731625493765e-3f + t2 * 2.443315711809948e-5f));
  s = sp * m[2] + cp * m[3];
  c = sp * m[4] + cp * m[5];
}

// Cosine-weighted direction about the +Z axis from two uniform numbers.
inline Vec3 cosine_hemisphere(float u1, float u2) {
  const float r = std::sqrt(u1);
  float s, c;
  sincos_2pi(u2, s, c);
  const float z2 = 1.0f - u1;
  return {r * c, r * s, std::sqrt(z2 > 0.0f ? z2 : 0.0f)};
}

inline Vec3 uniform_sphere(float u1, float u2) {
  const float z = 1.0f - 2.0f * u1;
  const float r = std::sqrt(std::fmax(0.0f, 1.0f - z * z));
  float s, c;
  sincos_2pi(u2, s, c);
  return {r * c, r * s, z};
}

// Shirley-Chiu concentric map of [0,1]^2 onto the unit disk: equal-area (pi
// per unit square), so uniform points map to uniform points and strata stay
// compact (disk lights; CSG face charts and face sampling).
template <typename T>
inline void concentric_disk(T u1, T u2, T& x, T& y) {
  const T a = T(2) * u1 - T(1), b = T(2) * u2 - T(1);
  if (a == T(0) && b == T(0)) {
    x = y = T(0);
    return;
  }
  T r, phi;
  if (std::fabs(a) > std::fabs(b)) {
    r = a;
    phi = (kPiT<T> / T(4)) * (b / a);
  } else {
    r = b;
    phi = (kPiT<T> / T(2)) - (kPiT<T> / T(4)) * (a / b);
  }
  x = r * std::cos(phi);
  y = r * std::sin(phi);
}

// A triangle whose float normal cannot be trusted: zero or tiny area against
// its edge lengths (angles below ~1e-10 rad), or non-finite. Such triangles
// are skipped everywhere (texel areas, emission, bounces) and counted.
inline bool degenerate_triangle(Vec3 p0, Vec3 p1, Vec3 p2) {
  const Vec3 e1 = p1 - p0, e2 = p2 - p0;
  const float c = length(cross(e1, e2));
  return !(c > 1e-10f * (dot(e1, e1) + dot(e2, e2))) || !std::isfinite(c);
}

}  // namespace plm

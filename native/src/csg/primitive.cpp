#include "csg/primitive.h"

#include <algorithm>
#include <limits>

#include "csg/quadrature.h"
#include "csg/roots.h"
#include "util/error.h"

namespace plm::csg {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr uint8_t kNoFace = 255;

// A piece [t0, t1] of the line with the face crossed at each end.
struct Range {
  double t0 = -kInf, t1 = kInf;
  uint8_t f0 = kNoFace, f1 = kNoFace;
  bool empty() const { return !(t1 > t0); }
  double length() const { return t1 - t0; }
};

// Keeps the part of a that also lies in b; the later entry and the earlier
// exit name the faces (on an exact tie the first range's face stays).
Range clip(Range a, const Range& b) {
  if (b.t0 > a.t0) a.t0 = b.t0, a.f0 = b.f0;
  if (b.t1 < a.t1) a.t1 = b.t1, a.f1 = b.f1;
  return a;
}

// Crossing lists are built through this: slivers dropped, seams closed.
struct Builder {
  Crossing* out;
  double eps;
  int n = 0;
  void add(const Range& r) {
    if (!(r.t1 > r.t0 + eps)) return;  // zero length: a tangent graze
    if (n > 0 && r.t0 <= out[n - 1].t + eps) {
      out[n - 1] = {r.t1, 0, r.f1, 0};  // touches the previous interval: one interval
      return;
    }
    out[n++] = {r.t0, 0, r.f0, 0};
    out[n++] = {r.t1, 0, r.f1, 0};
  }
};

// The line p + s d against the slab lo <= q[axis] <= hi; faces 2 axis (low) and 2 axis + 1 (high).
Range slab(double p, double d, double lo, double hi, uint8_t face_lo, uint8_t face_hi) {
  Range r;
  if (d == 0) {
    if (p < lo || p > hi) r.t0 = kInf, r.t1 = -kInf;
    return r;
  }
  const double a = (lo - p) / d, b = (hi - p) / d;
  if (d > 0) return {a, b, face_lo, face_hi};
  return {b, a, face_hi, face_lo};
}

Range box_range(Vec3d p, Vec3d d, Vec3d lo, Vec3d hi) {
  Range r;
  for (int a = 0; a < 3 && !r.empty(); ++a)
    r = clip(r, slab(p[a], d[a], lo[a], hi[a], uint8_t(2 * a), uint8_t(2 * a + 1)));
  return r;
}

void local_box(const Primitive& prim, Vec3d& lo, Vec3d& hi) {
  switch (prim.shape) {
    case Shape::Torus: {
      const double e = prim.major + prim.minor;
      lo = {-e, -e, -prim.minor};
      hi = {e, e, prim.minor};
      return;
    }
    case Shape::Paraboloid:
      lo = {-1, -1, 0};
      hi = {1, 1, 1};
      return;
    default:
      lo = {-1, -1, -1};
      hi = {1, 1, 1};
  }
}

// Where A s^2 + 2 B s + C <= 0: up to two ranges, faces `face` at finite ends.
// Roots by the cancellation-free pair q / A, C / q.
int quadratic_nonpositive(double A, double B, double C, uint8_t face, Range out[2]) {
  if (A == 0) {
    if (B == 0) {
      if (C > 0) return 0;
      out[0] = Range{};
      return 1;
    }
    const double s = -C / (2 * B);
    out[0] = B > 0 ? Range{-kInf, s, kNoFace, face} : Range{s, kInf, face, kNoFace};
    return 1;
  }
  const double disc = B * B - A * C;
  if (disc <= 0) {
    if (A > 0) return 0;  // positive everywhere except perhaps one point
    out[0] = Range{};      // A < 0: non-positive everywhere
    return 1;
  }
  const double q = -(B + std::copysign(std::sqrt(disc), B));
  double s1 = q / A, s2 = C / q;
  if (s1 > s2) std::swap(s1, s2);
  if (A > 0) {
    out[0] = {s1, s2, face, face};
    return 1;
  }
  out[0] = {-kInf, s1, kNoFace, face};
  out[1] = {s2, kInf, face, kNoFace};
  return 2;
}

// Each shape's intersection works on the line p + s d, where p is the point of
// the line in the middle of its span through the local bounding box: the
// coefficients are then O(1) however far the ray starts (no cancellation).
Range sphere_range(Vec3d p, Vec3d d) {
  const double a = dot(d, d), s0 = -dot(p, d) / a;
  const Vec3d closest = p + d * s0;
  const double h2 = 1.0 - dot(closest, closest);
  if (!(h2 > 0)) return {kInf, -kInf};
  const double h = std::sqrt(h2 / a);
  return {s0 - h, s0 + h, 0, 0};
}

Range cylinder_range(Vec3d p, Vec3d d) {
  Range r = slab(p.z, d.z, -1, 1, 1, 2);
  if (r.empty()) return r;
  const double a = d.x * d.x + d.y * d.y;
  if (a <= 1e-30 * dot(d, d)) {  // parallel to the axis
    if (p.x * p.x + p.y * p.y > 1) return {kInf, -kInf};
    return r;
  }
  const double s0 = -(p.x * d.x + p.y * d.y) / a;
  const double cx = p.x + s0 * d.x, cy = p.y + s0 * d.y;
  const double h2 = 1.0 - (cx * cx + cy * cy);
  if (!(h2 > 0)) return {kInf, -kInf};
  const double h = std::sqrt(h2 / a);
  return clip(Range{s0 - h, s0 + h, 0, 0}, r);
}

// Inside the double cone x^2+y^2 <= (1-z)^2/4 within z in [-1, 1]: the upper
// nappe lies above z = 1, so the slab leaves exactly Blender's cone. The cone
// is convex, so at most one piece is real; a second one can only be a
// rounding sliver at the apex, hence the longer piece wins.
Range cone_range(Vec3d p, Vec3d d) {
  const Range z = slab(p.z, d.z, -1, 1, 1, 0);  // the z = +1 end is the apex: side face
  if (z.empty()) return z;
  const double w = 1.0 - p.z;
  Range pieces[2];
  const int n = quadratic_nonpositive(d.x * d.x + d.y * d.y - 0.25 * d.z * d.z,
                                      p.x * d.x + p.y * d.y + 0.25 * w * d.z,
                                      p.x * p.x + p.y * p.y - 0.25 * w * w, 0, pieces);
  Range best{kInf, -kInf};
  for (int i = 0; i < n; ++i) {
    const Range c = clip(pieces[i], z);
    if (!c.empty() && (best.empty() || c.length() > best.length())) best = c;
  }
  return best;
}

// z >= x^2 + y^2 and z <= 1.
Range paraboloid_range(Vec3d p, Vec3d d) {
  Range pieces[2];
  const int n = quadratic_nonpositive(d.x * d.x + d.y * d.y, p.x * d.x + p.y * d.y - 0.5 * d.z,
                                      p.x * p.x + p.y * p.y - p.z, 0, pieces);
  if (n == 0) return {kInf, -kInf};
  return clip(pieces[0], slab(p.z, d.z, -kInf, 1, 0, 1));  // n == 1: A >= 0
}

// The torus (|q|^2 + R^2 - r^2)^2 - 4 R^2 (x^2 + y^2) <= 0 as a quartic in
// the arc length u from p. Its real roots inside the bounding-box span are
// isolated between the roots of its derivatives (see roots.h), which keeps
// the two close roots of a near-grazing ray; the sign of the quartic at the
// middle of each piece then decides inside/outside, so a double root (exact
// tangency) gives no interval and odd root counts cannot flip the parity.
int torus_ranges(Vec3d p, Vec3d d, double R, double r, double s_lo, double s_hi, Range out[2]) {
  const double len = length(d);
  const Vec3d e = d / len;
  const double b = dot(p, e), k = dot(p, p) + R * R - r * r, R2 = R * R;
  const double c[5] = {k * k - 4 * R2 * (p.x * p.x + p.y * p.y),
                       4 * b * k - 8 * R2 * (p.x * e.x + p.y * e.y),
                       4 * b * b + 2 * k - 4 * R2 * (e.x * e.x + e.y * e.y), 4 * b, 1.0};
  double x[6];
  x[0] = s_lo * len;
  const int nr = polynomial_roots(c, 4, s_lo * len, s_hi * len, x + 1);
  x[nr + 1] = s_hi * len;
  int n = 0;
  for (int i = 0; i <= nr; ++i) {
    if (!(x[i + 1] > x[i]) || horner(c, 4, 0.5 * (x[i] + x[i + 1])) >= 0) continue;
    if (n > 0 && out[n - 1].t1 == x[i] / len) {
      out[n - 1].t1 = x[i + 1] / len;  // a root without a sign change: continue the piece
    } else if (n < 2) {
      out[n++] = {x[i] / len, x[i + 1] / len, 0, 0};
    }
  }
  return n;
}

Range half_space_range(Vec3d p, Vec3d d) {
  if (d.z == 0) return p.z <= 0 ? Range{} : Range{kInf, -kInf};
  const double s = -p.z / d.z;
  return d.z > 0 ? Range{-kInf, s, kNoFace, 0} : Range{s, kInf, 0, kNoFace};
}

// p in local space as M^-1 (p - origin): the subtraction first is exact for
// points near a primitive far from the world origin, where M^-1 p + (-M^-1 t)
// would cancel two large numbers.
Vec3d local_point(const Primitive& prim, Vec3d p) { return prim.to_local.vector(p - prim.to_world.column(3)); }

Range shift(Range r, double t) { return {r.t0 + t, r.t1 + t, r.f0, r.f1}; }

// ---- local geometry: normals, distances, areas, sampling ----

Vec3d local_normal(const Primitive& prim, int face, Vec3d q) {
  switch (prim.shape) {
    case Shape::Sphere:
      return q;
    case Shape::Box: {
      Vec3d n{0, 0, 0};
      n[face / 2] = (face & 1) ? 1.0 : -1.0;
      return n;
    }
    case Shape::Cylinder:
      if (face == 0) return {q.x, q.y, 0};
      return {0, 0, face == 1 ? -1.0 : 1.0};
    case Shape::Cone: {
      if (face == 1) return {0, 0, -1};
      const Vec3d n{2 * q.x, 2 * q.y, 0.5 * (1 - q.z)};
      return dot(n, n) > 0 ? n : Vec3d{0, 0, 1};  // the apex
    }
    case Shape::Torus: {
      const double rho = std::sqrt(q.x * q.x + q.y * q.y);
      if (rho == 0) return {0, 0, q.z >= 0 ? 1.0 : -1.0};
      const double s = prim.major / rho;
      return {q.x - s * q.x, q.y - s * q.y, q.z};
    }
    case Shape::Paraboloid:
      if (face == 1) return {0, 0, 1};
      return {2 * q.x, 2 * q.y, -1};
    case Shape::HalfSpace:
      break;
  }
  return {0, 0, 1};
}

// Signed distance in local units, exact or a close under-estimate near the surface.
double local_distance(const Primitive& prim, Vec3d q) {
  const double rho = std::sqrt(q.x * q.x + q.y * q.y);
  switch (prim.shape) {
    case Shape::Sphere:
      return length(q) - 1.0;
    case Shape::Box:
      return max_abs_component(q) - 1.0;
    case Shape::Cylinder:
      return std::fmax(rho - 1.0, std::fabs(q.z) - 1.0);
    case Shape::Cone:
      return std::fmax((rho - 0.5 * (1.0 - q.z)) * (2.0 / std::sqrt(5.0)), -1.0 - q.z);
    case Shape::Torus:
      return std::hypot(rho - prim.major, q.z) - prim.minor;
    case Shape::Paraboloid:
      return std::fmax((rho * rho - q.z) / std::sqrt(1.0 + 4.0 * rho * rho), q.z - 1.0);
    case Shape::HalfSpace:
      break;
  }
  return q.z;
}

bool planar_face(Shape shape, int face) {
  switch (shape) {
    case Shape::Box:
    case Shape::HalfSpace:
      return true;
    case Shape::Cylinder:
    case Shape::Cone:
    case Shape::Paraboloid:
      return face > 0;
    default:
      return false;
  }
}

double local_area(const Primitive& prim, int face) {
  switch (prim.shape) {
    case Shape::Sphere:
      return 4 * kPiD;
    case Shape::Box:
      return 4;
    case Shape::Cylinder:
      return face == 0 ? 4 * kPiD : kPiD;
    case Shape::Cone:
      return face == 0 ? kPiD * std::sqrt(5.0) : kPiD;
    case Shape::Torus:
      return 4 * kPiD * kPiD * prim.major * prim.minor;
    case Shape::Paraboloid:
      return face == 0 ? kPiD / 6 * (5 * std::sqrt(5.0) - 1) : kPiD;
    case Shape::HalfSpace:
      break;
  }
  return kInf;
}

// World area per local area for a surface element with local unit normal n:
// |det M| |M^-T n| (Nanson's formula).
double area_ratio(const Primitive& prim, Vec3d n, double abs_det) {
  return abs_det * length(prim.to_local.transpose_vector(n));
}

// World area of a curved face for a general (non-similarity) map: Gauss-
// Legendre across, the periodic trapezoid rule around the axis (spectrally
// accurate for these smooth integrands).
double curved_face_area(const Primitive& prim, double abs_det) {
  constexpr int kAround = 256;
  const GaussLegendre& gl = gauss_legendre_64();
  auto ratio = [&](Vec3d n) { return area_ratio(prim, n, abs_det); };
  double sum = 0;
  for (int j = 0; j < kAround; ++j) {
    const double phi = 2 * kPiD * (j + 0.5) / kAround, c = std::cos(phi), s = std::sin(phi);
    switch (prim.shape) {
      case Shape::Sphere:
        for (int i = 0; i < gl.n; ++i) {  // theta in [0, pi]
          const double th = 0.5 * kPiD * (gl.x[i] + 1), st = std::sin(th);
          sum += 0.5 * kPiD * gl.w[i] * st * ratio({st * c, st * s, std::cos(th)});
        }
        break;
      case Shape::Cylinder:  // side: height 2
        sum += 2 * ratio({c, s, 0});
        break;
      case Shape::Cone:  // side: slant length sqrt(5), radius = slant / sqrt(5)
        sum += 0.5 * std::sqrt(5.0) * ratio(Vec3d{2 * c, 2 * s, 1} / std::sqrt(5.0));
        break;
      case Shape::Torus:
        for (int i = 0; i < kAround; ++i) {
          const double psi = 2 * kPiD * (i + 0.5) / kAround, cp = std::cos(psi);
          sum += (2 * kPiD / kAround) * prim.minor * (prim.major + prim.minor * cp) *
                 ratio({cp * c, cp * s, std::sin(psi)});
        }
        break;
      case Shape::Paraboloid:  // bowl, rho in [0, 1]
        for (int i = 0; i < gl.n; ++i) {
          const double rho = 0.5 * (gl.x[i] + 1), g = std::sqrt(1 + 4 * rho * rho);
          sum += 0.5 * gl.w[i] * rho * g * ratio(Vec3d{2 * rho * c, 2 * rho * s, -1} / g);
        }
        break;
      default:
        break;
    }
  }
  return sum * (2 * kPiD / kAround);
}

double face_world_area(const Primitive& prim, int face) {
  if (prim.shape == Shape::HalfSpace) return kInf;
  const double abs_det = std::fabs(prim.to_world.det());
  if (planar_face(prim.shape, face)) {
    const Vec3d n = local_normal(prim, face, {0, 0, 0});
    return local_area(prim, face) * area_ratio(prim, n, abs_det);
  }
  if (prim.similarity) return local_area(prim, face) * std::cbrt(abs_det * abs_det);
  if (prim.shape == Shape::Cylinder || prim.shape == Shape::Cone) {
    // A circular one stretched along its axis (what an L-system's turtle
    // draws): the side in closed form (integrating it was ~80 % of an
    // L-system object's set-up). Radius r, height h (the unit shapes' is 2).
    const Vec3d c0 = prim.to_world.column(0), c1 = prim.to_world.column(1), c2 = prim.to_world.column(2);
    const double l0 = length(c0), l1 = length(c1), l2 = length(c2), e = 1e-9 * std::fmax(l0, l1);
    if (std::fabs(l0 - l1) <= e && std::fabs(dot(c0, c1)) <= e * l0 && std::fabs(dot(c0, c2)) <= e * l2 &&
        std::fabs(dot(c1, c2)) <= e * l2) {
      const double r = 0.5 * (l0 + l1), h = 2 * l2;
      return prim.shape == Shape::Cylinder ? 2 * kPiD * r * h : kPiD * r * std::sqrt(r * r + h * h);
    }
  }
  return curved_face_area(prim, abs_det);
}

struct LocalSample {
  Vec3d q, n;        // local point and unit normal
  double u = 0, v = 0;
  double keep = 1;   // acceptance probability that makes the local density uniform in area
};

LocalSample disk_sample(double x1, double x2, double z, double nz) {
  LocalSample s;
  concentric_disk(x1, x2, s.q.x, s.q.y);  // uniform in the disk; strata stay compact
  s.q.z = z;
  s.n = {0, 0, nz};
  s.u = 0.5 * (s.q.x + 1);
  s.v = 0.5 * (s.q.y + 1);
  return s;
}

// Local samples uniform in local area (the torus by rejection, via keep).
LocalSample sample_local(const Primitive& prim, int face, double x1, double x2) {
  const double phi = 2 * kPiD * x1, c = std::cos(phi), s = std::sin(phi);
  LocalSample out;
  out.u = x1;
  switch (prim.shape) {
    case Shape::Sphere: {
      const double z = 1 - 2 * x2, rho = std::sqrt(std::fmax(0.0, 1 - z * z));
      out.q = out.n = {rho * c, rho * s, z};
      out.v = 0.5 * (z + 1);
      return out;
    }
    case Shape::Box:
      out.q = box_face_point(face, x1, x2);
      out.n = local_normal(prim, face, out.q);
      out.v = x2;
      return out;
    case Shape::Cylinder:
      if (face > 0) return disk_sample(x1, x2, face == 1 ? -1 : 1, face == 1 ? -1 : 1);
      out.q = {c, s, 2 * x2 - 1};
      out.n = {c, s, 0};
      out.v = x2;
      return out;
    case Shape::Cone: {
      if (face == 1) return disk_sample(x1, x2, -1, -1);
      const double rho = std::sqrt(x2);  // area grows linearly with the distance from the apex
      out.q = {rho * c, rho * s, 1 - 2 * rho};
      out.n = Vec3d{2 * c, 2 * s, 1} / std::sqrt(5.0);
      out.v = 0.5 * (out.q.z + 1);
      return out;
    }
    case Shape::Torus: {
      const double psi = 2 * kPiD * x2, cp = std::cos(psi), sp = std::sin(psi);
      const double R = prim.major, r = prim.minor;
      out.q = {(R + r * cp) * c, (R + r * cp) * s, r * sp};
      out.n = {cp * c, cp * s, sp};
      out.v = x2;
      out.keep = (R + r * cp) / (R + r);  // the area element r (R + r cos psi)
      return out;
    }
    case Shape::Paraboloid: {
      if (face == 1) return disk_sample(x1, x2, 1, 1);
      // Inverse of the area CDF ((1 + 4 rho^2)^1.5 - 1) / (5^1.5 - 1).
      const double g = std::cbrt(std::pow(1 + x2 * (5 * std::sqrt(5.0) - 1), 2.0));
      const double rho = std::sqrt(std::fmax(0.0, (g - 1) / 4));
      out.q = {rho * c, rho * s, rho * rho};
      out.n = normalize(Vec3d{2 * rho * c, 2 * rho * s, -1});
      out.v = rho * rho;
      return out;
    }
    case Shape::HalfSpace:
      break;
  }
  return out;
}

}  // namespace

int face_count(Shape shape) {
  switch (shape) {
    case Shape::Box:
      return 6;
    case Shape::Cylinder:
      return 3;
    case Shape::Cone:
    case Shape::Paraboloid:
      return 2;
    default:
      return 1;
  }
}

const char* shape_name(Shape shape) {
  static const char* const names[] = {"sphere", "box", "cylinder", "cone", "torus", "paraboloid", "half-space"};
  return names[int(shape)];
}

std::string check_primitive(const PrimitiveDesc& desc) {
  if (int(desc.shape) > int(Shape::HalfSpace)) return "unknown shape " + std::to_string(int(desc.shape));
  for (double v : desc.to_world)
    if (!std::isfinite(v)) return std::string(shape_name(desc.shape)) + " transform has NaN or Inf entries";
  const Affine3d m = Affine3d::from_array(desc.to_world);
  const double scale = length(m.column(0)) * length(m.column(1)) * length(m.column(2));
  if (!(std::fabs(m.det()) > 1e-12 * scale))
    return std::string(shape_name(desc.shape)) + " transform is singular (zero scale or collapsed axes)";
  if (desc.shape == Shape::Torus) {
    const double R = desc.major_radius, r = desc.minor_radius;
    if (!(std::isfinite(R) && std::isfinite(r) && R > 0 && r > 0))
      return "torus radii must be positive and finite (major " + std::to_string(R) + ", minor " + std::to_string(r) + ")";
    if (!(r < R))
      return "torus minor radius " + std::to_string(r) + " must be smaller than the major radius " + std::to_string(R);
  }
  return "";
}

Primitive make_primitive(const PrimitiveDesc& desc) {
  const std::string problem = check_primitive(desc);
  if (!problem.empty()) fail(PLM_ERROR_INVALID_ARGUMENT, problem);
  Primitive p = make_primitive_without_areas(desc);
  for (int f = 0; f < face_count(p.shape); ++f) p.area[f] = face_world_area(p, f);
  for (int f = face_count(p.shape); f < kMaxFaces; ++f) p.area[f] = 0;
  return p;
}

Primitive make_primitive_without_areas(const PrimitiveDesc& desc) {
  Primitive p{};
  p.shape = desc.shape;
  p.major = desc.major_radius;
  p.minor = desc.minor_radius;
  p.to_world = Affine3d::from_array(desc.to_world);
  p.to_local = inverse(p.to_world);
  const Vec3d c0 = p.to_world.column(0), c1 = p.to_world.column(1), c2 = p.to_world.column(2);
  const double l0 = length(c0), l1 = length(c1), l2 = length(c2), lmax = std::fmax(l0, std::fmax(l1, l2));
  p.size = lmax * (p.shape == Shape::Torus ? p.major + p.minor : 1.0);
  double frob = 0;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) frob += p.to_local.m[4 * r + c] * p.to_local.m[4 * r + c];
  p.stretch = std::sqrt(frob);
  const double e = 1e-12 * lmax * lmax;
  p.similarity = std::fabs(l0 - l1) <= 1e-12 * lmax && std::fabs(l0 - l2) <= 1e-12 * lmax &&
                 std::fabs(dot(c0, c1)) <= e && std::fabs(dot(c1, c2)) <= e && std::fabs(dot(c0, c2)) <= e;
  p.area_weight_max = std::fabs(p.to_world.det()) * p.stretch;
  for (double& a : p.area) a = std::numeric_limits<double>::quiet_NaN();

  if (p.shape == Shape::HalfSpace) {
    // Unbounded, except along an axis the plane's normal is parallel to.
    p.lo = {-kInf, -kInf, -kInf};
    p.hi = {kInf, kInf, kInf};
    const Vec3d n = normal(p, 0, p.to_world.column(3)), o = p.to_world.column(3);
    for (int a = 0; a < 3; ++a) {
      if (std::fabs(std::fabs(n[a]) - 1.0) > 1e-15) continue;
      if (n[a] > 0) p.hi[a] = o[a];
      else p.lo[a] = o[a];
    }
    return p;
  }
  Vec3d lo, hi;
  local_box(p, lo, hi);
  p.lo = {kInf, kInf, kInf};
  p.hi = -p.lo;
  for (int i = 0; i < 8; ++i) {
    const Vec3d corner = p.to_world.point({(i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z});
    p.lo = min(p.lo, corner);
    p.hi = max(p.hi, corner);
  }
  return p;
}

double ray_tolerance(const Primitive& prim, Vec3d o, Vec3d d) {
  const double len = kRelativeTolerance * prim.size +
                     kRoundingTolerance * (max_abs_component(o) + max_abs_component(prim.to_world.column(3)) + prim.size);
  return len / length(d);
}

int intersect(const Primitive& prim, Vec3d o, Vec3d d, double eps_t, Crossing* out) {
  Builder b{out, eps_t};
  const Vec3d q = local_point(prim, o), dq = prim.to_local.vector(d);
  if (prim.shape == Shape::HalfSpace) {
    b.add(half_space_range(q, dq));
    return b.n;
  }
  Vec3d lo, hi;
  local_box(prim, lo, hi);
  if (prim.shape == Shape::Box) {
    b.add(box_range(q, dq, lo, hi));
    return b.n;
  }
  // Span through a slightly enlarged box, so surface points on the box are inside it.
  const Vec3d pad = (hi - lo) * 1e-9;
  const Range span = box_range(q, dq, lo - pad, hi + pad);
  if (span.empty()) return 0;
  const double tm = 0.5 * (span.t0 + span.t1);
  const Vec3d p = q + dq * tm;
  switch (prim.shape) {
    case Shape::Sphere:
      b.add(shift(sphere_range(p, dq), tm));
      break;
    case Shape::Cylinder:
      b.add(shift(cylinder_range(p, dq), tm));
      break;
    case Shape::Cone:
      b.add(shift(cone_range(p, dq), tm));
      break;
    case Shape::Paraboloid:
      b.add(shift(paraboloid_range(p, dq), tm));
      break;
    case Shape::Torus: {
      Range r[2];
      const int n = torus_ranges(p, dq, prim.major, prim.minor, span.t0 - tm, span.t1 - tm, r);
      for (int i = 0; i < n; ++i) b.add(shift(r[i], tm));
      break;
    }
    default:
      break;
  }
  return b.n;
}

Vec3d normal(const Primitive& prim, int face, Vec3d p) {
  const Vec3d n = local_normal(prim, face, local_point(prim, p));
  return normalize(prim.to_local.transpose_vector(n));
}

int face_at(const Primitive& prim, Vec3d p) {
  const Vec3d q = local_point(prim, p);
  const double rho = std::sqrt(q.x * q.x + q.y * q.y);
  switch (prim.shape) {
    case Shape::Box: {
      const Vec3d a{std::fabs(q.x), std::fabs(q.y), std::fabs(q.z)};
      const int axis = a.x >= a.y && a.x >= a.z ? 0 : (a.y >= a.z ? 1 : 2);
      return 2 * axis + (q[axis] > 0 ? 1 : 0);
    }
    case Shape::Cylinder:
      if (std::fabs(rho - 1) <= 1 - std::fabs(q.z)) return 0;
      return q.z < 0 ? 1 : 2;
    case Shape::Cone:
      return std::fabs(rho - 0.5 * (1 - q.z)) * (2 / std::sqrt(5.0)) <= std::fabs(q.z + 1) ? 0 : 1;
    case Shape::Paraboloid:
      return std::fabs(rho * rho - q.z) / std::sqrt(1 + 4 * rho * rho) <= std::fabs(q.z - 1) ? 0 : 1;
    default:
      return 0;
  }
}

Side classify(const Primitive& prim, Vec3d p) {
  const double band = (kRelativeTolerance * prim.size + kRoundingTolerance * max_abs_component(p)) * prim.stretch;
  const double dist = local_distance(prim, local_point(prim, p));
  if (dist < -band) return Side::Inside;
  if (dist > band) return Side::Outside;
  return Side::Boundary;
}

bool inside_strict(const Primitive& prim, Vec3d p) { return local_distance(prim, local_point(prim, p)) < 0; }

bool sample_face(const Primitive& prim, int face, Rng& rng, FaceSample& out) {
  if (prim.shape == Shape::HalfSpace || face < 0 || face >= face_count(prim.shape)) return false;
  const bool planar = planar_face(prim.shape, face);
  const double abs_det = std::fabs(prim.to_world.det());
  // Rejection against the exact world/local area ratio; planar faces and
  // similarity maps have a constant ratio and never reject on it.
  const bool uniform_ratio = planar || prim.similarity;
  LocalSample s;
  for (int tries = 0; tries < (1 << 20); ++tries) {
    s = sample_local(prim, face, next_double(rng), next_double(rng));
    double keep = s.keep;
    if (!uniform_ratio) keep *= area_ratio(prim, s.n, abs_det) / prim.area_weight_max;
    if (keep >= 1 || next_double(rng) < keep) break;
  }
  out.p = prim.to_world.point(s.q);
  out.n = normalize(prim.to_local.transpose_vector(s.n));
  out.u = s.u;
  out.v = s.v;
  out.pdf = 1.0 / prim.area[face];
  return true;
}

}  // namespace plm::csg

// CSG primitives against truth: closed-form ray hits, brute-force marching of
// an independent inside test, grazing rays, exact areas against fine
// tessellations, and area-uniform sampling against tessellated bin areas.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <vector>

#include "csg/primitive.h"
#include "util/error.h"

namespace {

using namespace plm::csg;
using plm::Vec3d;
constexpr double kPi = 3.14159265358979323846;

// For RecordProperty: measured errors in the XML report (--gtest_output=xml).
std::string sci(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", x);
  return buf;
}

// The test's own frame: world = T + R(axis, angle) * diag(scale) * local.
struct Frame {
  Vec3d scale{1, 1, 1}, axis{0, 0, 1}, t{0, 0, 0};
  double angle = 0;
  Vec3d rotate(Vec3d v, double sign) const {
    const Vec3d k = normalize(axis);
    const double c = std::cos(sign * angle), s = std::sin(sign * angle);
    return v * c + cross(k, v) * s + k * (dot(k, v) * (1 - c));
  }
  Vec3d to_world(Vec3d q) const { return t + rotate({q.x * scale.x, q.y * scale.y, q.z * scale.z}, 1); }
  Vec3d to_local(Vec3d p) const {
    const Vec3d v = rotate(p - t, -1);
    return {v.x / scale.x, v.y / scale.y, v.z / scale.z};
  }
};

PrimitiveDesc make_desc(Shape shape, const Frame& f, double R = 1, double r = 0.25) {
  PrimitiveDesc d;
  d.shape = shape;
  d.major_radius = R;
  d.minor_radius = r;
  for (int c = 0; c < 3; ++c) {
    Vec3d e{0, 0, 0};
    e[c] = 1;
    const Vec3d col = f.to_world(e) - f.t;
    for (int row = 0; row < 3; ++row) d.to_world[4 * row + c] = col[row];
  }
  for (int row = 0; row < 3; ++row) d.to_world[4 * row + 3] = f.t[row];
  return d;
}

// Independent inside tests in local coordinates (no tolerance).
bool inside_local(Shape s, Vec3d q, double R = 1, double r = 0.25) {
  const double rho2 = q.x * q.x + q.y * q.y;
  switch (s) {
    case Shape::Sphere:
      return dot(q, q) < 1;
    case Shape::Box:
      return std::fabs(q.x) < 1 && std::fabs(q.y) < 1 && std::fabs(q.z) < 1;
    case Shape::Cylinder:
      return rho2 < 1 && std::fabs(q.z) < 1;
    case Shape::Cone:
      return q.z > -1 && q.z < 1 && std::sqrt(rho2) < 0.5 * (1 - q.z);
    case Shape::Torus: {
      const double a = std::sqrt(rho2) - R;
      return a * a + q.z * q.z < r * r;
    }
    case Shape::Paraboloid:
      return q.z < 1 && q.z > rho2;
    case Shape::HalfSpace:
      return q.z < 0;
  }
  return false;
}

struct Ray {
  Vec3d o, d;
};

// A ray from a random point on a sphere of radius 3 around the frame origin
// towards a random point near the primitive.
Ray random_ray(plm::Rng& rng, const Frame& f, double spread) {
  auto u = [&] { return 2 * next_double(rng) - 1; };
  Vec3d a{u(), u(), u()}, b{u(), u(), u()};
  a = normalize(a) * 3.0;
  b = b * spread;
  return {f.to_world(a), f.to_world(b) - f.to_world(a)};
}

// Crossings of the line by marching the independent inside test over [t0, t1]
// and bisecting each change. Returns false if some run is shorter than
// `min_run` steps (a near-grazing ray the march cannot resolve).
bool march(const std::function<bool(Vec3d)>& inside, const Ray& ray, double t0, double t1, int steps,
           std::vector<double>& out) {
  out.clear();
  const double h = (t1 - t0) / steps;
  bool prev = inside(ray.o + ray.d * t0);
  double last = t0;
  for (int i = 1; i <= steps; ++i) {
    const double t = t0 + h * i;
    const bool cur = inside(ray.o + ray.d * t);
    if (cur == prev) continue;
    double a = t - h, b = t;
    for (int k = 0; k < 80; ++k) {
      const double m = 0.5 * (a + b);
      (inside(ray.o + ray.d * m) == prev ? a : b) = m;
    }
    const double root = 0.5 * (a + b);
    if (!out.empty() && root - last < 3 * h) return false;
    out.push_back(root);
    last = root;
    prev = cur;
  }
  return true;
}

// March-based comparison of a primitive's crossings on random rays; returns max |t error|.
double compare_with_march(Shape shape, const Frame& f, int rays, double R = 1, double r = 0.25) {
  const Primitive p = make_primitive(make_desc(shape, f, R, r));
  plm::Rng rng(7, uint64_t(shape));
  double worst = 0;
  int compared = 0;
  std::vector<double> ref;
  for (int i = 0; i < rays; ++i) {
    const Ray ray = random_ray(rng, f, 1.3);
    if (!march([&](Vec3d w) { return inside_local(shape, f.to_local(w), R, r); }, ray, 0, 8, 6000, ref))
      continue;
    Crossing c[kMaxPrimitiveCrossings];
    const int n = intersect(p, ray.o, ray.d, ray_tolerance(p, ray.o, ray.d), c);
    bool resolvable = true;  // the march misses pieces shorter than a few steps
    for (int k = 1; k < n; ++k) resolvable &= c[k].t - c[k - 1].t > 3 * 8.0 / 6000;
    if (!resolvable) continue;
    EXPECT_EQ(n, int(ref.size())) << shape_name(shape) << " ray " << i;
    if (n != int(ref.size())) continue;
    for (int k = 0; k < n; ++k) {
      EXPECT_TRUE(std::isfinite(c[k].t));
      worst = std::fmax(worst, std::fabs(c[k].t - ref[k]));
    }
    ++compared;
  }
  EXPECT_GT(compared, rays * 9 / 10) << shape_name(shape);
  ::testing::Test::RecordProperty(std::string("max_t_error_") + shape_name(shape) + "_r" + std::to_string(r), sci(worst));
  return worst;
}

Frame skewed_frame() {
  Frame f;
  f.scale = {1.3, 0.7, 1.9};
  f.axis = {1, 2, 0.5};
  f.angle = 0.7;
  f.t = {0.4, -1.2, 2.5};
  return f;
}

TEST(CsgPrimitive, SphereMatchesClosedForm) {
  Frame f;
  f.scale = {1.7, 1.7, 1.7};
  f.t = {1, -2, 0.5};
  f.axis = {0, 1, 1};
  f.angle = 1.1;
  const Primitive p = make_primitive(make_desc(Shape::Sphere, f));
  plm::Rng rng(1, 1);
  double worst = 0;
  int hits = 0;
  for (int i = 0; i < 20000; ++i) {
    const Ray ray = random_ray(rng, f, 1.5);
    // |o + t d - c|^2 = s^2 in long double.
    const long double a = dot(ray.d, ray.d), b = dot(ray.o - f.t, ray.d),
                      c = (long double)dot(ray.o - f.t, ray.o - f.t) - 1.7L * 1.7L;
    const long double disc = b * b - a * c;
    Crossing x[4];
    const int n = intersect(p, ray.o, ray.d, ray_tolerance(p, ray.o, ray.d), x);
    if (disc <= 0) {
      EXPECT_EQ(n, 0);
      continue;
    }
    ASSERT_EQ(n, 2);
    ++hits;
    worst = std::fmax(worst, double(std::fabs(x[0].t - (-b - std::sqrt(disc)) / a)));
    worst = std::fmax(worst, double(std::fabs(x[1].t - (-b + std::sqrt(disc)) / a)));
  }
  EXPECT_GT(hits, 5000);
  EXPECT_LT(worst, 1e-12);
  RecordProperty("max_t_error", sci(worst));
}

TEST(CsgPrimitive, BoxMatchesSlabsWithFaces) {
  Frame f;
  f.scale = {0.5, 2, 1.25};
  f.t = {3, 1, -1};
  const Primitive p = make_primitive(make_desc(Shape::Box, f));
  plm::Rng rng(2, 2);
  double worst = 0;
  for (int i = 0; i < 20000; ++i) {
    const Ray ray = random_ray(rng, f, 1.5);
    double t0 = -1e300, t1 = 1e300;
    int f0 = -1, f1 = -1;
    for (int a = 0; a < 3; ++a) {
      const double lo = (f.t[a] - f.scale[a] - ray.o[a]) / ray.d[a], hi = (f.t[a] + f.scale[a] - ray.o[a]) / ray.d[a];
      const double n = std::fmin(lo, hi), x = std::fmax(lo, hi);
      if (n > t0) t0 = n, f0 = 2 * a + (ray.d[a] > 0 ? 0 : 1);
      if (x < t1) t1 = x, f1 = 2 * a + (ray.d[a] > 0 ? 1 : 0);
    }
    Crossing x[4];
    const int n = intersect(p, ray.o, ray.d, ray_tolerance(p, ray.o, ray.d), x);
    if (!(t1 > t0)) {
      EXPECT_EQ(n, 0);
      continue;
    }
    ASSERT_EQ(n, 2);
    EXPECT_EQ(x[0].face, f0);
    EXPECT_EQ(x[1].face, f1);
    worst = std::fmax(worst, std::fmax(std::fabs(x[0].t - t0), std::fabs(x[1].t - t1)));
    // The normal of the entry face points against the ray.
    EXPECT_LT(dot(normal(p, x[0].face, ray.o + ray.d * x[0].t), ray.d), 0);
  }
  EXPECT_LT(worst, 1e-12);
  RecordProperty("max_t_error", sci(worst));
}

TEST(CsgPrimitive, CylinderMatchesClosedForm) {
  Frame f;
  f.scale = {0.8, 0.8, 1.5};
  f.t = {-1, 0.5, 2};
  const Primitive p = make_primitive(make_desc(Shape::Cylinder, f));
  plm::Rng rng(3, 3);
  double worst = 0;
  for (int i = 0; i < 20000; ++i) {
    const Ray ray = random_ray(rng, f, 1.5);
    const Vec3d o = ray.o - f.t;
    const double a = ray.d.x * ray.d.x + ray.d.y * ray.d.y, b = o.x * ray.d.x + o.y * ray.d.y,
                 c = o.x * o.x + o.y * o.y - 0.64, disc = b * b - a * c;
    double t0 = (-f.scale.z - o.z) / ray.d.z, t1 = (f.scale.z - o.z) / ray.d.z;
    if (t0 > t1) std::swap(t0, t1);
    int f0 = ray.d.z > 0 ? 1 : 2, f1 = ray.d.z > 0 ? 2 : 1;
    if (disc > 0) {
      const double s0 = (-b - std::sqrt(disc)) / a, s1 = (-b + std::sqrt(disc)) / a;
      if (s0 > t0) t0 = s0, f0 = 0;
      if (s1 < t1) t1 = s1, f1 = 0;
    }
    Crossing x[4];
    const int n = intersect(p, ray.o, ray.d, ray_tolerance(p, ray.o, ray.d), x);
    if (!(disc > 0) || !(t1 > t0)) {
      EXPECT_EQ(n, 0);
      continue;
    }
    ASSERT_EQ(n, 2);
    EXPECT_EQ(x[0].face, f0);
    EXPECT_EQ(x[1].face, f1);
    worst = std::fmax(worst, std::fmax(std::fabs(x[0].t - t0), std::fabs(x[1].t - t1)));
  }
  EXPECT_LT(worst, 1e-10);
  RecordProperty("max_t_error", sci(worst));
}

TEST(CsgPrimitive, ConeTorusParaboloidMatchMarching) {
  const Frame f = skewed_frame();
  for (Shape s : {Shape::Cone, Shape::Torus, Shape::Paraboloid, Shape::Sphere, Shape::Cylinder, Shape::Box}) {
    const double worst = compare_with_march(s, f, 1000);
    EXPECT_LT(worst, 1e-9) << shape_name(s);
  }
  // A fat and a thin torus.
  EXPECT_LT(compare_with_march(Shape::Torus, f, 1000, 1.0, 0.9), 1e-9);
  EXPECT_LT(compare_with_march(Shape::Torus, f, 1000, 1.0, 0.02), 1e-9);
}

// Crossing t's of the line o + t (1,0,0) in the plane z = z0 against the
// unit-default torus (R, r), in closed form.
TEST(CsgPrimitive, TorusGrazingRaysAreExact) {
  const double R = 1, r = 0.25;
  const Primitive p = make_primitive(make_desc(Shape::Torus, Frame{}, R, r));
  const Vec3d d{1, 0, 0};
  auto hits = [&](Vec3d o, Crossing* x) { return intersect(p, o, d, ray_tolerance(p, o, d), x); };
  Crossing x[4];
  // Tangent to the outer equator: no interval, no NaN.
  EXPECT_EQ(hits({-5, R + r, 0}, x), 0);
  // Just inside it: one short interval, |x| <= sqrt((R+r)^2 - y^2).
  for (double gap : {1e-3, 1e-6, 1e-9}) {
    const double y = R + r - gap, half = std::sqrt((R + r) * (R + r) - y * y);
    ASSERT_EQ(hits({-5, y, 0}, x), 2) << gap;
    EXPECT_NEAR(x[0].t, 5 - half, 1e-9 + 1e-7 * half) << gap;
    EXPECT_NEAR(x[1].t, 5 + half, 1e-9 + 1e-7 * half) << gap;
  }
  // Tangent to the hole: the two intervals touch at x = 0 and merge.
  ASSERT_EQ(hits({-5, R - r, 0}, x), 2);
  EXPECT_NEAR(x[1].t - x[0].t, 2 * std::sqrt((R + r) * (R + r) - (R - r) * (R - r)), 1e-9);
  // Through the hole: two intervals.
  {
    const double y = 0.3, a = std::sqrt((R - r) * (R - r) - y * y), b = std::sqrt((R + r) * (R + r) - y * y);
    ASSERT_EQ(hits({-5, y, 0}, x), 4);
    const double expect[4] = {5 - b, 5 - a, 5 + a, 5 + b};
    for (int k = 0; k < 4; ++k) EXPECT_NEAR(x[k].t, expect[k], 1e-12);
  }
  // Tangent to the top circle at both x = +-R, and just below it.
  EXPECT_EQ(hits({-5, 0, r}, x), 0);
  for (double gap : {1e-4, 1e-8}) {
    const double z = r - gap, w = std::sqrt(r * r - z * z);
    ASSERT_EQ(hits({-5, 0, z}, x), 4) << gap;
    const double expect[4] = {5 - R - w, 5 - R + w, 5 + R - w, 5 + R + w};
    for (int k = 0; k < 4; ++k) EXPECT_NEAR(x[k].t, expect[k], 1e-9) << gap;
  }
  // Along the axis: misses; any random near-grazing direction: finite.
  EXPECT_EQ(intersect(p, {0, 0, -5}, {0, 0, 1}, 1e-12, x), 0);
  plm::Rng rng(11, 0);
  for (int i = 0; i < 20000; ++i) {
    const double phi = 2 * kPi * next_double(rng), y = R + r - 1e-6 * next_double(rng);
    const Vec3d o{-5 * std::cos(phi) - y * std::sin(phi), -5 * std::sin(phi) + y * std::cos(phi), 1e-7 * (next_double(rng) - 0.5)};
    const Vec3d dir{std::cos(phi), std::sin(phi), 0};
    const int n = intersect(p, o, dir, ray_tolerance(p, o, dir), x);
    ASSERT_EQ(n, 2);
    EXPECT_TRUE(std::isfinite(x[0].t) && std::isfinite(x[1].t));
  }
}

TEST(CsgPrimitive, SphereGrazesAndInsideStarts) {
  const Primitive p = make_primitive(make_desc(Shape::Sphere, Frame{}));
  Crossing x[4];
  EXPECT_EQ(intersect(p, {-5, 1, 0}, {1, 0, 0}, ray_tolerance(p, {-5, 1, 0}, {1, 0, 0}), x), 0);  // tangent
  const double y = 1 - 1e-6, half = std::sqrt(1 - y * y);
  ASSERT_EQ(intersect(p, {-5, y, 0}, {1, 0, 0}, 1e-15, x), 2);
  EXPECT_NEAR(x[0].t, 5 - half, 1e-12);
  EXPECT_NEAR(x[1].t, 5 + half, 1e-12);
  // From the centre, with a non-unit direction: t is in world units of d.
  ASSERT_EQ(intersect(p, {0, 0, 0}, {0, 0, 4}, 1e-15, x), 2);
  EXPECT_DOUBLE_EQ(x[0].t, -0.25);
  EXPECT_DOUBLE_EQ(x[1].t, 0.25);
}

TEST(CsgPrimitive, RaysAlongFacesAndParallelToCaps) {
  const Primitive box = make_primitive(make_desc(Shape::Box, Frame{}));
  Crossing x[4];
  // Along the +Y face plane: the closed box contains the face; defined, finite.
  ASSERT_EQ(intersect(box, {-5, 1, 0}, {1, 0, 0}, 1e-12, x), 2);
  EXPECT_DOUBLE_EQ(x[0].t, 4);
  EXPECT_DOUBLE_EQ(x[1].t, 6);
  EXPECT_EQ(x[0].face, 0);
  EXPECT_EQ(x[1].face, 1);
  // Along an edge, and just outside a face.
  EXPECT_EQ(intersect(box, {-5, 1, 1}, {1, 0, 0}, 1e-12, x), 2);
  EXPECT_EQ(intersect(box, {-5, 1 + 1e-12, 0}, {1, 0, 0}, 1e-12, x), 0);
  // Starting inside.
  ASSERT_EQ(intersect(box, {0.5, 0, 0}, {1, 0, 0}, 1e-12, x), 2);
  EXPECT_DOUBLE_EQ(x[0].t, -1.5);
  EXPECT_DOUBLE_EQ(x[1].t, 0.5);

  const Primitive cyl = make_primitive(make_desc(Shape::Cylinder, Frame{}));
  ASSERT_EQ(intersect(cyl, {-5, 0, 0.5}, {1, 0, 0}, 1e-12, x), 2);  // parallel to the caps
  EXPECT_DOUBLE_EQ(x[0].t, 4);
  EXPECT_EQ(x[0].face, 0);
  ASSERT_EQ(intersect(cyl, {-5, 0, 1}, {1, 0, 0}, 1e-12, x), 2);  // in the top cap's plane
  EXPECT_DOUBLE_EQ(x[1].t, 6);
  ASSERT_EQ(intersect(cyl, {0.5, 0, -5}, {0, 0, 1}, 1e-12, x), 2);  // along the axis: caps
  EXPECT_EQ(x[0].face, 1);
  EXPECT_EQ(x[1].face, 2);

  const Primitive cone = make_primitive(make_desc(Shape::Cone, Frame{}));
  ASSERT_EQ(intersect(cone, {0, 0, -5}, {0, 0, 1}, 1e-12, x), 2);  // base to apex
  EXPECT_DOUBLE_EQ(x[0].t, 4);
  EXPECT_DOUBLE_EQ(x[1].t, 6);
  EXPECT_EQ(x[0].face, 1);
  EXPECT_EQ(x[1].face, 0);
  ASSERT_EQ(intersect(cone, {-5, 0, 0}, {1, 0, 0}, 1e-12, x), 2);  // parallel to the base, radius 0.5 at z = 0
  EXPECT_DOUBLE_EQ(x[0].t, 4.5);
  EXPECT_DOUBLE_EQ(x[1].t, 5.5);
  // Parallel to the slant (the quadratic degenerates to a line).
  ASSERT_EQ(intersect(cone, {-4.75, 0, 10}, {1, 0, -2}, 1e-12, x), 2);
  EXPECT_NEAR(x[0].t, 4.625, 1e-12);
  EXPECT_NEAR(x[1].t, 5.5, 1e-12);
  EXPECT_EQ(x[0].face, 0);
  EXPECT_EQ(x[1].face, 1);

  const Primitive par = make_primitive(make_desc(Shape::Paraboloid, Frame{}));
  ASSERT_EQ(intersect(par, {0.5, 0, -5}, {0, 0, 1}, 1e-12, x), 2);  // vertical: bowl then cap
  EXPECT_DOUBLE_EQ(x[0].t, 5.25);
  EXPECT_DOUBLE_EQ(x[1].t, 6);
  EXPECT_EQ(x[0].face, 0);
  EXPECT_EQ(x[1].face, 1);
  ASSERT_EQ(intersect(par, {-5, 0, 1}, {1, 0, 0}, 1e-12, x), 2);  // in the cap plane
  EXPECT_DOUBLE_EQ(x[0].t, 4);

  const Primitive half = make_primitive(make_desc(Shape::HalfSpace, Frame{}));
  ASSERT_EQ(intersect(half, {0, 0, -1}, {0, 0, 1}, 1e-12, x), 2);
  EXPECT_EQ(x[0].t, -INFINITY);
  EXPECT_DOUBLE_EQ(x[1].t, 1);
  ASSERT_EQ(intersect(half, {0, 0, -1}, {1, 0, 0}, 1e-12, x), 2);  // parallel, below
  EXPECT_EQ(x[1].t, INFINITY);
  EXPECT_EQ(intersect(half, {0, 0, 1}, {1, 0, 0}, 1e-12, x), 0);
}

TEST(CsgPrimitive, NormalsOfAnEllipsoid) {
  Frame f;
  f.scale = {2, 0.5, 1};
  f.t = {1, 2, 3};
  const Primitive p = make_primitive(make_desc(Shape::Sphere, f));
  plm::Rng rng(5, 5);
  for (int i = 0; i < 1000; ++i) {
    FaceSample s;
    ASSERT_TRUE(sample_face(p, 0, rng, s));
    const Vec3d q = s.p - f.t;
    const Vec3d expect = normalize(Vec3d{q.x / 4, q.y / 0.25, q.z});
    EXPECT_NEAR(dot(s.n, expect), 1.0, 1e-12);
    EXPECT_NEAR(length(normal(p, 0, s.p) - expect), 0.0, 1e-12);
    EXPECT_EQ(classify(p, s.p), Side::Boundary);
    EXPECT_EQ(classify(p, s.p - s.n * 1e-3), Side::Inside);
    EXPECT_EQ(classify(p, s.p + s.n * 1e-3), Side::Outside);
  }
}

// A world-space parametrisation of each face for tessellation: (a, b) in [0,1]^2.
Vec3d face_point(Shape s, int face, double a, double b, const Frame& f, double R, double r) {
  const double phi = 2 * kPi * a, c = std::cos(phi), sn = std::sin(phi);
  Vec3d q;
  switch (s) {
    case Shape::Sphere: {
      const double th = kPi * b;
      q = {std::sin(th) * c, std::sin(th) * sn, std::cos(th)};
      break;
    }
    case Shape::Cylinder:
      q = face == 0 ? Vec3d{c, sn, 2 * b - 1} : Vec3d{b * c, b * sn, face == 1 ? -1.0 : 1.0};
      break;
    case Shape::Cone:
      q = face == 0 ? Vec3d{b * c, b * sn, 1 - 2 * b} : Vec3d{b * c, b * sn, -1};
      break;
    case Shape::Torus: {
      const double psi = 2 * kPi * b;
      q = {(R + r * std::cos(psi)) * c, (R + r * std::cos(psi)) * sn, r * std::sin(psi)};
      break;
    }
    case Shape::Paraboloid:
      q = face == 0 ? Vec3d{b * c, b * sn, b * b} : Vec3d{b * c, b * sn, 1};
      break;
    default:
      q = {2 * a - 1, 2 * b - 1, 1};  // box +Z
  }
  return f.to_world(q);
}

// Area of the tessellated face, optionally per bin of b.
double tessellated_area(Shape s, int face, const Frame& f, double R, double r, int n, std::vector<double>* bins) {
  double sum = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double a0 = double(i) / n, a1 = double(i + 1) / n, b0 = double(j) / n, b1 = double(j + 1) / n;
      const Vec3d p00 = face_point(s, face, a0, b0, f, R, r), p10 = face_point(s, face, a1, b0, f, R, r),
                  p01 = face_point(s, face, a0, b1, f, R, r), p11 = face_point(s, face, a1, b1, f, R, r);
      const double area = 0.5 * length(cross(p10 - p00, p11 - p00)) + 0.5 * length(cross(p11 - p00, p01 - p00));
      sum += area;
      if (bins) (*bins)[size_t(j) * bins->size() / n] += area;
    }
  return sum;
}

TEST(CsgPrimitive, AreasMatchClosedFormsAndTessellation) {
  // Similarity maps: closed forms.
  Frame u;
  u.scale = {2, 2, 2};
  u.axis = {1, 1, 0};
  u.angle = 0.4;
  EXPECT_NEAR(make_primitive(make_desc(Shape::Sphere, u)).area[0], 16 * kPi, 1e-12);
  EXPECT_NEAR(make_primitive(make_desc(Shape::Torus, u, 1, 0.25)).area[0], 4 * kPi * kPi * 0.25 * 4, 1e-12);
  EXPECT_NEAR(make_primitive(make_desc(Shape::Paraboloid, u)).area[0], 4 * kPi / 6 * (5 * std::sqrt(5.0) - 1), 1e-12);
  EXPECT_NEAR(make_primitive(make_desc(Shape::Cone, u)).area[0], 4 * kPi * std::sqrt(5.0), 1e-12);
  EXPECT_NEAR(make_primitive(make_desc(Shape::Box, u)).area[3], 16, 1e-12);
  // A spheroid (a, a, c) has a closed form; the general path uses quadrature.
  Frame sph;
  sph.scale = {1, 1, 0.5};
  sph.axis = {1, 0, 0};
  sph.angle = 0.3;
  const double e = std::sqrt(1 - 0.25), oblate = 2 * kPi * (1 + (0.25 / e) * std::atanh(e));
  EXPECT_NEAR(make_primitive(make_desc(Shape::Sphere, sph)).area[0] / oblate, 1.0, 1e-12);
  // Every curved face under a skewed non-uniform map against a fine tessellation.
  const Frame f = skewed_frame();
  struct Case {
    Shape s;
    int face;
  } cases[] = {{Shape::Sphere, 0}, {Shape::Cylinder, 0}, {Shape::Cylinder, 1}, {Shape::Cone, 0},
               {Shape::Cone, 1},   {Shape::Torus, 0},    {Shape::Paraboloid, 0}, {Shape::Paraboloid, 1}};
  for (const Case& c : cases) {
    const Primitive p = make_primitive(make_desc(c.s, f, 1, 0.3));
    ASSERT_FALSE(p.similarity);
    // Richardson extrapolation of two tessellations (error h^2 -> h^4).
    const double coarse = tessellated_area(c.s, c.face, f, 1, 0.3, 300, nullptr);
    const double fine = tessellated_area(c.s, c.face, f, 1, 0.3, 600, nullptr);
    const double ref = (4 * fine - coarse) / 3;
    EXPECT_NEAR(p.area[c.face] / ref, 1.0, 1e-8) << shape_name(c.s) << " face " << c.face;
    RecordProperty(std::string("area_rel_error_") + shape_name(c.s) + "_" + std::to_string(c.face),
                   sci(p.area[c.face] / ref - 1));
  }
}

// Cylinders and cones of circular section stretched along their axis (what
// an L-system's turtle draws) take a closed form for the side; elliptic ones
// the quadrature. Random rotations and scales against the textbook areas: 2 pi
// r h and pi r sqrt(r^2 + h^2); an elliptic cylinder: Ramanujan's perimeter x h.
TEST(CsgPrimitive, StretchedCylinderAndConeSidesMatchClosedForms) {
  std::mt19937_64 rng(77);
  std::uniform_real_distribution<double> u(0, 1);
  auto unit = [&] {
    const double z = 2 * u(rng) - 1, phi = 2 * kPi * u(rng), s = std::sqrt(1 - z * z);
    return Vec3d{s * std::cos(phi), s * std::sin(phi), z};
  };
  for (int i = 0; i < 400; ++i) {
    const Vec3d axis = unit(), l = normalize(cross(axis, unit())), up = cross(axis, l);
    const double scale = std::exp(4 * u(rng) - 2), a = scale * (0.01 + u(rng)), half = scale * (0.01 + 2 * u(rng));
    const bool elliptic = i % 10 == 9;
    const double b = elliptic ? 1.5 * a : a, h = 2 * half;
    const Vec3d cols[4] = {a * l, b * up, half * axis, 10 * unit()};
    PrimitiveDesc d;
    d.shape = i % 2 && !elliptic ? Shape::Cone : Shape::Cylinder;
    for (int c = 0; c < 4; ++c) {
      d.to_world[c] = cols[c].x;
      d.to_world[4 + c] = cols[c].y;
      d.to_world[8 + c] = cols[c].z;
    }
    const Primitive p = make_primitive(d);
    double side;
    if (d.shape == Shape::Cone) {
      side = kPi * a * std::sqrt(a * a + h * h);
    } else {
      const double q = (a - b) * (a - b) / ((a + b) * (a + b));  // Ramanujan II: error ~q^5
      side = kPi * (a + b) * (1 + 3 * q / (10 + std::sqrt(4 - 3 * q))) * h;
    }
    ASSERT_NEAR(p.area[0] / side, 1.0, 1e-9) << i << (elliptic ? " elliptic" : "");
    ASSERT_NEAR(p.area[1] / (kPi * a * b), 1.0, 1e-9) << i;
  }
}

// Sample counts per bin of the face parameter against tessellated bin areas
// (chi-square, 16 bins): area-uniform sampling under a skewed map.
TEST(CsgPrimitive, SamplingIsUniformInWorldArea) {
  const Frame f = skewed_frame();
  for (Shape s : {Shape::Sphere, Shape::Torus, Shape::Paraboloid, Shape::Cone}) {
    const Primitive p = make_primitive(make_desc(s, f, 1, 0.3));
    constexpr int kBins = 16, kSamples = 200000;
    std::vector<double> area(kBins, 0.0);
    const double total = tessellated_area(s, 0, f, 1, 0.3, 512, &area);
    std::vector<int> count(kBins, 0);
    plm::Rng rng(9, uint64_t(s));
    for (int i = 0; i < kSamples; ++i) {
      FaceSample x;
      ASSERT_TRUE(sample_face(p, 0, rng, x));
      EXPECT_NEAR(x.pdf * p.area[0], 1.0, 1e-12);
      // Back to the tessellation's b parameter.
      const Vec3d q = f.to_local(x.p);
      double b = 0;
      if (s == Shape::Sphere) b = std::acos(std::fmax(-1.0, std::fmin(1.0, q.z))) / kPi;
      if (s == Shape::Torus) b = x.v;
      if (s == Shape::Paraboloid) b = std::sqrt(std::fmax(0.0, q.z));
      if (s == Shape::Cone) b = 0.5 * (1 - q.z);
      ++count[std::min(kBins - 1, int(b * kBins))];
    }
    double chi2 = 0;
    for (int k = 0; k < kBins; ++k) {
      const double expect = kSamples * area[k] / total;
      chi2 += (count[k] - expect) * (count[k] - expect) / expect;
    }
    EXPECT_LT(chi2, 45.0) << shape_name(s);  // 15 dof: p ~ 1e-4
  }
}

TEST(CsgPrimitive, BoundsContainTheSolid) {
  const Frame f = skewed_frame();
  for (Shape s : {Shape::Sphere, Shape::Box, Shape::Cylinder, Shape::Cone, Shape::Torus, Shape::Paraboloid}) {
    const Primitive p = make_primitive(make_desc(s, f));
    plm::Rng rng(4, uint64_t(s));
    for (int i = 0; i < 2000; ++i) {
      FaceSample x;
      ASSERT_TRUE(sample_face(p, int(i % face_count(s)), rng, x));
      for (int a = 0; a < 3; ++a) {
        EXPECT_GE(x.p[a], p.lo[a] - 1e-12);
        EXPECT_LE(x.p[a], p.hi[a] + 1e-12);
      }
    }
  }
  Frame up;
  up.t = {0, 0, 2};
  const Primitive h = make_primitive(make_desc(Shape::HalfSpace, up));
  EXPECT_EQ(h.hi.z, 2);
  EXPECT_EQ(h.lo.z, -INFINITY);
  EXPECT_EQ(h.hi.x, INFINITY);
}

TEST(CsgPrimitive, BadInputIsRejected) {
  PrimitiveDesc d;
  d.to_world[5] = NAN;
  EXPECT_NE(check_primitive(d).find("NaN"), std::string::npos);
  d.to_world[5] = 0;
  EXPECT_NE(check_primitive(d).find("singular"), std::string::npos);
  EXPECT_THROW(make_primitive(d), plm::Error);
  PrimitiveDesc t;
  t.shape = Shape::Torus;
  t.major_radius = 1;
  t.minor_radius = 1;
  EXPECT_NE(check_primitive(t).find("smaller"), std::string::npos);
  t.minor_radius = -0.1;
  EXPECT_NE(check_primitive(t).find("positive"), std::string::npos);
}

}  // namespace

// CSG trees against truth: first hits against brute-force marching of the
// solid's inside test, boundary areas of cut solids against closed forms by
// Monte Carlo, coincident faces, tangent solids, extreme scales, bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "csg/csg.h"
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

// world = t + diag(s) * local (enough for trees; primitives test rotations).
PrimitiveDesc prim(Shape shape, Vec3d s, Vec3d t, double R = 1, double r = 0.25) {
  PrimitiveDesc d;
  d.shape = shape;
  d.major_radius = R;
  d.minor_radius = r;
  const double m[12] = {s.x, 0, 0, t.x, 0, s.y, 0, t.y, 0, 0, s.z, t.z};
  std::copy(m, m + 12, d.to_world);
  return d;
}

// Builds a flat tree: leaves first, then operators over them.
struct TreeBuilder {
  CsgDesc d;
  explicit TreeBuilder(std::string name) { d.name = std::move(name); }
  uint32_t leaf(const PrimitiveDesc& p) {
    d.primitives.push_back(p);
    d.materials.push_back(uint32_t(d.materials.size()) + 10);
    d.nodes.push_back({Op::Leaf, uint32_t(d.primitives.size() - 1), 0});
    return uint32_t(d.nodes.size() - 1);
  }
  uint32_t op(Op o, std::vector<uint32_t> kids) {
    d.nodes.push_back({o, uint32_t(d.children.size()), uint32_t(kids.size())});
    d.children.insert(d.children.end(), kids.begin(), kids.end());
    return d.root = uint32_t(d.nodes.size() - 1);
  }
  CsgObject build() const { return CsgObject(d); }
};

// Like op, but the whole object is scaled by s and moved by t.
CsgDesc sphere_minus_cylinder_desc(double s = 1, Vec3d t = {0, 0, 0}) {
  TreeBuilder b("sphere-cyl");
  const uint32_t sphere = b.leaf(prim(Shape::Sphere, Vec3d{1, 1, 1} * s, t));
  const uint32_t cyl = b.leaf(prim(Shape::Cylinder, Vec3d{0.4, 0.4, 2} * s, t));
  b.op(Op::Difference, {sphere, cyl});
  return b.d;
}
CsgObject sphere_minus_cylinder(double s = 1, Vec3d t = {0, 0, 0}) { return CsgObject(sphere_minus_cylinder_desc(s, t)); }

// The test's own evaluation of the unflattened tree with strict primitive
// tests: the truth the march follows (no tolerance band).
struct Truth {
  const CsgDesc& d;
  std::vector<Primitive> prims;
  explicit Truth(const CsgDesc& desc) : d(desc) {
    for (const PrimitiveDesc& p : desc.primitives) prims.push_back(make_primitive(p));
  }
  bool inside(uint32_t node, Vec3d p) const {
    const NodeDesc& n = d.nodes[node];
    if (n.op == Op::Leaf) return inside_strict(prims[n.first], p);
    bool acc = inside(d.children[n.first], p);
    for (uint32_t k = 1; k < n.count; ++k) {
      const bool b = inside(d.children[n.first + k], p);
      acc = n.op == Op::Union ? acc || b : n.op == Op::Intersection ? acc && b : acc && !b;
    }
    return acc;
  }
  bool operator()(Vec3d p) const { return inside(d.root, p); }
};

Vec3d random_unit(plm::Rng& rng) {
  const double z = 1 - 2 * next_double(rng), phi = 2 * kPi * next_double(rng), r = std::sqrt(1 - z * z);
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// Ray from a sphere around the object's bounds towards a random point inside them.
void random_ray(plm::Rng& rng, const CsgObject& obj, Vec3d& o, Vec3d& d) {
  const Vec3d c = (obj.bounds_lo() + obj.bounds_hi()) * 0.5, e = (obj.bounds_hi() - obj.bounds_lo()) * 0.5;
  const double radius = length(e) * 1.5;
  o = c + random_unit(rng) * radius;
  const Vec3d target = c + Vec3d{e.x * (2 * next_double(rng) - 1), e.y * (2 * next_double(rng) - 1),
                                 e.z * (2 * next_double(rng) - 1)};
  d = target - o;
}

// Crossings of the solid by marching inside() over t in [0, t1]; false when
// two changes are closer than 3 steps (unresolvable by the march).
bool march(const Truth& truth, Vec3d o, Vec3d d, double t1, int steps, std::vector<double>& out) {
  out.clear();
  const double h = t1 / steps;
  bool prev = truth(o);
  for (int i = 1; i <= steps; ++i) {
    const double t = h * i;
    const bool cur = truth(o + d * t);
    if (cur == prev) continue;
    double a = t - h, b = t;
    for (int k = 0; k < 70; ++k) {
      const double m = 0.5 * (a + b);
      (truth(o + d * m) == prev ? a : b) = m;
    }
    if (!out.empty() && 0.5 * (a + b) - out.back() < 3 * h) return false;
    out.push_back(0.5 * (a + b));
    prev = cur;
  }
  return true;
}

// Random rays: all crossings equal the march's; the first hit's normal points
// out of the solid. Returns the largest |t error| relative to the object size.
double check_against_march(const CsgDesc& desc, int rays, uint64_t seed) {
  const CsgObject obj(desc);
  const Truth truth(desc);
  plm::Rng rng(seed, 1);
  const double size = length(obj.bounds_hi() - obj.bounds_lo());
  double worst = 0;
  int compared = 0;
  std::vector<double> ref;
  Crossing buf[kMaxCrossings];
  for (int i = 0; i < rays; ++i) {
    Vec3d o, d;
    random_ray(rng, obj, o, d);
    const double t1 = 3.0;  // the far side of the bounding sphere is within t = 3
    if (!march(truth, o, d, t1, 6000, ref)) continue;
    const int n = obj.crossings(o, d, 0, t1, buf);
    bool resolvable = true;
    for (int k = 1; k < n; ++k) resolvable &= buf[k].t - buf[k - 1].t > 3 * t1 / 6000;
    if (!resolvable) continue;
    EXPECT_EQ(n, int(ref.size())) << obj.name() << " ray " << i;
    if (n != int(ref.size())) continue;
    ++compared;
    for (int k = 0; k < n; ++k) worst = std::fmax(worst, std::fabs(buf[k].t - ref[k]) * length(d) / size);
    CsgHit hit;
    EXPECT_EQ(obj.first_hit(o, d, 0, t1, hit), n > 0);
    if (n == 0) continue;
    EXPECT_EQ(hit.t, buf[0].t);
    EXPECT_EQ(hit.material, hit.prim + 10);
    const double delta = 1e-6 * size + 10 * obj.tolerance();
    EXPECT_TRUE(obj.inside(hit.p - hit.n * delta)) << obj.name() << " ray " << i;
    EXPECT_FALSE(obj.inside(hit.p + hit.n * delta)) << obj.name() << " ray " << i;
  }
  EXPECT_GT(compared, rays * 9 / 10) << obj.name();
  ::testing::Test::RecordProperty("max_rel_t_error_" + obj.name() + "_" + std::to_string(seed), sci(worst));
  return worst;
}

TEST(CsgTree, FirstHitsMatchMarching) {
  EXPECT_LT(check_against_march(sphere_minus_cylinder_desc(), 1500, 1), 1e-9);
  {
    TreeBuilder b("box-and-sphere");
    b.op(Op::Intersection, {b.leaf(prim(Shape::Box, {1, 1, 1}, {0, 0, 0})),
                            b.leaf(prim(Shape::Sphere, {1.3, 1.3, 1.3}, {0.2, 0, 0}))});
    EXPECT_LT(check_against_march(b.d, 1500, 2), 1e-9);
  }
  for (Op op : {Op::Union, Op::Intersection, Op::Difference}) {
    TreeBuilder b("three");
    b.op(op, {b.leaf(prim(Shape::Box, {1, 0.8, 0.6}, {0, 0, 0})),
              b.leaf(prim(Shape::Torus, {1, 1, 1.5}, {0.3, 0, 0.2}, 1, 0.35)),
              b.leaf(prim(Shape::Cone, {0.7, 0.7, 1.2}, {-0.2, 0.3, 0}))});
    EXPECT_LT(check_against_march(b.d, 1000, 3 + int(op)), 1e-9) << int(op);
  }
  // Nested operators and a paraboloid: (box - (cyl u paraboloid)) n sphere.
  TreeBuilder b("nested");
  const uint32_t box = b.leaf(prim(Shape::Box, {1, 1, 1}, {0, 0, 0}));
  const uint32_t cyl = b.leaf(prim(Shape::Cylinder, {0.3, 0.3, 2}, {0.5, 0.5, 0}));
  const uint32_t par = b.leaf(prim(Shape::Paraboloid, {0.6, 0.6, 0.8}, {-0.3, 0, 0.4}));
  const uint32_t sph = b.leaf(prim(Shape::Sphere, {1.35, 1.35, 1.35}, {0, 0, 0}));
  const uint32_t u = b.op(Op::Union, {cyl, par});
  const uint32_t diff = b.op(Op::Difference, {box, u});
  b.op(Op::Intersection, {diff, sph});
  EXPECT_LT(check_against_march(b.d, 1000, 9), 1e-9);
}

// The boundary area of a solid by Monte Carlo: per face, area x the fraction
// of uniform samples on the solid's boundary; returns {estimate, std error}.
std::pair<double, double> boundary_area(const CsgObject& obj, int samples, uint64_t seed) {
  double area = 0, var = 0;
  plm::Rng rng(seed, 0);
  for (uint32_t i = 0; i < obj.primitive_count(); ++i) {
    const Primitive& p = obj.primitive(i);
    for (int f = 0; f < face_count(p.shape); ++f) {
      int on = 0;
      for (int k = 0; k < samples; ++k) {
        FaceSample s;
        EXPECT_TRUE(sample_face(p, f, rng, s));
        on += obj.on_boundary(i, f, s.p);
      }
      const double frac = double(on) / samples;
      area += p.area[f] * frac;
      var += p.area[f] * p.area[f] * frac * (1 - frac) / samples;
    }
  }
  return {area, std::sqrt(var)};
}

void check_area(const CsgObject& obj, double exact) {
  const auto [a1, e1] = boundary_area(obj, 4000, 1);
  const auto [a2, e2] = boundary_area(obj, 64000, 2);
  ::testing::Test::RecordProperty("area_" + obj.name(), sci(a2) + " +- " + sci(e2) + " exact " + sci(exact));
  EXPECT_LT(std::fabs(a1 - exact), 4 * e1 + 1e-12) << obj.name() << " estimate " << a1 << " exact " << exact;
  EXPECT_LT(std::fabs(a2 - exact), 4 * e2 + 1e-12) << obj.name() << " estimate " << a2 << " exact " << exact;
  if (e1 > 0) {
    EXPECT_NEAR(e2 / e1, 0.25, 0.05) << obj.name();  // the error falls as 1/sqrt(samples)
  }
}

TEST(CsgTree, CutSurfaceAreasMatchClosedForms) {
  // Sphere R = 1 minus a cylinder r = 0.4 through its centre.
  const double R = 1, r = 0.4, w = std::sqrt(R * R - r * r);
  check_area(sphere_minus_cylinder(), 4 * kPi * R * w + 4 * kPi * r * w);
  // A box cut by a sphere: the sphere's zone below z = c plus a disk.
  const double c = 0.3;
  TreeBuilder b("box-cut-sphere");
  b.op(Op::Intersection, {b.leaf(prim(Shape::Box, {2, 2, (c + 2) / 2}, {0, 0, (c - 2) / 2})),
                          b.leaf(prim(Shape::Sphere, {R, R, R}, {0, 0, 0}))});
  check_area(b.build(), 2 * kPi * R * (R + c) + kPi * (R * R - c * c));
  // A sphere containing a box: the box.
  TreeBuilder inner("box-in-sphere");
  inner.op(Op::Intersection, {inner.leaf(prim(Shape::Box, {0.5, 0.5, 0.5}, {0, 0, 0})),
                              inner.leaf(prim(Shape::Sphere, {1, 1, 1}, {0, 0, 0}))});
  check_area(inner.build(), 6.0);
}

TEST(CsgTree, HalfSpaceCutsASphere) {
  TreeBuilder b("half");
  b.op(Op::Intersection, {b.leaf(prim(Shape::Sphere, {1, 1, 1}, {0, 0, 0})),
                          b.leaf(prim(Shape::HalfSpace, {1, 1, 1}, {0, 0, 0.3}))});
  const CsgObject obj = b.build();
  EXPECT_NEAR(obj.bounds_hi().z, 0.3, 1e-6);  // clipped by the plane
  EXPECT_NEAR(obj.bounds_lo().z, -1, 1e-6);
  CsgHit hit;
  ASSERT_TRUE(obj.first_hit({0.1, 0.2, 5}, {0, 0, -1}, 0, 100, hit));
  EXPECT_NEAR(hit.t, 4.7, 1e-12);
  EXPECT_EQ(hit.prim, 1u);
  EXPECT_NEAR(hit.n.z, 1, 1e-12);
  ASSERT_TRUE(obj.first_hit({0.1, 0.2, -5}, {0, 0, 1}, 0, 100, hit));
  EXPECT_NEAR(hit.t, 5 - std::sqrt(1 - 0.05), 1e-12);
  EXPECT_LT(check_against_march(b.d, 800, 21), 1e-9);
  // Subtracting the half-space keeps the other cap.
  TreeBuilder s("half-diff");
  s.op(Op::Difference, {s.leaf(prim(Shape::Sphere, {1, 1, 1}, {0, 0, 0})),
                        s.leaf(prim(Shape::HalfSpace, {1, 1, 1}, {0, 0, 0.3}))});
  const CsgObject top = s.build();
  ASSERT_TRUE(top.first_hit({0.1, 0.2, -5}, {0, 0, 1}, 0, 100, hit));
  EXPECT_NEAR(hit.t, 5.3, 1e-12);
  EXPECT_TRUE(hit.flipped);
  EXPECT_NEAR(hit.n.z, -1, 1e-12);
}

TEST(CsgTree, UnionOfBoxesSharingAFaceHasNoInternalFace) {
  TreeBuilder b("two-boxes");
  b.op(Op::Union, {b.leaf(prim(Shape::Box, {1, 1, 1}, {0, 0, 0})), b.leaf(prim(Shape::Box, {1, 1, 1}, {2, 0, 0}))});
  const CsgObject obj = b.build();
  ASSERT_EQ(obj.warnings().size(), 1u);
  EXPECT_NE(obj.warnings()[0].find("'two-boxes': primitives 0 (box face +X) and 1 (box face -X)"), std::string::npos)
      << obj.warnings()[0];
  CsgHit hit;
  // From inside the first box across the shared plane: the far face of the second.
  ASSERT_TRUE(obj.first_hit({0, 0.3, 0.2}, {1, 0, 0}, 0, 100, hit));
  EXPECT_DOUBLE_EQ(hit.t, 3);
  EXPECT_EQ(hit.prim, 1u);
  ASSERT_TRUE(obj.first_hit({2, 0.3, 0.2}, {-1, 0, 0}, 0, 100, hit));
  EXPECT_DOUBLE_EQ(hit.t, 3);
  EXPECT_EQ(hit.prim, 0u);
  // Oblique rays through the shared plane: exactly two crossings.
  plm::Rng rng(3, 3);
  Crossing buf[kMaxCrossings];
  for (int i = 0; i < 2000; ++i) {
    const Vec3d o{-3, 2 * next_double(rng) - 1, 2 * next_double(rng) - 1};
    const Vec3d target{3, 2 * next_double(rng) - 1, 2 * next_double(rng) - 1};
    EXPECT_EQ(obj.crossings(o, target - o, 0, 1, buf), 2);
  }
  // Nor is the shared face part of the boundary.
  EXPECT_FALSE(obj.on_boundary(0, 1, {1, 0.2, 0.3}));
  EXPECT_FALSE(obj.on_boundary(1, 0, {1, 0.2, 0.3}));
  EXPECT_TRUE(obj.on_boundary(0, 3, {0.2, 1, 0.3}));
  // The same when the second box is off by rounding (e.g. from a float matrix).
  TreeBuilder c("two-boxes-rounded");
  c.op(Op::Union, {c.leaf(prim(Shape::Box, {1, 1, 1}, {0, 0, 0})),
                   c.leaf(prim(Shape::Box, {1, 1, 1}, {2 + 3e-8, 0, 0}))});
  ASSERT_TRUE(c.build().first_hit({0, 0.3, 0.2}, {1, 0, 0}, 0, 100, hit));
  EXPECT_NEAR(hit.t, 3, 1e-7);
}

TEST(CsgTree, DifferenceSharingAFaceLeavesNoSkin) {
  // A pocket that reaches the +X face: x in [0, 1], |y|, |z| <= 0.5.
  for (double offset : {0.0, 4e-8, -4e-8}) {
    TreeBuilder b("pocket");
    b.op(Op::Difference, {b.leaf(prim(Shape::Box, {1, 1, 1}, {0, 0, 0})),
                          b.leaf(prim(Shape::Box, {0.5, 0.5, 0.5}, {0.5 + offset, 0, 0}))});
    const CsgObject obj = b.build();
    EXPECT_EQ(obj.warnings().size(), 1u);
    Crossing buf[kMaxCrossings];
    // Along x through the pocket: enter at -1, leave into the pocket at 0; nothing at x = 1.
    ASSERT_EQ(obj.crossings({-5, 0, 0}, {1, 0, 0}, 0, 100, buf), 2) << offset;
    EXPECT_DOUBLE_EQ(buf[0].t, 4);
    EXPECT_NEAR(buf[1].t, 5 + offset, 1e-15);
    CsgHit hit = obj.make_hit(buf[1], {-5, 0, 0}, {1, 0, 0});
    EXPECT_EQ(hit.prim, 1u);
    EXPECT_TRUE(hit.flipped);
    EXPECT_NEAR(hit.n.x, 1, 1e-12);  // out of the solid, into the pocket
    // From outside on the +X side: straight into the pocket, hitting its floor.
    ASSERT_TRUE(obj.first_hit({5, 0.1, 0.1}, {-1, 0, 0}, 0, 100, hit));
    EXPECT_NEAR(hit.t, 5 - offset, 1e-15);
    EXPECT_NEAR(hit.n.x, 1, 1e-12);
    // Beside the pocket the +X face is there.
    ASSERT_TRUE(obj.first_hit({5, 0.8, 0.1}, {-1, 0, 0}, 0, 100, hit));
    EXPECT_DOUBLE_EQ(hit.t, 4);
    EXPECT_EQ(hit.prim, 0u);
    EXPECT_FALSE(obj.on_boundary(0, 1, {1, 0.1, 0.1}));  // the removed part of the face
    EXPECT_FALSE(obj.on_boundary(1, 1, {1, 0.1, 0.1}));  // the pocket's own coincident face
    EXPECT_TRUE(obj.on_boundary(0, 1, {1, 0.8, 0.1}));
    EXPECT_TRUE(obj.on_boundary(1, 0, {offset, 0.1, 0.1}));
  }
  // Area: the cube's 24 minus the removed 1 x 1 square plus the pocket's 5 inner 1 x 1 walls.
  TreeBuilder b("pocket-area");
  b.op(Op::Difference, {b.leaf(prim(Shape::Box, {1, 1, 1}, {0, 0, 0})),
                        b.leaf(prim(Shape::Box, {0.5, 0.5, 0.5}, {0.5, 0, 0}))});
  const auto [area, err] = boundary_area(b.build(), 20000, 7);
  EXPECT_LT(std::fabs(area - (24 - 1 + 5)), 4 * err + 1e-12) << area;
}

TEST(CsgTree, TouchingFromOutsideAndSharedFaceIntersection) {
  TreeBuilder b("touching");
  b.op(Op::Difference, {b.leaf(prim(Shape::Box, {1, 1, 1}, {0, 0, 0})), b.leaf(prim(Shape::Box, {1, 1, 1}, {2, 0, 0}))});
  const CsgObject obj = b.build();
  CsgHit hit;
  ASSERT_TRUE(obj.first_hit({5, 0.1, 0.1}, {-1, 0, 0}, 0, 100, hit));
  EXPECT_DOUBLE_EQ(hit.t, 4);
  EXPECT_EQ(hit.prim, 0u);  // the minuend's face stays
  EXPECT_FALSE(hit.flipped);
  EXPECT_TRUE(obj.on_boundary(0, 1, {1, 0.1, 0.1}));
  EXPECT_FALSE(obj.on_boundary(1, 0, {1, 0.1, 0.1}));

  TreeBuilder i("shared");
  i.op(Op::Intersection, {i.leaf(prim(Shape::Box, {1, 1, 1}, {0, 0, 0})),
                          i.leaf(prim(Shape::Box, {1, 0.5, 0.5}, {0, 0, 0}))});
  ASSERT_TRUE(i.build().first_hit({-5, 0.1, 0.1}, {1, 0, 0}, 0, 100, hit));
  EXPECT_DOUBLE_EQ(hit.t, 4);
  EXPECT_EQ(hit.prim, 0u);  // the first child's face
}

TEST(CsgTree, TangentSpheres) {
  TreeBuilder u("tangent-union");
  u.op(Op::Union, {u.leaf(prim(Shape::Sphere, {1, 1, 1}, {-1, 0, 0})), u.leaf(prim(Shape::Sphere, {1, 1, 1}, {1, 0, 0}))});
  const CsgObject obj = u.build();
  Crossing buf[kMaxCrossings];
  ASSERT_EQ(obj.crossings({-5, 0, 0}, {1, 0, 0}, 0, 100, buf), 2);  // the touching point is no boundary crossing
  EXPECT_DOUBLE_EQ(buf[0].t, 3);
  EXPECT_DOUBLE_EQ(buf[1].t, 7);
  for (double y : {1e-9, 1e-6, 1e-3}) {
    const int n = obj.crossings({-5, y, 0}, {1, 0, 0}, 0, 100, buf);
    EXPECT_TRUE(n == 2 || n == 4) << y;
    for (int k = 0; k < n; ++k) EXPECT_TRUE(std::isfinite(buf[k].t));
  }
  TreeBuilder x("tangent-intersection");
  x.op(Op::Intersection, {x.leaf(prim(Shape::Sphere, {1, 1, 1}, {-1, 0, 0})), x.leaf(prim(Shape::Sphere, {1, 1, 1}, {1, 0, 0}))});
  const CsgObject empty = x.build();
  EXPECT_EQ(empty.crossings({-5, 0, 0}, {1, 0, 0}, 0, 100, buf), 0);
  EXPECT_EQ(empty.crossings({0, 0, -5}, {0, 0, 1}, 0, 100, buf), 0);
}

// The unit object's crossings, scaled and moved, must scale exactly.
TEST(CsgTree, ExtremeScalesAndFarPlacement) {
  const CsgObject unit = sphere_minus_cylinder();
  plm::Rng rng(17, 0);
  Crossing a[kMaxCrossings], b[kMaxCrossings];
  for (double s : {1e-4, 1.0, 1e4}) {
    for (Vec3d t : {Vec3d{0, 0, 0}, Vec3d{1e5, -1e5, 1e5}}) {
      const CsgObject obj = sphere_minus_cylinder(s, t);
      // Far from the origin a world point is only known to an ulp of its coordinates.
      const double ulp = std::nextafter(max_abs_component(t), INFINITY) - max_abs_component(t);
      EXPECT_LT(check_against_march(sphere_minus_cylinder_desc(s, t), 200, 31), 1e-9 + 8 * ulp / s) << s;
      double worst = 0;
      for (int i = 0; i < 2000; ++i) {
        Vec3d o, d;
        random_ray(rng, unit, o, d);
        const int n = unit.crossings(o, d, 0, 10, a);
        const int m = obj.crossings(o * s + t, d * s, 0, 10, b);
        // Rounding of o * s + t far from the origin moves the ray by up to an ulp of t.
        const double ray_error = ulp / s;
        if (n != m) {
          bool close_call = false;  // a near-tangent piece the moved ray may miss
          for (int k = 1; k < n; ++k) close_call |= a[k].t - a[k - 1].t < 1e-3;
          EXPECT_TRUE(close_call && ray_error > 0) << s << " ray " << i;
          continue;
        }
        for (int k = 0; k < n; ++k) {
          ASSERT_TRUE(std::isfinite(b[k].t));
          worst = std::fmax(worst, std::fabs(a[k].t - b[k].t));
          EXPECT_EQ(a[k].prim, b[k].prim);
        }
        CsgHit hit;
        if (obj.first_hit(o * s + t, d * s, 0, 10, hit)) {
          EXPECT_TRUE(is_finite(hit.n) && is_finite(hit.p));
        }
      }
      // In t units (the unit object's); the moved ray's rounding is amplified
      // at grazing incidence, so allow a thousand ulps there.
      EXPECT_LT(worst, 1e-9 + 1000 * ulp / s) << "scale " << s << " at " << t.x;
    }
  }
}

TEST(CsgTree, BadInputNamesTheCulprit) {
  auto expect_error = [](const CsgDesc& d, const std::string& needle) {
    try {
      CsgObject obj(d);
      ADD_FAILURE() << "no error for " << needle;
    } catch (const plm::Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  auto two_spheres = [] {
    TreeBuilder b("obj");
    b.op(Op::Union, {b.leaf(prim(Shape::Sphere, {1, 1, 1}, {0, 0, 0})), b.leaf(prim(Shape::Sphere, {1, 1, 1}, {1, 0, 0}))});
    return b.d;
  };
  CsgDesc d = two_spheres();
  d.primitives[1].to_world[0] = NAN;
  expect_error(d, "CSG object 'obj': primitive 1: sphere transform has NaN");
  d = two_spheres();
  d.primitives[1].to_world[10] = 0;
  expect_error(d, "primitive 1: sphere transform is singular");
  d = two_spheres();
  d.primitives[0].shape = Shape::Torus;
  d.primitives[0].minor_radius = 2;
  expect_error(d, "primitive 0: torus minor radius");
  d = two_spheres();
  d.nodes[2].count = 0;
  expect_error(d, "node 2 (union) has no children");
  d = two_spheres();
  d.children[1] = 7;
  expect_error(d, "node 2 has child 7");
  d = two_spheres();
  d.nodes[1].first = 5;
  expect_error(d, "node 1 refers to primitive 5");
  d = two_spheres();
  d.children[1] = 2;  // the union contains itself
  expect_error(d, "cycle through node 2");
  d = two_spheres();
  d.materials.pop_back();
  expect_error(d, "1 materials for 2 primitives");
  TreeBuilder h("halfspace-only");
  h.op(Op::Union, {h.leaf(prim(Shape::Sphere, {1, 1, 1}, {0, 0, 0})), h.leaf(prim(Shape::HalfSpace, {1, 1, 1}, {0, 0, 0}))});
  expect_error(h.d, "CSG object 'halfspace-only' is unbounded");
  TreeBuilder big("big");
  std::vector<uint32_t> leaves;
  for (int i = 0; i < 300; ++i) leaves.push_back(big.leaf(prim(Shape::Sphere, {1, 1, 1}, {double(i), 0, 0})));
  big.op(Op::Union, leaves);
  expect_error(big.d, "CSG object 'big' needs");
}

TEST(CsgTree, NestedSameOperatorsAreMerged) {
  // ((a - b) - c) equals -(a, b, c); (a u (b u c)) equals u(a, b, c).
  TreeBuilder b("nested-diff");
  const uint32_t a = b.leaf(prim(Shape::Box, {1, 1, 1}, {0, 0, 0}));
  const uint32_t s1 = b.leaf(prim(Shape::Sphere, {0.5, 0.5, 0.5}, {1, 0, 0}));
  const uint32_t s2 = b.leaf(prim(Shape::Sphere, {0.5, 0.5, 0.5}, {-1, 0, 0}));
  b.op(Op::Difference, {b.op(Op::Difference, {a, s1}), s2});
  const CsgObject obj = b.build();
  EXPECT_EQ(obj.scratch_crossings(), 6 + 2 + 6);
  CsgHit hit;
  ASSERT_TRUE(obj.first_hit({-5, 0, 0}, {1, 0, 0}, 0, 100, hit));
  EXPECT_DOUBLE_EQ(hit.t, 4.5);
  EXPECT_EQ(hit.prim, 2u);
  EXPECT_TRUE(obj.warnings().empty());
  // tnear / tfar select crossings.
  ASSERT_TRUE(obj.first_hit({-5, 0, 0}, {1, 0, 0}, 4.6, 100, hit));
  EXPECT_DOUBLE_EQ(hit.t, 5.5);
  EXPECT_FALSE(obj.first_hit({-5, 0, 0}, {1, 0, 0}, 0, 4.4, hit));
  EXPECT_TRUE(obj.occluded({-5, 0, 0}, {1, 0, 0}, 0, 4.6));
  EXPECT_FALSE(obj.occluded({-5, 0, 0}, {1, 0, 0}, 4.6, 5.4));
}

}  // namespace

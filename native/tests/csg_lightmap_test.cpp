// CSG-aware lightmaps: face charts against exact areas, sub-texel areas
// against closed-form boundary areas, texel splitting at a groove, transfer
// from a tessellation, and scale extremes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>

#include "csg/csg_lightmap.h"
#include "csg/quadrature.h"
#include "util/error.h"

namespace {

using namespace plm::csg;
using plm::Vec3d;

constexpr double kPi = 3.14159265358979323846;

PrimitiveDesc prim(Shape shape, Vec3d s, Vec3d t) {
  PrimitiveDesc d;
  d.shape = shape;
  const double m[12] = {s.x, 0, 0, t.x, 0, s.y, 0, t.y, 0, 0, s.z, t.z};
  std::copy(m, m + 12, d.to_world);
  return d;
}

// A skewed, non-uniformly scaled map far enough from the origin to matter.
PrimitiveDesc skewed(Shape shape) {
  PrimitiveDesc d;
  d.shape = shape;
  const double m[12] = {1.3, 0.4, 0.1, 3.0, 0.2, 0.7, -0.3, -2.0, 0.05, 0.25, 1.9, 0.5};
  std::copy(m, m + 12, d.to_world);
  return d;
}

// Primitives combined by one operator at the root (a single primitive: a leaf).
CsgObject make(const std::vector<PrimitiveDesc>& prims, Op op) {
  CsgDesc d;
  d.name = "test";
  d.primitives = prims;
  d.materials.assign(prims.size(), 0);
  for (uint32_t i = 0; i < prims.size(); ++i) d.nodes.push_back({Op::Leaf, i, 0});
  if (prims.size() == 1) {
    d.root = 0;
  } else {
    for (uint32_t i = 0; i < prims.size(); ++i) d.children.push_back(i);
    d.nodes.push_back({op, 0, uint32_t(prims.size())});
    d.root = uint32_t(prims.size());
  }
  return CsgObject(d);
}

CsgLightmap lightmap(const CsgObject& obj, double texel, int grid = 8, bool split = true) {
  CsgLightmapSettings s;
  s.texel_size = texel;
  s.grid = grid;
  s.split = split;
  return CsgLightmap(obj, s);
}

double total_area(const CsgLightmap& lm) {
  double sum = 0;
  for (uint32_t i = 0; i < lm.sub_texel_count(); ++i) sum += lm.area(i);
  return sum;
}

// Integral over a triangle of (s, t) space, Duffy-mapped from its apex a so
// that charts that are polar about a (disk centre, sphere pole) are smooth.
double integrate_triangle(const std::function<double(double, double)>& f, double as, double at, double bs, double bt,
                          double cs, double ct) {
  const GaussLegendre& gl = gauss_legendre_64();
  const double jac = std::fabs((bs - as) * (ct - at) - (cs - as) * (bt - at));
  double sum = 0;
  for (int i = 0; i < gl.n; ++i) {
    const double rho = 0.5 * (gl.x[i] + 1);
    for (int j = 0; j < gl.n; ++j) {
      const double sig = 0.5 * (gl.x[j] + 1);
      const double s = as + rho * ((1 - sig) * (bs - as) + sig * (cs - as));
      const double t = at + rho * ((1 - sig) * (bt - at) + sig * (ct - at));
      sum += 0.25 * gl.w[i] * gl.w[j] * rho * jac * f(s, t);
    }
  }
  return sum;
}

double integrate_square(const std::function<double(double, double)>& f) {
  const GaussLegendre& gl = gauss_legendre_64();
  double sum = 0;
  for (int i = 0; i < gl.n; ++i)
    for (int j = 0; j < gl.n; ++j) sum += 0.25 * gl.w[i] * gl.w[j] * f(0.5 * (gl.x[i] + 1), 0.5 * (gl.x[j] + 1));
  return sum;
}

// The integral of the chart's area element over [0,1]^2, split where the chart has kinks.
double chart_area(const Primitive& p, int face) {
  auto f = [&](double s, double t) { return face_point(p, face, s, t).area; };
  const bool disk = (p.shape == Shape::Cylinder && face > 0) || p.shape == Shape::Cone || p.shape == Shape::Paraboloid;
  if (disk) {  // four wedges about the disk centre
    const double c[5][2] = {{1, 0}, {1, 1}, {0, 1}, {0, 0}, {1, 0}};
    double sum = 0;
    for (int k = 0; k < 4; ++k) sum += integrate_triangle(f, 0.5, 0.5, c[k][0], c[k][1], c[k + 1][0], c[k + 1][1]);
    return sum;
  }
  if (p.shape == Shape::Sphere) {  // the octahedron's 8 triangles, each from its pole corner
    double sum = 0;
    for (int q = 0; q < 4; ++q) {
      const double su = (q & 1) ? 1 : -1, sv = (q & 2) ? 1 : -1;  // quadrant signs in (u, v) = 2 (s, t) - 1
      auto st = [](double u) { return 0.5 * (u + 1); };
      sum += integrate_triangle(f, st(0), st(0), st(su), st(0), st(0), st(sv));
      sum += integrate_triangle(f, st(su), st(sv), st(su), st(0), st(0), st(sv));
    }
    return sum;
  }
  return integrate_square(f);
}

struct FaceCase {
  Shape shape;
  int face;
};

const FaceCase kFaces[] = {{Shape::Sphere, 0},     {Shape::Box, 0},      {Shape::Box, 3},        {Shape::Box, 5},
                           {Shape::Cylinder, 0},   {Shape::Cylinder, 1}, {Shape::Cylinder, 2},   {Shape::Cone, 0},
                           {Shape::Cone, 1},       {Shape::Torus, 0},    {Shape::Paraboloid, 0}, {Shape::Paraboloid, 1},
                           {Shape::HalfSpace, 0}};

double periodic_gap(double a, double b) {
  const double d = std::fabs(a - b);
  return std::fmin(d, 1 - d);
}

TEST(CsgLightmapCharts, RoundTripUnderSkewedMap) {
  plm::Rng rng(11, 0);
  const PlaneRect rect{-2.0, 3.0, -1.5, 0.5};
  for (const FaceCase& fc : kFaces) {
    const Primitive p = make_primitive(skewed(fc.shape));
    double worst = 0;
    for (int k = 0; k < 2000; ++k) {
      const double s = 0.001 + 0.998 * next_double(rng), t = 0.001 + 0.998 * next_double(rng);
      const FacePoint fp = face_point(p, fc.face, s, t, rect);
      ASSERT_TRUE(is_finite(fp.p) && is_finite(fp.n) && std::isfinite(fp.area));
      ASSERT_GT(fp.area, 0);
      const FaceCoord back = face_param(p, fc.face, fp.p, rect);
      worst = std::fmax(worst, std::fmax(periodic_gap(back.s, s), periodic_gap(back.t, t)));
      // The chart lands on the face, with the face's normal.
      ASSERT_NE(classify(p, fp.p), Side::Inside) << shape_name(fc.shape);
      if (fc.shape != Shape::HalfSpace) {
        ASSERT_EQ(classify(p, fp.p), Side::Boundary) << shape_name(fc.shape) << " face " << fc.face;
        ASSERT_GT(dot(fp.n, normal(p, fc.face, fp.p)), 1 - 1e-9) << shape_name(fc.shape) << " face " << fc.face;
      }
    }
    EXPECT_LT(worst, 1e-9) << shape_name(fc.shape) << " face " << fc.face;
  }
}

TEST(CsgLightmapCharts, AreaElementIntegratesToFaceArea) {
  for (const FaceCase& fc : kFaces) {
    if (fc.shape == Shape::HalfSpace) continue;
    for (int similar = 0; similar < 2; ++similar) {
      const Primitive p = make_primitive(similar ? prim(fc.shape, {0.7, 0.7, 0.7}, {1, 2, 3}) : skewed(fc.shape));
      const double exact = p.area[fc.face], got = chart_area(p, fc.face);
      EXPECT_NEAR(got / exact, 1.0, 1e-6) << shape_name(fc.shape) << " face " << fc.face << " similar " << similar;
    }
  }
  // The half-space chart: a parallelogram.
  const Primitive h = make_primitive(skewed(Shape::HalfSpace));
  const PlaneRect rect{-2.0, 3.0, -1.5, 0.5};
  const Vec3d e0 = h.to_world.vector({rect.x1 - rect.x0, 0, 0}), e1 = h.to_world.vector({0, rect.y1 - rect.y0, 0});
  EXPECT_NEAR(integrate_square([&](double s, double t) { return face_point(h, 0, s, t, rect).area; }) /
                  length(cross(e0, e1)),
              1.0, 1e-12);
}

// Max/min texel area per chart (unit primitives, about 32 x 32 texels).
TEST(CsgLightmapCharts, TexelAreaRatioIsBounded) {
  for (const FaceCase& fc : kFaces) {
    if (fc.shape == Shape::HalfSpace) continue;
    const CsgObject obj = make({prim(fc.shape, {1, 1, 1}, {0, 0, 0})}, Op::Union);
    const CsgLightmap lm = lightmap(obj, 0.1, 8, false);
    const uint32_t fi = lm.face_index(0, fc.face);
    const CsgLightmap::Face& f = lm.face(fi);
    double lo = 1e300, hi = 0;
    for (uint32_t i = 0; i < f.width * f.height; ++i) {
      const double a = lm.area(lm.texel_first_sub(f.first_texel + i));
      lo = std::fmin(lo, a);
      hi = std::fmax(hi, a);
    }
    const double bound = fc.shape == Shape::Paraboloid && fc.face == 0 ? std::sqrt(5.0)
                         : fc.shape == Shape::Torus                   ? (1 + 0.25) / (1 - 0.25)
                                                                      : 1.0;
    std::printf("chart %-10s face %d: %4u x %-4u texels, max/min texel area %.6f (bound %.4f)\n",
                shape_name(fc.shape), fc.face, f.width, f.height, hi / lo, bound);
    EXPECT_LE(hi / lo, bound * (1 + 1e-9)) << shape_name(fc.shape) << " face " << fc.face;
  }
}

// Sphere radius R minus a cylinder radius r along z through its centre.
CsgObject holed_sphere(double R, double r, double scale = 1, Vec3d at = {0, 0, 0}) {
  return make({prim(Shape::Sphere, Vec3d{R, R, R} * scale, at), prim(Shape::Cylinder, Vec3d{r, r, 2 * R} * scale, at)},
              Op::Difference);
}

double holed_sphere_area(double R, double r) {
  const double h = std::sqrt(R * R - r * r);
  return 4 * kPi * R * h + 4 * kPi * r * h;
}

// The holed sphere under a random rotation, with a random cylinder length
// (which moves the rim, a straight line t = const in the cylinder's chart,
// relative to the texel rows): grid errors of single placements partly
// cancel or alias, so the convergence in g is judged on their mean.
CsgObject placed_holed_sphere(double R, double r, plm::Rng& rng) {
  double q[4], n = 0;
  for (double& c : q) c = 2 * next_double(rng) - 1, n += c * c;
  for (double& c : q) c /= std::sqrt(n);
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  const double rot[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
                            {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
                            {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}};
  const double half = R * (1.2 + 1.3 * next_double(rng));
  auto place = [&](Shape shape, Vec3d s) {
    PrimitiveDesc d;
    d.shape = shape;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) d.to_world[4 * i + j] = rot[i][j] * s[j];
    d.to_world[3] = 0.3;
    d.to_world[7] = -0.1;
    d.to_world[11] = 0.2;
    return d;
  };
  return make({place(Shape::Sphere, {R, R, R}), place(Shape::Cylinder, {r, r, half})}, Op::Difference);
}

TEST(CsgLightmap, SubTexelAreasConvergeToBoundaryArea) {
  const double R = 1, r = 0.4, exact = holed_sphere_area(R, r);
  constexpr int kPlacements = 16;
  double prev = 1e300;
  for (int g : {4, 8, 16}) {
    plm::Rng rng(21, 0);  // the same placements for every g
    double mean = 0, worst = 0;
    CsgLightmapStats st;
    for (int k = 0; k < kPlacements; ++k) {
      const CsgObject obj = placed_holed_sphere(R, r, rng);
      const CsgLightmap lm = lightmap(obj, 0.1, g);
      const double err = std::fabs(total_area(lm) / exact - 1);
      mean += err / kPlacements;
      worst = std::fmax(worst, err);
      st = lm.stats();
      EXPECT_GT(st.cut, 0u);
      EXPECT_EQ(st.uncut + st.cut + st.inert, st.texels);
    }
    std::printf("holed sphere g=%2d: rel. area error mean %.3e max %.3e (%d placements); last: texels %llu uncut %llu "
                "cut %llu inert %llu subs %llu, %.3f s\n",
                g, mean, worst, kPlacements, (unsigned long long)st.texels, (unsigned long long)st.uncut,
                (unsigned long long)st.cut, (unsigned long long)st.inert, (unsigned long long)st.sub_texels,
                st.setup_seconds);
    EXPECT_LT(mean, prev) << "g " << g;
    if (g == 16) {
      EXPECT_LT(worst, 0.01);
    }
    prev = mean;
  }
}

// A sub-texel's cover is its share of its texel (the phantom hit of its error
// estimate is scaled by it): 1 uncut, the cut texel's sub-texels share at most
// the whole texel, each in proportion to its area.
TEST(CsgLightmap, SubTexelsCoverTheirShareOfTheTexel) {
  const CsgObject obj = make({prim(Shape::Box, {1, 1, 1}, {0, 0, 0}), prim(Shape::Sphere, {1.2, 1.2, 1.2}, {0, 0, 0})},
                             Op::Intersection);
  const CsgLightmap lm = lightmap(obj, 0.05, 16);
  ASSERT_GT(lm.stats().cut, 0u);
  double least = 1.0;
  uint32_t checked = 0;
  for (uint32_t texel = 0; texel < lm.texel_count(); ++texel) {
    if (lm.texel_first_sub(texel) == CsgLightmap::kNone) continue;
    const uint32_t first = lm.texel_first_sub(texel), n = lm.texel_sub_count(texel);
    if (!lm.texel_cut(texel)) {
      ASSERT_EQ(lm.cover(first), 1.0);
      continue;
    }
    double sum = 0.0;
    for (uint32_t k = 0; k < n; ++k) {
      const double c = lm.cover(first + k);
      ASSERT_GT(c, 0.0);
      sum += c;
      least = std::min(least, c);
      // area / cover is the whole texel's area, the same for every sub-texel of it
      EXPECT_NEAR(lm.area(first + k) / c, lm.area(first) / lm.cover(first), 1e-9 * lm.area(first) / lm.cover(first));
    }
    EXPECT_LE(sum, 1.0 + 1e-6);
    ++checked;
  }
  EXPECT_GT(checked, 100u);
  EXPECT_LT(least, 0.05);  // slivers: a whole phantom hit would overstate their error 20x and more
}

TEST(CsgLightmap, BoxIntersectSphereArea) {
  // 1 < R < sqrt(2): the sphere cuts a disk of radius sqrt(R^2 - 1) from each
  // face, and its six caps beyond the faces do not overlap.
  const double R = 1.2;
  const double exact = 6 * kPi * (R * R - 1) + 4 * kPi * R * R - 12 * kPi * R * (R - 1);
  const CsgObject obj = make({prim(Shape::Box, {1, 1, 1}, {0, 0, 0}), prim(Shape::Sphere, {R, R, R}, {0, 0, 0})},
                             Op::Intersection);
  const CsgLightmap lm = lightmap(obj, 0.05, 16);
  const double err = std::fabs(total_area(lm) / exact - 1);
  std::printf("box & sphere g=16: rel. area error %.3e\n", err);
  EXPECT_LT(err, 0.01);
}

TEST(CsgLightmap, UncutSphereIsExact) {
  const double R = 1.7;
  const CsgObject obj = make({prim(Shape::Sphere, {R, R, R}, {0.3, -0.2, 5})}, Op::Union);
  const CsgLightmap lm = lightmap(obj, 0.1);
  EXPECT_EQ(lm.stats().cut, 0u);
  EXPECT_EQ(lm.stats().inert, 0u);
  EXPECT_EQ(lm.stats().sub_texels, lm.stats().texels);
  EXPECT_NEAR(total_area(lm) / (4 * kPi * R * R), 1.0, 1e-6);
  // Representative normals point out of the sphere.
  for (uint32_t i = 0; i < lm.sub_texel_count(); ++i)
    ASSERT_GT(dot(lm.normal(i), normalize(lm.point(i) - Vec3d{0.3, -0.2, 5})), 1 - 1e-9);
}

// Box [-1,1]^3 minus a thin slab across the +Z face at x in [0.095, 0.155]
// (inside the texel column [0, 0.25] of an 8 x 8 grid) and a wide slab at
// x in [-0.75, -0.25] (covering two whole texel columns).
TEST(CsgLightmap, GrooveSplitsTexels) {
  const CsgObject obj = make({prim(Shape::Box, {1, 1, 1}, {0, 0, 0}), prim(Shape::Box, {0.03, 2, 0.75}, {0.125, 0, 1.25}),
                              prim(Shape::Box, {0.25, 2, 0.75}, {-0.5, 0, 1.25})},
                             Op::Difference);
  const CsgLightmap lm = lightmap(obj, 0.25);
  const uint32_t top = lm.face_index(0, 5);  // +Z: s along x, t along y
  const CsgLightmap::Face& f = lm.face(top);
  ASSERT_EQ(f.width, 8u);
  ASSERT_EQ(f.height, 8u);
  for (uint32_t y = 0; y < 8; ++y) {
    for (uint32_t x = 0; x < 8; ++x) {
      const uint32_t t = lm.texel_index(top, x, y);
      if (x == 4) {
        EXPECT_EQ(lm.texel_sub_count(t), 2u) << x << "," << y;
        EXPECT_TRUE(lm.texel_cut(t));
      } else if (x == 1 || x == 2) {
        EXPECT_EQ(lm.texel_sub_count(t), 0u) << x << "," << y;  // removed by the wide slab: inert
      } else {
        EXPECT_EQ(lm.texel_sub_count(t), 1u) << x << "," << y;
        EXPECT_FALSE(lm.texel_cut(t));
      }
    }
  }
  // Hits on either side of the thin groove: the same texel, different sub-texels.
  for (double y : {-0.9, -0.3, 0.4, 0.8}) {
    const int64_t left = lm.sub_texel_of_hit(0, 5, {0.05, y, 1}), right = lm.sub_texel_of_hit(0, 5, {0.2, y, 1});
    ASSERT_GE(left, 0);
    ASSERT_GE(right, 0);
    EXPECT_NE(left, right);
    EXPECT_EQ(lm.texel_of_sub(uint32_t(left)), lm.texel_of_sub(uint32_t(right)));
    // The split areas: strips 0.095 and 0.095 wide, 0.25 long.
    EXPECT_NEAR(lm.area(uint32_t(left)), 0.095 * 0.25, 0.25 * 0.25 / 8 + 1e-12);
    EXPECT_NEAR(lm.area(uint32_t(right)), 0.095 * 0.25, 0.25 * 0.25 / 8 + 1e-12);
    // Points sampled on each strip stay on it.
    for (int k = 0; k < 16; ++k) {
      Vec3d p, n;
      lm.sample_point(uint32_t(left), (k + 0.5) / 16, std::fmod(k * 0.618, 1.0), p, n);
      EXPECT_TRUE(obj.on_boundary(0, 5, p));
      EXPECT_LT(p.x, 0.095 + 1e-12);
      EXPECT_NEAR(n.z, 1, 1e-12);
    }
  }
  // Inside the wide groove the removed face has no sub-texel.
  EXPECT_EQ(lm.sub_texel_of_hit(0, 5, {-0.5, 0.3, 1}), -1);
  // The groove's floor and walls are faces of subtracted primitives: normals flipped.
  const int64_t floor = lm.sub_texel_of_hit(2, 4, {-0.5, 0.3, 0.5});
  ASSERT_GE(floor, 0);
  EXPECT_NEAR(lm.normal(uint32_t(floor)).z, 1, 1e-12);
  // The slabs' parts outside the box are inert.
  const uint32_t slab_top = lm.face_index(1, 5);
  for (uint32_t i = 0; i < lm.face(slab_top).width * lm.face(slab_top).height; ++i)
    EXPECT_EQ(lm.texel_sub_count(lm.face(slab_top).first_texel + i), 0u);
  // Total: box 24, minus the two groove openings, plus their walls and floors.
  // Total: the box's 24, plus per groove its two walls (2 x 0.5 deep), minus
  // the notches it leaves in the +-Y faces (the top opening and the floor cancel).
  const double exact = 24 + (2 * 2 * 0.5 - 2 * 0.06 * 0.5) + (2 * 2 * 0.5 - 2 * 0.5 * 0.5);
  EXPECT_NEAR(total_area(lm) / exact, 1.0, 0.01);
}

TEST(CsgLightmap, UnionOfBoxesHasNoInternalFaces) {
  const CsgObject obj =
      make({prim(Shape::Box, {1, 1, 1}, {0, 0, 0}), prim(Shape::Box, {1, 1, 1}, {2, 0, 0})}, Op::Union);
  const CsgLightmap lm = lightmap(obj, 0.2);
  for (const auto& [p, face] : {std::pair<uint32_t, int>{0, 1}, {1, 0}}) {
    const CsgLightmap::Face& f = lm.face(lm.face_index(p, face));
    ASSERT_GT(f.width * f.height, 0u);
    for (uint32_t i = 0; i < f.width * f.height; ++i) EXPECT_EQ(lm.texel_sub_count(f.first_texel + i), 0u);
  }
  EXPECT_EQ(lm.stats().cut, 0u);
  EXPECT_NEAR(total_area(lm), 40.0, 1e-9);
}

TEST(CsgLightmap, TransferFromTessellation) {
  const double R = 1, r = 0.4;
  const CsgObject obj = holed_sphere(R, r);
  const CsgLightmap lm = lightmap(obj, 0.05);
  plm::Rng rng(3, 0);
  int total = 0, right = 0;
  // Exact surface points by sampling the faces, kept where on the boundary.
  while (total < 20000) {
    const uint32_t pi = next_double(rng) < 0.5 ? 0 : 1;
    const Primitive& p = obj.primitive(pi);
    const int face = pi == 0 ? 0 : int(next_double(rng) * 3) % 3;
    FaceSample fs;
    ASSERT_TRUE(sample_face(p, face, rng, fs));
    if (!obj.on_boundary(pi, face, fs.p)) continue;
    const int64_t truth = lm.sub_texel_of_hit(pi, face, fs.p);
    ASSERT_GE(truth, 0);
    const double off = (total & 1) ? 1e-4 : -1e-4;
    // Tessellation normals are not exact: tilt the hint a little.
    const Vec3d hint = normalize(fs.n + Vec3d{0.01, -0.02, 0.015});
    right += lm.lookup(fs.p + fs.n * off, hint, 1e-3) == truth;
    ++total;
  }
  std::printf("transfer: %d of %d points found their sub-texel\n", right, total);
  EXPECT_GT(right, 0.999 * total);
  // Far from the surface: nothing.
  EXPECT_EQ(lm.lookup({0, 0, 0}, {1, 0, 0}, 1e-3), -1);        // the middle of the hole
  EXPECT_EQ(lm.lookup({0, 0, 0.5}, {0, 0, 1}, 1e-2), -1);      // in the hole, along its axis
  EXPECT_EQ(lm.lookup({3, 0, 0}, {1, 0, 0}, 1e-2), -1);        // outside
  EXPECT_EQ(lm.lookup({0.7, 0, 0}, {0, 0, 0}, 1e-2), -1);      // inside the solid, no hint
  EXPECT_GE(lm.lookup({1.0005, 0, 0}, {0, 0, 0}, 1e-3), 0);    // no hint: the axes find the sphere
}

TEST(CsgLightmap, ScaleExtremes) {
  for (double scale : {1e-4, 1e4}) {
    for (Vec3d at : {Vec3d{0, 0, 0}, Vec3d{1e5, -1e5, 1e5}}) {
      const double R = 1.3 * scale;
      const CsgObject sphere = make({prim(Shape::Sphere, {R, R, R}, at)}, Op::Union);
      const CsgLightmap a = lightmap(sphere, 0.1 * scale);
      EXPECT_EQ(a.stats().cut, 0u) << scale;
      EXPECT_EQ(a.stats().inert, 0u) << scale;
      EXPECT_NEAR(total_area(a) / (4 * kPi * R * R), 1.0, 1e-6) << scale << " at " << at.x;

      const CsgObject holed = holed_sphere(1, 0.4, scale, at);
      const CsgLightmap b = lightmap(holed, 0.1 * scale, 16);
      const double area = total_area(b);
      ASSERT_TRUE(std::isfinite(area));
      for (uint32_t i = 0; i < b.sub_texel_count(); ++i) {
        ASSERT_TRUE(is_finite(b.point(i)) && is_finite(b.normal(i)) && std::isfinite(b.area(i)));
        ASSERT_GT(b.area(i), 0);
      }
      EXPECT_NEAR(area / (holed_sphere_area(1, 0.4) * scale * scale), 1.0, 0.01) << scale << " at " << at.x;
      // A hit maps back to its sub-texel.
      const int64_t s = b.sub_texel_of_hit(0, 0, b.point(0));
      EXPECT_EQ(s, 0);
    }
  }
}

TEST(CsgLightmap, SetupCostAgainstPlainLightmap) {
  const CsgObject obj = holed_sphere(1, 0.4);
  const CsgLightmap csg = lightmap(obj, 0.02, 8, true);
  const CsgLightmap plain = lightmap(obj, 0.02, 8, false);
  const CsgLightmapStats &a = csg.stats(), &b = plain.stats();
  std::printf("set-up, holed sphere, texel 0.02, g=8: CSG-aware %.3f s %.2f MiB (%llu texels: %llu uncut, %llu cut, "
              "%llu inert; %llu sub-texels); plain %.3f s %.2f MiB\n",
              a.setup_seconds, a.bytes / 1048576.0, (unsigned long long)a.texels, (unsigned long long)a.uncut,
              (unsigned long long)a.cut, (unsigned long long)a.inert, (unsigned long long)a.sub_texels, b.setup_seconds,
              b.bytes / 1048576.0);
  EXPECT_EQ(a.texels, b.texels);
  EXPECT_EQ(b.sub_texels, b.texels);
  EXPECT_GT(a.inert, 0u);
}

TEST(CsgLightmap, SettingsAreValidated) {
  const CsgObject obj = holed_sphere(1, 0.4);
  CsgLightmapSettings s;
  s.texel_size = 0;
  EXPECT_THROW(CsgLightmap(obj, s), plm::Error);
  s.texel_size = 0.1;
  s.grid = 1;
  EXPECT_THROW(CsgLightmap(obj, s), plm::Error);
  s.grid = 64;
  EXPECT_THROW(CsgLightmap(obj, s), plm::Error);
  s.grid = 8;
  s.texel_size = 1e-9;  // clamped to 1024 per side: fine
  s.max_resolution = 16;
  EXPECT_NO_THROW(CsgLightmap(obj, s));
}

TEST(CsgLightmap, HalfSpaceCutsOverObjectBounds) {
  // A sphere cut by the plane z = 0.3 (keep below): the plane's chart covers
  // the sphere's bounds; the disk it leaves has area pi (R^2 - 0.09).
  const double R = 1;
  const CsgObject obj =
      make({prim(Shape::Sphere, {R, R, R}, {0, 0, 0}), prim(Shape::HalfSpace, {1, 1, 1}, {0, 0, 0.3})},
           Op::Intersection);
  const CsgLightmap lm = lightmap(obj, 0.05, 16);
  const uint32_t fi = lm.face_index(1, 0);
  const CsgLightmap::Face& f = lm.face(fi);
  ASSERT_GT(f.width * f.height, 0u);
  double disk = 0;
  for (uint32_t i = 0; i < f.width * f.height; ++i) {
    const uint32_t t = f.first_texel + i;
    for (uint32_t k = 0; k < lm.texel_sub_count(t); ++k) disk += lm.area(lm.texel_first_sub(t) + k);
  }
  EXPECT_NEAR(disk / (kPi * (R * R - 0.09)), 1.0, 0.01);
  const double cap = 2 * kPi * R * (R + 0.3);  // the sphere below z = 0.3
  EXPECT_NEAR(total_area(lm) / (cap + kPi * (R * R - 0.09)), 1.0, 0.01);
}

}  // namespace

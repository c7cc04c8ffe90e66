#include "ol/area_estimation.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>

#include "util/error.h"

namespace plm::ol {
namespace {

// Within k standard errors of the truth, plus rounding where the error is 0.
::testing::AssertionResult within_se(double est, double truth, double se, double k = 4.0) {
  const double tol = k * se + 1e-9 * std::fabs(truth);
  if (std::fabs(est - truth) <= tol) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "estimate " << est << ", truth " << truth << ", standard error " << se
                                       << " (" << (est - truth) / se << " sigma)";
}

Affine3d rotate_x_then_move(double angle, Vec3d t) {
  const double c = std::cos(angle), s = std::sin(angle);
  const double m[12] = {1, 0, 0, t.x, 0, c, -s, t.y, 0, s, c, t.z};
  return Affine3d::from_array(m);
}

// Sphereflake: a sphere with 9 children of a third of its radius touching it,
// 6 around its equator and 3 above, recursively ([Thesis §8.2], level 4 = 7381 spheres).
void sphereflake(Vec3d c, double r, Vec3d axis, int level, std::vector<Patch>& out) {
  out.push_back(Patch::sphere(c, r));
  if (level == 0) return;
  Vec3 tf, bf;
  make_frame(to_float(axis), tf, bf);
  const Vec3d t = to_double(tf), b = to_double(bf);
  for (int k = 0; k < 9; ++k) {
    const double elev = k < 6 ? 0.0 : kPiD / 3.0;
    const double az = k < 6 ? k * kPiD / 3.0 : kPiD / 6.0 + (k - 6) * 2.0 * kPiD / 3.0;
    const Vec3d dir =
        normalize(t * (std::cos(elev) * std::cos(az)) + b * (std::cos(elev) * std::sin(az)) + axis * std::sin(elev));
    sphereflake(c + dir * (r * 4.0 / 3.0), r / 3.0, dir, level - 1, out);
  }
}

// Sierpinski tetrahedron: 4^level tetrahedra, each face one triangle wound outwards.
void sierpinski(const Vec3d v[4], int level, std::vector<Patch>& out) {
  if (level == 0) {
    const Vec3d centre = (v[0] + v[1] + v[2] + v[3]) * 0.25;
    for (int skip = 0; skip < 4; ++skip) {
      Vec3d f[3];
      for (int i = 0, k = 0; i < 4; ++i)
        if (i != skip) f[k++] = v[i];
      if (dot(cross(f[1] - f[0], f[2] - f[0]), f[0] - centre) < 0) std::swap(f[1], f[2]);
      out.push_back(Patch::triangle(f[0], f[1], f[2]));
    }
    return;
  }
  for (int corner = 0; corner < 4; ++corner) {
    Vec3d sub[4];
    for (int i = 0; i < 4; ++i) sub[i] = (v[corner] + v[i]) * 0.5;
    sierpinski(sub, level - 1, out);
  }
}

TEST(OlArea, SphereTotalAndPerBinArea) {
  const OctGrid grid(8);
  const double r = 2.0;
  AreaSettings s;
  s.samples = 1000000;
  const AreaEstimate e = estimate_area(grid, {Patch::sphere({0.3, -0.2, 0.5}, r)}, s);
  EXPECT_TRUE(within_se(e.total, 4.0 * kPiD * r * r, e.total_error()));
  // Every normal occurs once on a sphere: bin area = r^2 * bin solid angle.
  double z2 = 0.0;
  for (uint32_t b = 0; b < grid.bins(); ++b) {
    const double truth = r * r * grid.solid_angle(b);
    EXPECT_TRUE(within_se(e.area[b], truth, e.error(b))) << "bin " << b;
    z2 += (e.area[b] - truth) * (e.area[b] - truth) / e.variance[b];
  }
  // The reported errors are the real ones: mean squared z-score near 1.
  RecordProperty("sphere_bin_mean_z2", std::to_string(z2 / grid.bins()));
  EXPECT_GT(z2 / grid.bins(), 0.5);
  EXPECT_LT(z2 / grid.bins(), 1.6);
  RecordProperty("sphere_total_rel_error", std::to_string(e.total_error() / e.total));
}

TEST(OlArea, TorusTotalAndErrorFallsAsOneOverSqrtN) {
  const OctGrid grid(16);
  const Patch torus = Patch::torus(1.0, 0.25, rotate_x_then_move(0.7, {1, 2, 3}));
  const double truth = 4.0 * kPiD * kPiD * 1.0 * 0.25;
  AreaSettings s;
  s.samples = 200000;
  const AreaEstimate e = estimate_area(grid, {torus}, s);
  EXPECT_TRUE(within_se(e.total, truth, e.total_error()));
  // Measured RMS error over independent seeds at n and 16 n: ratio ~ 4.
  double sq[2] = {0, 0}, se[2] = {0, 0};
  const uint64_t n[2] = {2000, 32000};
  const int seeds = 48;
  for (int k = 0; k < 2; ++k)
    for (int seed = 0; seed < seeds; ++seed) {
      s.samples = n[k];
      s.seed = 100 + seed;
      const AreaEstimate ek = estimate_area(grid, {torus}, s);
      sq[k] += (ek.total - truth) * (ek.total - truth);
      se[k] += ek.total_error();
    }
  const double rms_ratio = std::sqrt(sq[0] / sq[1]), se_ratio = se[0] / se[1];
  EXPECT_GT(rms_ratio, 2.6);
  EXPECT_LT(rms_ratio, 6.0);
  EXPECT_NEAR(se_ratio, 4.0, 0.2);
  RecordProperty("torus_rms_ratio", std::to_string(rms_ratio));
}

TEST(OlArea, SphereflakeLevel4) {
  std::vector<Patch> parts;
  sphereflake({0, 0, 0}, 1.0, {0, 0, 1}, 4, parts);
  ASSERT_EQ(parts.size(), 7381u);
  // Level l has 9^l spheres of radius 3^-l: each level adds 4 pi.
  const double truth = 5 * 4.0 * kPiD;
  const OctGrid grid(16);
  AreaSettings s;
  s.samples = 4000000;
  const AreaEstimate big = estimate_area(grid, parts, s);
  EXPECT_TRUE(within_se(big.total, truth, big.total_error()));
  s.samples = 250000;
  const AreaEstimate small = estimate_area(grid, parts, s);
  EXPECT_TRUE(within_se(small.total, truth, small.total_error()));
  // 16x the samples, a quarter of the error (heavy tailed: the root sphere is
  // a fifth of the area but one part in 7381, so allow some slack).
  EXPECT_NEAR(small.total_error() / big.total_error(), 4.0, 0.6);
  RecordProperty("sphereflake_rel_error_4M", std::to_string(big.total_error() / truth));
}

TEST(OlArea, SierpinskiTetrahedron) {
  const Vec3d v[4] = {{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}};
  const double edge = std::sqrt(8.0);
  const int level = 5;
  std::vector<Patch> parts;
  sierpinski(v, level, parts);
  ASSERT_EQ(parts.size(), 4u * 1024u);
  // 4^k tetrahedra of edge L / 2^k, touching at corners only: sqrt(3) L^2 at every level.
  const double truth = std::sqrt(3.0) * edge * edge;
  const OctGrid grid(8);
  const AreaEstimate exact = estimate_area(grid, parts);  // triangles are exact by default
  EXPECT_NEAR(exact.total, truth, 1e-12 * truth);
  EXPECT_EQ(exact.samples, 0u);
  // All tetrahedra face the same four ways: four bins of a quarter each.
  int nonzero = 0;
  for (uint32_t b = 0; b < grid.bins(); ++b)
    if (exact.area[b] > 0) {
      ++nonzero;
      EXPECT_NEAR(exact.area[b], truth / 4, 1e-12 * truth);
    }
  EXPECT_EQ(nonzero, 4);

  // The sampled path: equal parts make the total exact; bins are binomial.
  AreaSettings s;
  s.exact_triangles = false;
  double se[2];
  const uint64_t n[2] = {20000, 320000};
  for (int k = 0; k < 2; ++k) {
    s.samples = n[k];
    const AreaEstimate e = estimate_area(grid, parts, s);
    EXPECT_NEAR(e.total, truth, 1e-9 * truth);
    se[k] = 0.0;
    for (uint32_t b = 0; b < grid.bins(); ++b)
      if (exact.area[b] > 0) {
        EXPECT_TRUE(within_se(e.area[b], truth / 4, e.error(b)));
        se[k] += e.error(b);
      } else {
        EXPECT_EQ(e.area[b], 0.0);
      }
  }
  EXPECT_NEAR(se[0] / se[1], 4.0, 0.1);
}

TEST(OlArea, TrimmedCustomPatch) {
  // A sphere given as a custom patch, trimmed to its upper half by keep().
  const double r = 1.5;
  const SurfaceEval eval = [r](double th, double ph, SurfacePoint& o) {
    const double st = std::sin(th), ct = std::cos(th), sp = std::sin(ph), cp = std::cos(ph);
    o.p = Vec3d{st * cp, st * sp, ct} * r;
    o.dpdu = Vec3d{ct * cp, ct * sp, -st} * r;
    o.dpdv = Vec3d{-st * sp, st * cp, 0.0} * r;
  };
  const Patch half = Patch::custom(0, kPiD, 0, 2 * kPiD, eval, [](Vec3d p) { return p.z > 0; });
  const OctGrid grid(8);
  AreaSettings s;
  s.samples = 400000;
  const AreaEstimate e = estimate_area(grid, {half}, s);
  EXPECT_TRUE(within_se(e.total, 2 * kPiD * r * r, e.total_error()));
  for (uint32_t b = 0; b < grid.bins(); ++b) {
    if (grid.centre(b).z < -0.3) {
      EXPECT_EQ(e.area[b], 0.0) << "bin " << b;
    }
  }
}

TEST(OlArea, DeterministicAndIndependentOfThreads) {
  std::vector<Patch> parts;
  sphereflake({0, 0, 0}, 1.0, {0, 0, 1}, 2, parts);
  parts.push_back(Patch::torus(1.0, 0.25));
  const OctGrid grid(16);
  AreaSettings s;
  s.samples = 300001;  // not a multiple of the block size
  AreaEstimate one, many;
  {
    tbb::global_control only(tbb::global_control::max_allowed_parallelism, 1);
    one = estimate_area(grid, parts, s);
  }
  many = estimate_area(grid, parts, s);
  EXPECT_EQ(one.total, many.total);
  EXPECT_EQ(one.area, many.area);
  EXPECT_EQ(one.variance, many.variance);
  s.seed = 2;
  EXPECT_NE(estimate_area(grid, parts, s).total, one.total);
}

TEST(OlArea, RejectsBadParts) {
  const OctGrid grid(4);
  const auto message = [&](const std::vector<Patch>& parts, uint64_t samples) -> std::string {
    AreaSettings s;
    s.samples = samples;
    try {
      estimate_area(grid, parts, s);
    } catch (const Error& e) {
      EXPECT_EQ(e.status(), PLM_ERROR_INVALID_ARGUMENT);
      return e.what();
    }
    return "no error";
  };
  EXPECT_NE(message({}, 10).find("no parts"), std::string::npos);
  EXPECT_NE(message({Patch::sphere({0, 0, 0}, 0.0)}, 10).find("part 0: sphere"), std::string::npos);
  EXPECT_NE(message({Patch::sphere({0, 0, 0}, 1.0), Patch::torus(1, -1)}, 10).find("part 1: torus"),
            std::string::npos);
  EXPECT_NE(message({Patch::triangle({0, 0, NAN}, {1, 0, 0}, {0, 1, 0})}, 10).find("not finite"), std::string::npos);
  EXPECT_NE(message({Patch::custom(0, 1, 0, 1, {})}, 10).find("no eval"), std::string::npos);
  EXPECT_NE(message({Patch::sphere({0, 0, 0}, 1.0)}, 0).find("samples must be > 0"), std::string::npos);
  // Only exact triangles: no samples needed.
  EXPECT_EQ(message({Patch::triangle({0, 0, 0}, {1, 0, 0}, {0, 1, 0})}, 0), "no error");
}

}  // namespace
}  // namespace plm::ol

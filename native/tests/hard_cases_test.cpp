// Hard cases: grazing angles, extreme scales, degenerate and sliver
// triangles, texels much smaller or much larger than triangles, albedo near 1,
// lights inside geometry, overlapping UVs, many lights, tiny scenes, and bad
// input through the C API. Every case states its expected answer and its
// tolerance and checks the engine against truth (an analytic value or exact
// conservation), never against another run of the engine.
// docs/robustness.md lists every case with its measured result.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "demo_scenes.h"
#include "test_support.h"

namespace {

using plm_demo::SceneBuilder;
using plm_demo::V3;
using plm_test::bake;
using plm_test::BakeResult;
using plm_test::Map;

// ---- small helpers (this file only) ----------------------------------------

// The two ways a bake computes direct light: the default direct pass (shadow
// rays from points inside each texel, photons add the indirect part, pooled
// over up to filter_radius texels), and photons alone, unfiltered
// (direct_samples = 0, filter_radius = 0): the raw photon-lightmap estimator,
// whose per-texel answer is exact in expectation. Value cases run in both.
enum class Mode { DirectPass, PhotonsOnly };
const Mode kModes[] = {Mode::DirectPass, Mode::PhotonsOnly};
const char* name(Mode m) { return m == Mode::DirectPass ? "direct pass" : "photons only"; }

// Texel averages: the hard cases' exact answers (and conservation of flux)
// are averages over texels; texel-centre values are tested in bake_test.cpp.
plm_bake_settings settings(uint64_t photons, uint32_t max_bounces = 1024, Mode mode = Mode::DirectPass) {
  plm_bake_settings s;
  plm_bake_settings_default(&s);
  s.texel_value = PLM_TEXEL_AREA;
  s.photon_count = photons;
  s.max_bounces = max_bounces;
  if (mode == Mode::PhotonsOnly) {
    s.direct_samples = 0;
    s.filter_radius = 0;
  }
  return s;
}

// A sun of strength S shining from zenith angle theta, coming from the +y side
// (it travels along (0, -sin, -cos)); angle 0: a perfectly parallel sun.
plm_light sun(float strength, double theta) {
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_SUN);
  l.power = strength;
  l.angle = 0.0f;
  const float c = float(std::cos(theta)), s = float(std::sin(theta));
  // Row-major; the local z axis (against the light) maps to (0, sin, cos).
  l.matrix[5] = c;
  l.matrix[6] = s;
  l.matrix[9] = -s;
  l.matrix[10] = c;
  return l;
}

plm_light point(float watts, V3 at) {
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_POINT);
  l.power = watts;
  l.radius = 0.0f;
  l.matrix[3] = at.x;
  l.matrix[7] = at.y;
  l.matrix[11] = at.z;
  return l;
}

// Agreement with a constant exact value over the texels with coverage >= min_cov:
// the mean deviation in units of the standard error of the mean, the worst
// texel's deviation in units of its own reported error, and the worst
// relative deviation.
struct Agreement {
  int texels = 0;
  double mean = 0, mean_z = 0, max_z = 0, max_rel = 0;
};

template <typename Exact>
Agreement agree(const Map& m, Exact exact, float min_cov = 0.999f) {
  Agreement a;
  double sum_dev = 0, sum_var = 0, sum = 0;
  for (size_t t = 0; t < m.coverage.size(); ++t) {
    if (m.coverage[t] < min_cov) continue;
    const double e = exact(t), v = m.value(t), dev = v - e;
    // A noiseless estimate (an unoccluded sun in the direct pass) reports
    // error 0; float rounding of 1e-5 relative is then no deviation.
    const double err = std::max(double(m.error[t]), 1e-5 * std::fabs(e) + 1e-30);
    ++a.texels;
    sum += v;
    sum_dev += dev;
    sum_var += err * err;
    a.max_z = std::max(a.max_z, std::fabs(dev) / err);
    a.max_rel = std::max(a.max_rel, std::fabs(dev) / e);
  }
  a.mean = sum / std::max(1, a.texels);
  a.mean_z = sum_dev / std::sqrt(sum_var);
  return a;
}

Agreement agree_const(const Map& m, double exact, float min_cov = 0.999f) {
  return agree(
      m, [&](size_t) { return exact; }, min_cov);
}

// Flux recorded on a lightmap: sum of value * pi * world area, the world area of
// a texel being its coverage times the world area of a whole texel.
double recorded_flux(const Map& m, double texel_world_area) {
  double sum = 0.0;
  for (size_t t = 0; t < m.coverage.size(); ++t)
    if (m.coverage[t] > 0) sum += m.value(t) * M_PI * m.coverage[t] * texel_world_area;
  return sum;
}

// Irradiance / pi of a point light of power P at height h, averaged over the
// texel [x0, x0 + dx] x [y0, y0 + dy] of a plane below it (16 x 16 midpoint rule).
double point_over_plane(double P, double h, double x0, double y0, double dx, double dy) {
  double avg = 0.0;
  const int k = 16;
  for (int a = 0; a < k; ++a)
    for (int c = 0; c < k; ++c) {
      const double x = x0 + (a + 0.5) / k * dx, y = y0 + (c + 0.5) / k * dy, d2 = x * x + y * y + h * h;
      avg += P / (4 * M_PI) * h / std::pow(d2, 1.5) / M_PI;
    }
  return avg / (k * k);
}

// Standard error of recorded_flux: the texels' errors added in quadrature.
double flux_error(const Map& m, double texel_world_area) {
  double var = 0.0;
  for (size_t t = 0; t < m.coverage.size(); ++t)
    if (m.coverage[t] > 0) {
      const double e = double(m.error[t]) * M_PI * m.coverage[t] * texel_world_area;
      var += e * e;
    }
  return std::sqrt(var);
}

// Measured numbers for docs/robustness.md are printed as "[ measured ] ..." lines.
std::string test_name() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  return info ? info->name() : "";
}
// exact 0: a per-texel analytic value, not one constant.
void report(const char* mode, const Agreement& a, double exact) {
  if (exact == 0.0) {
    std::printf("[ measured ] %s (%s): %d texels, mean dev %+.2g sigma, worst %.3g sigma, worst %.3g%%\n",
                test_name().c_str(), mode, a.texels, a.mean_z, a.max_z, 100.0 * a.max_rel);
    return;
  }
  std::printf("[ measured ] %s (%s): %d texels, mean %.6g (exact %.6g, %+.2g sigma), worst %.3g sigma, worst %.3g%%\n",
              test_name().c_str(), mode, a.texels, a.mean, exact, a.mean_z, a.max_z, 100.0 * a.max_rel);
}

bool contains(const std::string& s, const char* needle) { return s.find(needle) != std::string::npos; }

// ---- self-intersection at grazing angles -----------------------------------

// A white (albedo 0.8) plane alone under a sun 89.5 degrees from the zenith:
// every texel is S cos(89.5 deg) / pi, nothing else (light reflected by a plane
// can hit nothing). Tolerance: worst texel within 5 reported errors, the mean
// within 4 standard errors of the mean, every texel within 15%. A ray that hit
// its own surface again would add bright texels; a ray starting below the
// surface would leave dark ones.
TEST(HardCases, GrazingSunOverPlaneHasNoSpeckles) {
  for (const Mode mode : kModes) {
    SCOPED_TRACE(name(mode));
    SceneBuilder b;
    const uint32_t white = b.material("white", {0.8f, 0.8f, 0.8f});
    b.quad("plane", {-10, -10, 0}, {20, 0, 0}, {0, 20, 0}, white, 4);
    const double theta = 89.5 * M_PI / 180.0, S = 100.0;
    b.light(sun(float(S), theta), "sun");
    BakeResult r;
    bake(b, settings(2000000, 1024, mode), r);
    const double exact = S * std::cos(theta) / M_PI;
    const Agreement a = agree_const(r.map(0), exact);
    report(name(mode), a, exact);
    EXPECT_EQ(a.texels, 16);
    EXPECT_LT(a.max_z, 5.0) << "mean " << a.mean << " exact " << exact;
    EXPECT_LT(std::fabs(a.mean_z), 4.0) << "mean " << a.mean << " exact " << exact;
    EXPECT_LT(a.max_rel, 0.15);
  }
}

// A convex white box (outward faces, albedo 0.8) under a sun 89.5 degrees from
// the zenith, coming from +y. Light reflected off a convex body never reaches
// it again, so each face shows exactly S cos(angle to its normal) / pi: the +y
// face S cos(0.5 deg) / pi, the top S cos(89.5 deg) / pi, the faces turned
// away 0 exactly, and the +-x faces (parallel to the sun) 0 exactly.
// Tolerance: lit faces within 5 reported errors per texel and 5% (top) / 1%
// (+y); dark faces 0 up to a few photons: the faces' UV islands touch, and
// a UV edge such as 4/6 rounds a few 1e-7 of a texel into the neighbouring
// island, so now and then a photon on the edge of the lit +y face lands in
// the dark -y face's texel (one photon: 1.5e-5 against 3.18 lit). Seed 12
// failed the earlier "exactly 0"; the default seed happened to miss the edge.
TEST(HardCases, BoxFacesUnderGrazingSunAreExact) {
  for (const Mode mode : kModes) {
    SCOPED_TRACE(name(mode));
    SceneBuilder b;
    const uint32_t white = b.material("white", {0.8f, 0.8f, 0.8f});
    const uint32_t r_face = 2;  // 2 x 2 texels per face, atlas 6 x 4
    b.box("box", {0, 0, 0}, {2, 2, 2}, 0.0f, white, r_face);
    const double theta = 89.5 * M_PI / 180.0, S = 10.0;
    b.light(sun(float(S), theta), "sun");
    BakeResult r;
    bake(b, settings(2000000, 1024, mode), r);
    const Map m = r.map(0);
    // Faces in atlas order: +z, -z, +x, -x, +y, -y; face f in cell (f % 3, f / 3).
    const double exact[6] = {S * std::cos(theta) / M_PI, 0, 0, 0, S * std::sin(theta) / M_PI, 0};
    const double rel_tol[6] = {0.05, 0, 0, 0, 0.01, 0};
    for (int f = 0; f < 6; ++f) {
      for (uint32_t j = 0; j < r_face; ++j)
        for (uint32_t i = 0; i < r_face; ++i) {
          const size_t t = size_t((f / 3) * r_face + j) * m.w + (f % 3) * r_face + i;
          if (exact[f] == 0) {
            EXPECT_LT(m.value(t), 1e-5 * exact[4]) << "face " << f << " texel " << i << "," << j;
            continue;
          }
          EXPECT_NEAR(m.value(t), exact[f], rel_tol[f] * exact[f]) << "face " << f << " texel " << i << "," << j;
          EXPECT_LT(std::fabs(m.value(t) - exact[f]), 5.0 * std::max(double(m.error[t]), 1e-5 * exact[f]))
              << "face " << f;
        }
    }
  }
}

// ---- extreme scales: exact conservation in a closed black box --------------

// A closed black box (inward faces, albedo 0) around a light. Photons only:
// every photon is absorbed at its first hit, so the recorded flux is the
// light's flux exactly (point: P; area: pi P / 4) and every emitted photon is
// recorded once; tolerance 1e-4 relative (float sums), photon_hits ==
// photon_count. Direct pass: the same flux within 4 standard errors of the
// recorded flux (texel errors added in quadrature) plus 1e-4.
void expect_black_box_conserves(V3 center, float size, const plm_light& light, double flux, int lights = 1) {
  for (const Mode mode : kModes) {
    SCOPED_TRACE(name(mode));
    SceneBuilder b;
    const uint32_t black = b.material("black", {0, 0, 0});
    const uint32_t face_res = 8;  // one-texel margin: 6 x 6 covered texels per face
    b.box("closed", center, {size, size, size}, 0.0f, black, face_res, true);
    for (int i = 0; i < lights; ++i) {
      plm_light l = light;  // lights > 1: a 10 x 10 x 10 grid filling 90% of the box
      if (lights > 1) {
        const float step = 0.9f * size / 9.0f;
        l.matrix[3] = center.x - 0.45f * size + step * float(i % 10);
        l.matrix[7] = center.y - 0.45f * size + step * float((i / 10) % 10);
        l.matrix[11] = center.z - 0.45f * size + step * float(i / 100);
      }
      b.light(l, "light");
    }
    BakeResult r;
    const uint64_t photons = 100000;
    bake(b, settings(photons, 1024, mode), r);
    const double texel_area = double(size) * size / 36.0;
    const Map m = r.map(0);
    const double got = recorded_flux(m, texel_area);
    std::printf("[ measured ] %s (%s) size %g at %g: flux %.7g (exact %.7g, sigma %.3g), hits %llu\n",
                test_name().c_str(), name(mode), double(size), double(center.x), got, flux, flux_error(m, texel_area),
                (unsigned long long)r.stats().photon_hits);
    if (mode == Mode::PhotonsOnly) {
      EXPECT_NEAR(got, flux, 1e-4 * flux) << "size " << size << " at " << center.x;
      EXPECT_EQ(r.stats().photon_hits, photons) << "size " << size << " at " << center.x;
    } else {
      EXPECT_NEAR(got, flux, 4.0 * flux_error(m, texel_area) + 1e-4 * flux) << "size " << size << " at " << center.x;
    }
  }
}

plm_light area_light(float watts, V3 at, float sx, float sy) {
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_AREA_RECT);
  l.power = watts;
  l.size_x = sx;
  l.size_y = sy;
  l.matrix[3] = at.x;
  l.matrix[7] = at.y;
  l.matrix[11] = at.z;
  return l;
}

TEST(HardCases, TinySceneConservesFlux) {
  const float s = 1e-4f;
  expect_black_box_conserves({0, 0, 0}, s, point(100, {0, 0, 0}), 100.0);
  expect_black_box_conserves({0, 0, 0}, s, area_light(100, {0, 0, 0.25f * s}, 0.3f * s, 0.2f * s), 25.0 * M_PI);
}

TEST(HardCases, HugeSceneConservesFlux) {
  const float s = 1e4f;
  expect_black_box_conserves({0, 0, 0}, s, point(100, {0, 0, 0}), 100.0);
  expect_black_box_conserves({0, 0, 0}, s, area_light(100, {0, 0, 0.25f * s}, 0.3f * s, 0.2f * s), 25.0 * M_PI);
}

TEST(HardCases, SceneFarFromOriginConservesFlux) {
  const V3 c{1e5f, -1e5f, 1e5f};
  expect_black_box_conserves(c, 20.0f, point(100, c), 100.0);
  expect_black_box_conserves(c, 20.0f, area_light(100, {c.x, c.y, c.z + 5.0f}, 6.0f, 4.0f), 25.0 * M_PI);
}

// ---- sliver and degenerate triangles ---------------------------------------

// A 1 x 1 m quad (two triangles) plus three zero-area triangles (two
// collinear, one with a repeated vertex) in one mesh under a sun at the
// zenith: it bakes, warns "3 degenerate ... (first: triangle 1)", and every
// texel is S / pi. Tolerance: 5 reported errors per texel, 3% per texel.
TEST(HardCases, DegenerateTrianglesAreSkippedAndReported) {
  for (const Mode mode : kModes) {
    SCOPED_TRACE(name(mode));
    SceneBuilder b;
    const float pos[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0.5f, 0, 0, 0.25f, 0, 0};
    const uint32_t idx[] = {0, 1, 2,   // quad, first half
                            0, 4, 1,   // collinear: degenerate
                            0, 2, 3,   // quad, second half
                            4, 4, 2,   // repeated vertex: degenerate
                            5, 4, 1};  // collinear: degenerate
    const float uv[] = {0, 0, 1, 0,    1, 1,    0, 0, 0.5f, 0,     1, 0,    0, 0, 1,
                        1, 0, 1, 0.5f, 0, 0.5f, 0, 1, 1,    0.25f, 0, 0.5f, 0, 1, 0};
    ASSERT_EQ(plm_scene_add_mesh(b.scene, "quad", pos, 6, idx, 5, uv, nullptr, 4, 4, nullptr), PLM_OK)
        << plm_last_error();
    const double S = 2.0;
    b.light(sun(float(S), 0.0), "sun");
    BakeResult r;
    bake(b, settings(400000, 1024, mode), r);
    const std::string w = r.warning("degenerate");
    EXPECT_TRUE(contains(w, "mesh 'quad'")) << r.all_warnings();
    EXPECT_TRUE(contains(w, "3 degenerate")) << w;
    EXPECT_TRUE(contains(w, "triangle 1")) << w;
    const Agreement a = agree_const(r.map(0), S / M_PI);
    report(name(mode), a, S / M_PI);
    EXPECT_EQ(a.texels, 16);
    EXPECT_LT(a.max_z, 5.0);
    EXPECT_LT(a.max_rel, 0.03);
  }
}

// A 1 x 1 m quad made of 4000 sliver triangles (a fan from one corner, edges
// 1/2000 m apart, aspect ratios up to 2800) with a 4 x 4 lightmap under a sun
// 30 degrees from the zenith: every texel S cos(30) / pi, as for two
// triangles. Tolerance: 5 reported errors per texel, 3%; no warnings.
TEST(HardCases, SliverFanBakesLikeAQuad) {
  for (const Mode mode : kModes) {
    SCOPED_TRACE(name(mode));
    const uint32_t n = 2000;
    std::vector<float> pos = {0, 0, 0};
    std::vector<float> uv;
    std::vector<uint32_t> idx;
    // Rim: along y = 1 from x = 0 to 1, then along x = 1 from y = 1 down to 0.
    for (uint32_t i = 0; i <= 2 * n; ++i) {
      const float x = i <= n ? float(i) / n : 1.0f, y = i <= n ? 1.0f : 1.0f - float(i - n) / n;
      pos.insert(pos.end(), {x, y, 0});
    }
    for (uint32_t i = 0; i < 2 * n; ++i) {
      // Counter-clockwise seen from +z: corner, then rim i + 1, then rim i.
      idx.insert(idx.end(), {0, i + 2, i + 1});
      const float* p1 = &pos[3 * (i + 2)];
      const float* p2 = &pos[3 * (i + 1)];
      uv.insert(uv.end(), {0, 0, p1[0], p1[1], p2[0], p2[1]});
    }
    SceneBuilder b;
    ASSERT_EQ(plm_scene_add_mesh(b.scene, "fan", pos.data(), uint32_t(pos.size() / 3), idx.data(),
                                 uint32_t(idx.size() / 3), uv.data(), nullptr, 4, 4, nullptr),
              PLM_OK)
        << plm_last_error();
    const double S = 2.0, theta = M_PI / 6;
    b.light(sun(float(S), theta), "sun");
    BakeResult r;
    bake(b, settings(400000, 1024, mode), r);
    EXPECT_EQ(plm_result_warning_count(r.r), 0u) << r.all_warnings();
    const Agreement a = agree_const(r.map(0), S * std::cos(theta) / M_PI);
    report(name(mode), a, S * std::cos(theta) / M_PI);
    EXPECT_EQ(a.texels, 16);
    EXPECT_LT(a.max_z, 5.0);
    EXPECT_LT(a.max_rel, 0.03);
  }
}

// ---- texels and triangles of very different sizes ---------------------------

// One triangle whose UVs cover half of a 512 x 512 lightmap (130,816 whole
// texels) under a sun 30 degrees from the zenith, with only ~16 photon hits
// per texel: every texel is S cos(30) / pi within noise. With ~16 hits a
// texel's own error estimate is itself noisy (a texel with 2 hits would claim
// z = 9), so deviations are measured in units of the RMS reported error s.
// Tolerance: the mean within 4 s / sqrt(n) of exact (about 0.1%), no texel
// beyond 7 s (Poisson tails reach ~5 s in 131k texels), and the reported
// errors calibrated: RMS of the deviations / s in [0.9, 1.1].
TEST(HardCases, TexelsFarSmallerThanTheTriangle) {
  for (const Mode mode : kModes) {
    SCOPED_TRACE(name(mode));
    SceneBuilder b;
    const float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint32_t idx[] = {0, 1, 2};
    const float uv[] = {0, 0, 1, 0, 0, 1};
    ASSERT_EQ(plm_scene_add_mesh(b.scene, "tri", pos, 3, idx, 1, uv, nullptr, 512, 512, nullptr), PLM_OK);
    const double S = 2.0, theta = M_PI / 6, exact = S * std::cos(theta) / M_PI;
    b.light(sun(float(S), theta), "sun");
    BakeResult r;
    bake(b, settings(8000000, 0, mode), r);
    const Map m = r.map(0);
    double n = 0, sum_dev = 0, sum_dev2 = 0, sum_err2 = 0, max_dev = 0;
    for (size_t t = 0; t < m.coverage.size(); ++t) {
      if (m.coverage[t] < 0.999f) continue;
      const double dev = m.value(t) - exact;
      n += 1;
      sum_dev += dev;
      sum_dev2 += dev * dev;
      sum_err2 += double(m.error[t]) * m.error[t];
      max_dev = std::max(max_dev, std::fabs(dev));
    }
    EXPECT_EQ(n, 512 * 511 / 2);
    std::printf("[ measured ] %s (%s): mean %.6g (exact %.6g), %+.2g s/sqrt(n), worst %.3g s, rms %.3g s, s = %.3g%%\n",
                test_name().c_str(), name(mode), exact + sum_dev / n, exact,
                sum_dev / n / (std::max(std::sqrt(sum_err2 / n), 1e-5 * exact) / std::sqrt(n)),
                max_dev / std::max(std::sqrt(sum_err2 / n), 1e-5 * exact),
                std::sqrt(sum_dev2 / n) / std::max(std::sqrt(sum_err2 / n), 1e-5 * exact),
                100 * std::sqrt(sum_err2 / n) / exact);
    const double s_rms = std::sqrt(sum_err2 / n), s = std::max(s_rms, 1e-5 * exact);
    EXPECT_LT(std::fabs(sum_dev / n), std::max(4.0 * s / std::sqrt(n), 1e-6 * exact)) << "mean " << exact + sum_dev / n;
    EXPECT_LT(max_dev / s, 7.0) << "s " << s;
    if (s_rms > 1e-5 * exact) {  // photons: the reported errors match the real spread
      EXPECT_GT(std::sqrt(sum_dev2 / n) / s, 0.9);
      EXPECT_LT(std::sqrt(sum_dev2 / n) / s, 1.1);
    }
  }
}

// A 1 x 1 m quad split into 200 x 200 cells (80,000 triangles, each 1/2500 of
// a texel) with a 4 x 4 lightmap under a sun 30 degrees from the zenith: every
// texel S cos(30) / pi. Tolerance: 5 reported errors per texel, 2%.
TEST(HardCases, TrianglesFarSmallerThanATexel) {
  for (const Mode mode : kModes) {
    SCOPED_TRACE(name(mode));
    SceneBuilder b;
    const uint32_t black = b.material("black", {0, 0, 0});
    b.quad("fine", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, black, 4, 200);
    const double S = 2.0, theta = M_PI / 6;
    b.light(sun(float(S), theta), "sun");
    BakeResult r;
    bake(b, settings(1000000, 1024, mode), r);
    const Agreement a = agree_const(r.map(0), S * std::cos(theta) / M_PI);
    report(name(mode), a, S * std::cos(theta) / M_PI);
    EXPECT_EQ(a.texels, 16);
    EXPECT_LT(a.max_z, 5.0);
    EXPECT_LT(a.max_rel, 0.02);
  }
}

// ---- albedo near 1 in the furnace ------------------------------------------

// Inward closed box, emission E = 1, albedo rho on every face. Half the
// emitted power leaves outwards; each trapped photon makes at most B + 1 hits
// (B = max_bounces), so the exact value is
//   E (1 - rho^(B+1)) / (1 - rho),
// and the power lost at the cap is 0.5 rho^(B+1) of the emitted power, which a
// warning must report when it exceeds 0.01%.
struct Furnace {
  double mean = 0, lost_percent = -1;
  std::string warning;
};

Furnace furnace(float rho, uint32_t max_bounces, uint64_t photons, Mode mode) {
  SceneBuilder b;
  const uint32_t m = b.material("furnace", {rho, rho, rho}, {1, 1, 1});
  b.box("furnace", {0, 0, 0}, {2, 2, 2}, 0.0f, m, 4, true);
  BakeResult r;
  Furnace f;
  bake(b, settings(photons, max_bounces, mode), r);
  if (!r.r) return f;
  const Map lm = r.map(0);
  double sum = 0, n = 0;
  for (size_t t = 0; t < lm.coverage.size(); ++t)
    if (lm.coverage[t] > 0.999f) {
      sum += lm.value(t);
      n += 1;
    }
  f.mean = sum / n;
  f.warning = r.warning("max_bounces");
  std::printf("[ measured ] %s (%s): mean %.6g, warning: %s\n", test_name().c_str(), name(mode), f.mean,
              f.warning.empty() ? "none" : f.warning.c_str());
  // "... losing 26.1% of the emitted power ...": the number before the '%'.
  const size_t pct = f.warning.find('%');
  if (pct != std::string::npos) {
    size_t start = f.warning.rfind(' ', pct);
    f.lost_percent = std::atof(f.warning.c_str() + (start == std::string::npos ? 0 : start + 1));
  }
  return f;
}

// rho = 0.99, B = 1024: exact value 99.997 (the cap loses 0.003%, under the
// warning threshold). Tolerance 2% (each photon makes ~100 hits; measured
// noise about 0.5%).
TEST(HardCases, FurnaceAlbedo099IsEnergyCorrect) {
  for (const Mode mode : kModes) {
    SCOPED_TRACE(name(mode));
    const Furnace f = furnace(0.99f, 1024, 100000, mode);
    const double exact = (1.0 - std::pow(0.99, 1025)) / 0.01;
    EXPECT_NEAR(f.mean, exact, 0.02 * exact);
    EXPECT_EQ(f.warning, "");
  }
}

// rho = 0.99, B = 64: exact value (1 - 0.99^65) / 0.01 = 47.97, and a warning
// reports the 0.5 * 0.99^65 = 26.0% lost at the cap. Tolerance: value 2%,
// reported loss within 2 percentage points (binomial noise of the trapped half).
TEST(HardCases, FurnaceAlbedo099TruncatedReportsItsLoss) {
  for (const Mode mode : kModes) {
    SCOPED_TRACE(name(mode));
    const Furnace f = furnace(0.99f, 64, 100000, mode);
    const double exact = (1.0 - std::pow(0.99, 65)) / 0.01;
    EXPECT_NEAR(f.mean, exact, 0.02 * exact);
    EXPECT_NEAR(f.lost_percent, 50.0 * std::pow(0.99, 65), 2.0) << f.warning;
  }
}

// rho = 1 never ends by itself: with the default cap B = 1024 every trapped
// path makes exactly 1025 hits (value 1025 E) and the warning reports the
// trapped half, 50% of the power, as lost. Tolerance: value 5% and loss 3
// points (3 sigma of the binomial side each of 4000 photons leaves by). Exact
// identity: value = 1025 E * (lost fraction / 0.5), within 0.5%.
TEST(HardCases, FurnaceAlbedoOneIsBoundedAndReportsItsLoss) {
  for (const Mode mode : kModes) {
    SCOPED_TRACE(name(mode));
    const Furnace f = furnace(1.0f, 1024, 4000, mode);
    EXPECT_NEAR(f.mean, 1025.0, 0.05 * 1025.0);
    EXPECT_NEAR(f.lost_percent, 50.0, 3.0) << f.warning;
    EXPECT_NEAR(f.mean, 1025.0 * f.lost_percent / 50.0, 0.005 * f.mean) << f.warning;
  }
}

// ---- a light inside geometry -----------------------------------------------

// A point light inside a closed box (albedo 0.5; once with faces pointing in,
// once out) standing over a large floor: no light gets out, so the floor is
// exactly 0 and records no hit. The inward box records light on its faces;
// the outward box receives it only on the back of its faces, which lightmaps
// do not record (Cycles bakes the front), so it stays 0 too.
TEST(HardCases, LightInsideClosedBoxLeaksNothing) {
  for (const Mode mode : kModes) {
    SCOPED_TRACE(name(mode));
    for (const bool inward : {true, false}) {
      SceneBuilder b;
      const uint32_t grey = b.material("grey", {0.5f, 0.5f, 0.5f});
      b.quad("floor", {-5, -5, 0}, {10, 0, 0}, {0, 10, 0}, grey, 16);
      b.box("box", {0.3f, -0.2f, 1.0f}, {1, 1, 1}, 0.4f, grey, 4, inward);
      b.light(point(100, {0.35f, -0.1f, 1.1f}), "inside");
      BakeResult r;
      bake(b, settings(200000, 1024, mode), r);
      const Map floor = r.map(0);
      double sum = 0, hits = 0;
      for (size_t t = 0; t < floor.hits.size(); ++t) {
        sum += floor.value(t);
        hits += floor.hits[t];
      }
      EXPECT_EQ(sum, 0.0) << (inward ? "inward" : "outward");
      EXPECT_EQ(hits, 0.0) << (inward ? "inward" : "outward");
      double box = 0;
      const Map bm = r.map(1);
      for (size_t t = 0; t < bm.coverage.size(); ++t) box += bm.value(t);
      if (inward) EXPECT_GT(box, 0.0);
      else EXPECT_EQ(box, 0.0);
    }
  }
}

// ---- overlapping UVs -------------------------------------------------------

// Two 1 x 1 m quads side by side in one mesh, both mapped onto the whole UV
// square of a 4 x 4 lightmap, under a sun at the zenith: a warning names the
// overlap and its first texel; the shared texels show flux / total area, which
// is still S / pi. Tolerance: 5 reported errors, 3%.
TEST(HardCases, OverlappingUvsAreReported) {
  for (const Mode mode : kModes) {
    SCOPED_TRACE(name(mode));
    SceneBuilder b;
    const float pos[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 2, 0, 0, 2, 1, 0};
    const uint32_t idx[] = {0, 1, 2, 0, 2, 3, 1, 4, 5, 1, 5, 2};
    const float uv[] = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1, 0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
    ASSERT_EQ(plm_scene_add_mesh(b.scene, "twins", pos, 6, idx, 4, uv, nullptr, 4, 4, nullptr), PLM_OK);
    const double S = 2.0;
    b.light(sun(float(S), 0.0), "sun");
    BakeResult r;
    bake(b, settings(400000, 1024, mode), r);
    const std::string w = r.warning("overlap");
    EXPECT_TRUE(contains(w, "mesh 'twins'")) << r.all_warnings();
    EXPECT_TRUE(contains(w, "16 texels")) << w;
    EXPECT_TRUE(contains(w, "texel 0, 0")) << w;
    const Agreement a = agree_const(r.map(0), S / M_PI, 1.5f);
    report(name(mode), a, S / M_PI);
    EXPECT_EQ(a.texels, 16);
    EXPECT_LT(a.max_z, 5.0);
    EXPECT_LT(a.max_rel, 0.03);
  }
}

// ---- very many lights ------------------------------------------------------

// 1000 point lights of P / 1000 at the same place, and one light of P, each
// over a black 4 x 4 m plane 1 m below: both give the analytic inverse-square
// cosine average per texel. Tolerance: 5 reported errors per texel, mean
// deviation within 4 standard errors of the mean.
TEST(HardCases, ThousandLightsEqualOne) {
  for (const Mode mode : kModes) {
    SCOPED_TRACE(name(mode));
    const double P = 1000.0, h = 1.0;
    for (const int count : {1, 1000}) {
      SceneBuilder b;
      const uint32_t black = b.material("black", {0, 0, 0});
      b.quad("plane", {-2, -2, 0}, {4, 0, 0}, {0, 4, 0}, black, 8);
      for (int i = 0; i < count; ++i) b.light(point(float(P / count), {0, 0, float(h)}), "bulb");
      BakeResult r;
      bake(b, settings(400000, 1024, mode), r);
      const Map m = r.map(0);
      const Agreement a = agree(m, [&](size_t t) {
        return point_over_plane(P, h, -2.0 + 0.5 * double(t % 8), -2.0 + 0.5 * double(t / 8), 0.5, 0.5);
      });
      EXPECT_EQ(a.texels, 64);
      report(count == 1 ? (mode == Mode::PhotonsOnly ? "1 light, photons only" : "1 light, direct pass")
                        : (mode == Mode::PhotonsOnly ? "1000 lights, photons only" : "1000 lights, direct pass"),
             a, 0.0);
      EXPECT_LT(a.max_z, 5.0) << count << " lights";
      EXPECT_LT(std::fabs(a.mean_z), 4.0) << count << " lights";
    }
  }
}

// Conservation with 1000 lights of 0.1 W spread through a closed black box:
// the recorded flux is the total 100 W (see expect_black_box_conserves).
TEST(HardCases, ThousandLightsConserveFlux) {
  expect_black_box_conserves({0, 0, 0}, 2.0f, point(0.1f, {0, 0, 0}), 100.0, 1000);
}

// ---- the smallest scenes ---------------------------------------------------

// A scene of one triangle with a 1 x 1 lightmap (half covered) under a sun at
// the zenith: the texel is S / pi. Tolerance: 5 reported errors and 2%.
TEST(HardCases, OneTriangleScene) {
  for (const Mode mode : kModes) {
    SCOPED_TRACE(name(mode));
    SceneBuilder b;
    const float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint32_t idx[] = {0, 1, 2};
    const float uv[] = {0, 0, 1, 0, 0, 1};
    ASSERT_EQ(plm_scene_add_mesh(b.scene, "only", pos, 3, idx, 1, uv, nullptr, 1, 1, nullptr), PLM_OK);
    const double S = 2.0;
    b.light(sun(float(S), 0.0), "sun");
    BakeResult r;
    bake(b, settings(200000, 1024, mode), r);
    const Map m = r.map(0);
    EXPECT_NEAR(m.coverage[0], 0.5f, 1e-6f);
    EXPECT_NEAR(m.value(0), S / M_PI, 0.02 * S / M_PI);
    EXPECT_LT(std::fabs(m.value(0) - S / M_PI), 5.0 * std::max(double(m.error[0]), 1e-5 * S / M_PI));
  }
}

// An empty scene, and one with lights but no meshes: PLM_ERROR_INVALID_SCENE,
// a message saying there is nothing to bake, no result.
TEST(HardCases, EmptySceneIsAnError) {
  SceneBuilder b;
  const plm_bake_settings s = settings(1000);
  plm_result* r = reinterpret_cast<plm_result*>(1);
  EXPECT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r), PLM_ERROR_INVALID_SCENE);
  EXPECT_EQ(r, nullptr);
  EXPECT_TRUE(contains(plm_last_error(), "no meshes")) << plm_last_error();
  b.light(point(100, {0, 0, 1}), "lonely");
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r), PLM_ERROR_INVALID_SCENE);
  EXPECT_TRUE(contains(plm_last_error(), "no meshes")) << plm_last_error();
}

// No light with power, no emission, a black world: the bake is refused (every
// lightmap would be black) and no result is made.
TEST(HardCases, NoLightsIsRefused) {
  SceneBuilder b;
  const uint32_t white = b.material("white", {0.8f, 0.8f, 0.8f});
  b.box("box", {0, 0, 0}, {1, 1, 1}, 0.0f, white, 4);
  const float black[3] = {0, 0, 0};
  ASSERT_EQ(plm_scene_set_world(b.scene, black), PLM_OK);
  b.light(point(0.0f, {0, 0, 3}), "off");  // a light of power 0 emits nothing
  const plm_bake_settings st = settings(1000);
  plm_result* r = nullptr;
  EXPECT_EQ(plm_bake(b.scene, &st, nullptr, nullptr, &r), PLM_ERROR_INVALID_SCENE);
  EXPECT_EQ(r, nullptr);
  EXPECT_NE(std::string(plm_last_error()).find("nothing lights the scene"), std::string::npos) << plm_last_error();
}

// ---- bad input through the C API -------------------------------------------

struct BadInput : ::testing::Test {
  plm_scene* s = nullptr;
  void SetUp() override { ASSERT_EQ(plm_scene_create(&s), PLM_OK); }
  void TearDown() override { plm_scene_release(s); }
  // The call returned INVALID_ARGUMENT and the message holds every needle.
  static void rejected(plm_status st, std::initializer_list<const char*> needles) {
    EXPECT_EQ(st, PLM_ERROR_INVALID_ARGUMENT) << plm_last_error();
    for (const char* n : needles)
      EXPECT_TRUE(contains(plm_last_error(), n)) << "'" << n << "' not in: " << plm_last_error();
  }
};

const float kBad[] = {NAN, INFINITY, -INFINITY};

// A NaN, +Inf or -Inf in any vertex position or lightmap UV: rejected, the
// message names the mesh and the vertex (or triangle and corner).
TEST_F(BadInput, NonFiniteMeshDataIsRejectedWithItsIndex) {
  const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
  for (const float bad : kBad) {
    for (int k = 0; k < 12; ++k) {
      float pos[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
      pos[k] = bad;
      const float uv[12] = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
      const std::string vertex = "vertex " + std::to_string(k / 3);
      rejected(plm_scene_add_mesh(s, "wall", pos, 4, idx, 2, uv, nullptr, 4, 4, nullptr),
               {"mesh 'wall'", vertex.c_str(), "non-finite"});
    }
    for (int k = 0; k < 12; ++k) {
      const float pos[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
      float uv[12] = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
      uv[k] = bad;
      const std::string where = "triangle " + std::to_string(k / 6) + " corner " + std::to_string((k % 6) / 2);
      rejected(plm_scene_add_mesh(s, nullptr, pos, 4, idx, 2, uv, nullptr, 4, 4, nullptr),
               {"mesh '#0'", where.c_str(), "lightmap UV"});
    }
  }
}

// A NaN or infinity in a material's albedo or emission: rejected, naming the
// material and the channel.
TEST_F(BadInput, NonFiniteMaterialIsRejectedWithItsChannel) {
  for (const float bad : kBad) {
    for (int c = 0; c < 3; ++c) {
      float albedo[3] = {0.5f, 0.5f, 0.5f}, emission[3] = {0, 0, 0};
      albedo[c] = bad;
      const std::string ch = "albedo[" + std::to_string(c) + "]";
      rejected(plm_scene_add_material(s, "paint", albedo, emission, nullptr), {"material 'paint'", ch.c_str()});
      albedo[c] = 0.5f;
      emission[c] = bad;
      const std::string ech = "emission[" + std::to_string(c) + "]";
      rejected(plm_scene_add_material(s, nullptr, albedo, emission, nullptr), {"material '#0'", ech.c_str()});
    }
  }
}

// A NaN or infinity in a light's matrix, colour, power, radius, angle, size or
// spot parameters: rejected, naming the light and the field (and the matrix
// element). The world radiance likewise, naming the channel.
TEST_F(BadInput, NonFiniteLightOrWorldIsRejected) {
  for (const float bad : kBad) {
    for (int i = 0; i < 16; ++i) {
      plm_light l;
      plm_light_default(&l, PLM_LIGHT_POINT);
      l.matrix[i] = bad;
      const std::string el = "matrix element " + std::to_string(i);
      rejected(plm_scene_add_light(s, "lamp", &l, nullptr), {"light 'lamp'", el.c_str()});
    }
    for (int c = 0; c < 3; ++c) {
      plm_light l;
      plm_light_default(&l, PLM_LIGHT_SPOT);
      l.color[c] = bad;
      const std::string ch = "color[" + std::to_string(c) + "]";
      rejected(plm_scene_add_light(s, "spot", &l, nullptr), {"light 'spot'", ch.c_str()});
      float world[3] = {0, 0, 0};
      world[c] = bad;
      const std::string wc = "radiance[" + std::to_string(c) + "]";
      rejected(plm_scene_set_world(s, world), {"world", wc.c_str()});
    }
    struct Field {
      plm_light_type type;
      float plm_light::*field;
      const char* name;
    };
    const Field fields[] = {
        {PLM_LIGHT_POINT, &plm_light::power, "power"},         {PLM_LIGHT_SUN, &plm_light::power, "power"},
        {PLM_LIGHT_POINT, &plm_light::radius, "radius"},       {PLM_LIGHT_SPOT, &plm_light::radius, "radius"},
        {PLM_LIGHT_SUN, &plm_light::angle, "angle"},           {PLM_LIGHT_AREA_RECT, &plm_light::size_x, "size"},
        {PLM_LIGHT_AREA_DISK, &plm_light::size_y, "size"},     {PLM_LIGHT_SPOT, &plm_light::spot_size, "spot_size"},
        {PLM_LIGHT_SPOT, &plm_light::spot_blend, "spot_blend"},
        // Fields the type does not use must be numbers too.
        {PLM_LIGHT_SUN, &plm_light::radius, "radius"},         {PLM_LIGHT_POINT, &plm_light::angle, "angle"},
        {PLM_LIGHT_SUN, &plm_light::size_x, "size_x"},         {PLM_LIGHT_AREA_RECT, &plm_light::spot_size, "spot_size"}};
    for (const Field& f : fields) {
      plm_light l;
      plm_light_default(&l, f.type);
      l.*f.field = bad;
      rejected(plm_scene_add_light(s, nullptr, &l, nullptr), {"light '#0'", f.name});
    }
  }
  // Nothing bad was kept: the scene still has no light and a black world.
  const float pos[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
  const float uv[12] = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
  ASSERT_EQ(plm_scene_add_mesh(s, "ok", pos, 4, idx, 2, uv, nullptr, 2, 2, nullptr), PLM_OK);
  const plm_bake_settings st = settings(1000);
  plm_result* r = nullptr;
  EXPECT_EQ(plm_bake(s, &st, nullptr, nullptr, &r), PLM_ERROR_INVALID_SCENE);
  EXPECT_NE(std::string(plm_last_error()).find("nothing lights the scene"), std::string::npos) << plm_last_error();
}

// Counts over the limits: photon_count above 2^40 (or 0), a lightmap side
// above 16384, dilation above 4096, filter_radius above 64, direct_samples
// above 65536, target_error outside [0, 1), time_budget outside [0, 1e7) or
// NaN/Inf. Rejected with the limit in the message; a side of exactly 16384
// is accepted by add_mesh.
TEST_F(BadInput, HugeCountsAreRejected) {
  const float pos[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
  const float uv[12] = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
  rejected(plm_scene_add_mesh(s, "big", pos, 4, idx, 2, uv, nullptr, 16385, 4, nullptr), {"mesh 'big'", "16384"});
  rejected(plm_scene_add_mesh(s, "big", pos, 4, idx, 2, uv, nullptr, 4, 0xFFFFFFFFu, nullptr), {"mesh 'big'", "16384"});
  EXPECT_EQ(plm_scene_add_mesh(s, "edge", pos, 4, idx, 2, uv, nullptr, 16384, 1, nullptr), PLM_OK) << plm_last_error();
  plm_result* r = nullptr;
  plm_bake_settings st = settings((uint64_t(1) << 40) + 1);
  rejected(plm_bake(s, &st, nullptr, nullptr, &r), {"photon_count", "2^40"});
  EXPECT_EQ(r, nullptr);
  st = settings(~uint64_t(0));
  rejected(plm_bake(s, &st, nullptr, nullptr, &r), {"photon_count"});
  st = settings(0);
  rejected(plm_bake(s, &st, nullptr, nullptr, &r), {"photon_count"});
  st = settings(1000);
  st.dilation = 4097;
  rejected(plm_bake(s, &st, nullptr, nullptr, &r), {"dilation", "4096"});
  st = settings(1000);
  st.filter_radius = 65;
  rejected(plm_bake(s, &st, nullptr, nullptr, &r), {"filter_radius", "64"});
  st = settings(1000);
  st.direct_samples = 65537;
  rejected(plm_bake(s, &st, nullptr, nullptr, &r), {"direct_samples", "65536"});
  for (const double bad : {-1.0, 1.0, double(NAN), double(INFINITY)}) {
    st = settings(1000);
    st.target_error = bad;
    rejected(plm_bake(s, &st, nullptr, nullptr, &r), {"target_error"});
  }
  for (const double bad : {-1.0, 1e8, double(NAN), double(INFINITY)}) {
    st = settings(1000);
    st.time_budget = bad;
    rejected(plm_bake(s, &st, nullptr, nullptr, &r), {"time_budget"});
  }
  EXPECT_EQ(r, nullptr);
}

// Sizes that do not fit together: 0 vertices, 0 triangles, a 0 x 5 or 5 x 0
// lightmap, a lightmap without UVs, NULL arrays. Rejected, naming the mesh.
TEST_F(BadInput, MismatchedSizesAreRejected) {
  const float pos[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
  const float uv[12] = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
  rejected(plm_scene_add_mesh(s, "m", pos, 0, idx, 2, uv, nullptr, 4, 4, nullptr), {"mesh 'm'", "0 vertices"});
  rejected(plm_scene_add_mesh(s, "m", pos, 4, idx, 0, uv, nullptr, 4, 4, nullptr), {"mesh 'm'", "0 triangles"});
  rejected(plm_scene_add_mesh(s, "m", pos, 4, idx, 2, uv, nullptr, 0, 5, nullptr), {"mesh 'm'", "0 x 5"});
  rejected(plm_scene_add_mesh(s, "m", pos, 4, idx, 2, uv, nullptr, 5, 0, nullptr), {"mesh 'm'", "5 x 0"});
  rejected(plm_scene_add_mesh(s, "m", pos, 4, idx, 2, nullptr, nullptr, 4, 4, nullptr), {"mesh 'm'", "UVs"});
  rejected(plm_scene_add_mesh(s, "m", nullptr, 4, idx, 2, uv, nullptr, 4, 4, nullptr), {"mesh 'm'", "NULL"});
  rejected(plm_scene_add_mesh(s, "m", pos, 4, nullptr, 2, uv, nullptr, 4, 4, nullptr), {"mesh 'm'", "NULL"});
  rejected(plm_scene_add_mesh(s, "m", pos, 3, idx, 2, uv, nullptr, 4, 4, nullptr), {"mesh 'm'", "uses vertex 3"});
  rejected(plm_scene_add_mesh(nullptr, "m", pos, 4, idx, 2, uv, nullptr, 4, 4, nullptr), {"scene"});
  const float a[3] = {0.5f, 0.5f, 0.5f};
  rejected(plm_scene_add_material(s, "m", nullptr, a, nullptr), {"material 'm'", "NULL"});
  rejected(plm_scene_add_light(s, "l", nullptr, nullptr), {"light"});
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_POINT);
  l.type = 7;
  rejected(plm_scene_add_light(s, "l", &l, nullptr), {"light 'l'", "type 7"});
  rejected(plm_scene_set_world(s, nullptr), {"world"});
  // Nothing was added: the scene is still empty.
  plm_result* r = nullptr;
  const plm_bake_settings st = settings(1000);
  EXPECT_EQ(plm_bake(s, &st, nullptr, nullptr, &r), PLM_ERROR_INVALID_SCENE);
  EXPECT_TRUE(contains(plm_last_error(), "no meshes")) << plm_last_error();
  // BakeResult queries with bad ids.
  EXPECT_EQ(plm_result_lightmap_size(nullptr, 0, nullptr, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_result_warning_count(nullptr), 0u);
  EXPECT_STREQ(plm_result_warning(nullptr, 3), "");
}

// Finite input whose products overflow float: a light of colour 1e30 and power
// 1e30 (flux 1e60 W). Expected: rejected with a message naming the light, or a
// bake whose every texel is finite. Either is acceptable; NaN/Inf texels are not.
bool finite_or_rejected(SceneBuilder& b, std::string& why) {
  plm_result* r = nullptr;
  const plm_bake_settings s = settings(20000, 4);
  const plm_status st = plm_bake(b.scene, &s, nullptr, nullptr, &r);
  if (st != PLM_OK) {
    why = plm_last_error();
    return st == PLM_ERROR_INVALID_ARGUMENT || st == PLM_ERROR_INVALID_SCENE;
  }
  BakeResult res;
  res.r = r;
  const Map m = res.map(0);
  for (size_t i = 0; i < m.rgb.size(); ++i)
    if (!std::isfinite(m.rgb[i])) {
      why = "texel " + std::to_string(i / 3) + " is " + std::to_string(m.rgb[i]);
      return false;
    }
  for (float e : m.error)
    if (!std::isfinite(e)) {
      why = "an error texel is " + std::to_string(e);
      return false;
    }
  return true;
}

// Guards against: a light with colour 1e30 and power
// 1e30, both accepted by plm_scene_add_light, has a flux of 1e60 that overflows
// float to inf; the light-choice table becomes inf / inf = NaN and every texel
// of the bake is NaN, with status PLM_OK and no warning. Expected: rejected at
// add_light/plm_bake, or finite texels.
TEST(HardCases, OverflowingLightFluxIsRejectedOrFinite) {
  SceneBuilder b;
  const uint32_t grey = b.material("grey", {0.5f, 0.5f, 0.5f});
  b.quad("floor", {-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, grey, 4);
  plm_light l = point(1e30f, {0, 0, 1});
  l.color[0] = l.color[1] = l.color[2] = 1e30f;
  b.light(l, "blinding");
  ASSERT_TRUE(b.ok()) << b.error;
  std::string why;
  EXPECT_TRUE(finite_or_rejected(b, why)) << why;
}

// Guards against: a floor quad of side 2e18 m
// (finite positions, accepted by plm_scene_add_mesh) under a sun ABORTS the
// process: Debian's Embree is built with assertions and aborts in
// bvh_intersector1.cpp:59 "Assertion `ray.valid()' failed", because sun
// photons start 2 scene radii out, beyond Embree's |origin| <= 1.844e18
// (FLT_LARGE). A library inside Blender must never abort. Expected: positions
// (or scene extents) beyond a documented limit rejected with a message naming
// the mesh and vertex, or a finite bake. (At 2e19 and 2e20 the bake is
// rejected, but with the misleading "the scene has no triangle with a non-zero
// area": the areas overflow float.)
TEST(HardCases, HugeCoordinatesAreRejectedOrFinite) {
  SceneBuilder b;
  const uint32_t grey = b.material("grey", {0.5f, 0.5f, 0.5f});
  b.quad("floor", {-1e18f, -1e18f, 0}, {2e18f, 0, 0}, {0, 2e18f, 0}, grey, 4);
  b.light(sun(1.0f, 0.3), "sun");
  // Now rejected when the mesh is added, naming the mesh and the vertex.
  EXPECT_FALSE(b.ok());
  EXPECT_NE(b.error.find("mesh 'floor': vertex 0"), std::string::npos) << b.error;
  EXPECT_NE(b.error.find("beyond the engine's range"), std::string::npos) << b.error;
  // Up to the limit, a bake stays finite.
  SceneBuilder c;
  const uint32_t g = c.material("grey", {0.5f, 0.5f, 0.5f});
  c.quad("floor", {-1e11f, -1e11f, 0}, {2e11f, 0, 0}, {0, 2e11f, 0}, g, 4);
  c.light(sun(1.0f, 0.3), "sun");
  ASSERT_TRUE(c.ok()) << c.error;
  std::string why;
  EXPECT_TRUE(finite_or_rejected(c, why)) << why;
}

// Guards against (a case fuzz_scene_api found): a quad whose second edge is
// denormal-small (0, 0, 2.8e-45) has a world area > 0 in double, so its texels
// get an area, but its float normal is 0 / 0 = NaN. Under a world light (a sun
// or point light does not trigger it) the direct pass then casts
// a shadow ray with a NaN origin and Debian's Embree ABORTS the process
// ("Assertion `ray.valid()' failed", bvh_intersector1.cpp:145). Expected: the
// triangle treated as degenerate (skipped, warned with its index) or any
// finite bake; never an abort.
TEST(HardCases, NearlyDegenerateTriangleDoesNotAbort) {
  SceneBuilder b;
  const uint32_t grey = b.material("grey", {0.8f, 0.8f, 0.8f});
  b.quad("sliver", {-1, -1, 0}, {2, 0, 0}, {0, 0, 2.8026e-45f}, grey, 8);
  const float world[3] = {1, 1, 1};
  ASSERT_EQ(plm_scene_set_world(b.scene, world), PLM_OK);
  ASSERT_TRUE(b.ok()) << b.error;
  std::string why;
  EXPECT_TRUE(finite_or_rejected(b, why)) << why;
}

}  // namespace

namespace {

// Lightmaps far larger than any machine's memory (4 meshes of 16384 x 16384
// texels: about 400 GB) are refused before anything is allocated, with a
// message that names the largest lightmap and the memory free.
TEST(HardCases, BakeThatCannotFitIsRefused) {
  SceneBuilder b;
  const uint32_t white = b.material("white", {0.8f, 0.8f, 0.8f});
  (void)white;
  const float pos[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
  const float uv[12] = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
  for (int k = 0; k < 4; ++k) {
    const std::string name = "huge" + std::to_string(k);
    ASSERT_EQ(plm_scene_add_mesh(b.scene, name.c_str(), pos, 4, idx, 2, uv, nullptr, 16384, 16384, nullptr), PLM_OK);
  }
  b.light(point(100.0f, {0.5f, 0.5f, 1}), "lamp");
  const plm_bake_settings st = settings(1000);
  plm_result* r = nullptr;
  EXPECT_EQ(plm_bake(b.scene, &st, nullptr, nullptr, &r), PLM_ERROR_OUT_OF_MEMORY);
  EXPECT_EQ(r, nullptr);
  const std::string msg = plm_last_error();
  EXPECT_TRUE(contains(msg, "mesh 'huge0', 16384 x 16384 texels")) << msg;
  EXPECT_TRUE(contains(msg, "are free: lower the lightmap resolution of 'huge0'")) << msg;
}

// The estimate is reported and is of the right size: a 512 x 512 lightmap
// wholly covered needs about 170 MB with the process (a measured 1024 x 1024
// one: 490 MB).
TEST(HardCases, MemoryEstimateIsReported) {
  SceneBuilder b;
  b.material("white", {0.8f, 0.8f, 0.8f});
  b.quad("floor", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 0, 512);
  b.light(point(100.0f, {0.5f, 0.5f, 1}), "lamp");
  BakeResult r;
  bake(b, settings(1000), r);
  const uint64_t bytes = r.stats().memory_estimate;
  EXPECT_GT(bytes, uint64_t(120) << 20);
  EXPECT_LT(bytes, uint64_t(250) << 20);
}

}  // namespace

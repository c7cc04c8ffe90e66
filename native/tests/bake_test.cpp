// Bakes through the C API checked against analytic answers.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <dirent.h>
#include <numeric>
#include <string>
#include <vector>

#include "demo_scenes.h"
#include "test_support.h"
#include "util/rng.h"

namespace {

using plm_demo::SceneBuilder;
using plm_demo::V3;
using plm_test::bake;
using plm_test::open_scene;

using Lightmap = plm_test::Map;
using Baked = plm_test::BakeResult;

plm_bake_settings settings(uint64_t photons, uint32_t max_bounces = 1024, uint32_t direct_samples = 16,
                           uint32_t filter_radius = 3) {
  plm_bake_settings s;
  plm_bake_settings_default(&s);
  s.photon_count = photons;
  s.max_bounces = max_bounces;
  s.direct_samples = direct_samples;
  s.filter_radius = filter_radius;
  return s;
}

// Photons only, every texel on its own: sums of value * area are exactly the recorded flux.
plm_bake_settings raw_photons(uint64_t photons, uint32_t max_bounces = 1024) {
  return settings(photons, max_bounces, 0, 0);
}

// Flux recorded on a lightmap: sum of value * pi * texel area (world area = coverage * area per texel).
double recorded_flux(const Lightmap& m, double world_area_per_texel) {
  double sum = 0.0;
  for (size_t t = 0; t < m.coverage.size(); ++t)
    if (m.coverage[t] > 0) sum += m.value(t) * M_PI * m.coverage[t] * world_area_per_texel;
  return sum;
}

// Furnace: closed box, uniform emission E and albedo rho: radiosity E / (1 - rho) everywhere.
void expect_furnace(float rho, V3 center, float size, uint64_t photons) {
  SceneBuilder b;
  const uint32_t m = b.material("furnace", {rho, rho, rho}, {1, 1, 1});
  b.box("furnace", center, {size, size, size}, 0.0f, m, 12, true);
  Baked r;
  bake(b, settings(photons), r);
  const Lightmap lm = r.map(0);
  const double exact = 1.0 / (1.0 - rho);
  double sum = 0, wsum = 0, z2 = 0;
  int n = 0;
  for (size_t t = 0; t < lm.coverage.size(); ++t) {
    if (lm.coverage[t] < 0.999f) continue;
    sum += lm.value(t);
    wsum += 1;
    const double z = (lm.value(t) - exact) / lm.error[t];
    z2 += z * z;
    ++n;
  }
  EXPECT_NEAR(sum / wsum, exact, 0.01 * exact) << "rho " << rho << " size " << size;
  // The reported standard error matches the real spread (z-scores of unit variance).
  EXPECT_GT(z2 / n, 0.5);
  EXPECT_LT(z2 / n, 2.0);
}

TEST(Bake, FurnaceAlbedoHalf) { expect_furnace(0.5f, {0, 0, 0}, 2.0f, 2000000); }
TEST(Bake, FurnaceAlbedoPointNine) { expect_furnace(0.9f, {0, 0, 0}, 2.0f, 1000000); }
TEST(Bake, FurnaceTinyScale) { expect_furnace(0.5f, {0, 0, 0}, 1e-4f, 1000000); }
TEST(Bake, FurnaceHugeScale) { expect_furnace(0.5f, {0, 0, 0}, 1e4f, 1000000); }
// 1e5 m out, float positions are 0.008 m apart: a 20 m room keeps texel-exact hits.
TEST(Bake, FurnaceFarFromOrigin) { expect_furnace(0.5f, {1e5f, -1e5f, 1e5f}, 20.0f, 1000000); }

TEST(Bake, AlbedoOneStopsAtMaxBouncesAndWarns) {
  SceneBuilder b;
  const uint32_t m = b.material("mirror", {1, 1, 1}, {1, 1, 1});
  b.box("closed", {0, 0, 0}, {2, 2, 2}, 0.0f, m, 4, true);
  Baked r;
  bake(b, settings(20000, 16), r);
  // Emission leaves both sides: the half emitted outwards escapes, the rest is trapped.
  EXPECT_NEAR(double(r.stats().paths_truncated), 10000.0, 400.0);
  EXPECT_TRUE(!r.warning("max_bounces").empty());
  // 17 hits per photon, each carrying the full flux: value = 17 * E (E = 1).
  const Lightmap lm = r.map(0);
  double sum = 0, n = 0;
  for (size_t t = 0; t < lm.coverage.size(); ++t)
    if (lm.coverage[t] > 0.999f) {
      sum += lm.value(t);
      n += 1;
    }
  EXPECT_NEAR(sum / n, 17.0, 0.5);
}

// Closed black box, photons only: every photon is absorbed at its first hit,
// so the flux recorded over all six faces is exactly the light's flux.
double black_box_flux(const plm_light& light) {
  SceneBuilder b;
  const uint32_t m = b.material("black", {0, 0, 0});
  b.box("closed", {0, 0, 0}, {2, 2, 2}, 0.0f, m, 8, true);
  b.light(light, "light");
  Baked r;
  bake(b, raw_photons(200000), r);
  // Each face 2 x 2 m over (8 - 2 margin) ^ 2 covered texels of a 24 x 16 map.
  return recorded_flux(r.map(0), 4.0 / 36.0);
}

TEST(Bake, LightPowerMatchesCyclesUnits) {
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_POINT);
  l.power = 100.0f;
  l.radius = 0.0f;
  EXPECT_NEAR(black_box_flux(l), 100.0, 0.01);  // point: P
  plm_light_default(&l, PLM_LIGHT_AREA_RECT);
  l.power = 100.0f;
  l.size_x = 0.3f;
  l.size_y = 0.7f;
  EXPECT_NEAR(black_box_flux(l), 25.0 * M_PI, 0.01);  // area: pi P / 4
  plm_light_default(&l, PLM_LIGHT_AREA_DISK);
  l.power = 100.0f;
  EXPECT_NEAR(black_box_flux(l), 25.0 * M_PI, 0.01);
  plm_light_default(&l, PLM_LIGHT_SPOT);
  l.power = 100.0f;
  l.radius = 0.0f;
  l.spot_blend = 0.0f;
  l.spot_size = 1.0f;
  // Intensity P/(4 pi) cos(a) inside the cone: flux P sin^2(half angle) / 4.
  EXPECT_NEAR(black_box_flux(l), 25.0 * std::pow(std::sin(0.5), 2.0), 0.02);
}

TEST(Bake, EmissiveTriangleEmitsFromBothSides) {
  SceneBuilder b;
  const uint32_t black = b.material("black", {0, 0, 0});
  const uint32_t glow = b.material("glow", {0, 0, 0}, {2, 2, 2});
  b.box("closed", {0, 0, 0}, {2, 2, 2}, 0.0f, black, 8, true);
  b.quad("panel", {-0.25f, -0.25f, 0}, {0.5f, 0, 0}, {0, 0.5f, 0}, glow, 0);
  Baked r;
  bake(b, raw_photons(200000), r);
  EXPECT_NEAR(recorded_flux(r.map(0), 4.0 / 36.0), 2.0 * M_PI * 2.0 * 0.25, 1e-3);  // 2 pi L A
}

// A square plane of side 20 at z = 0, lightmap res x res; returns its lightmap.
Lightmap lit_plane(const plm_light& light, uint32_t res, uint64_t photons, const float* world = nullptr,
                   uint32_t texel_value = PLM_TEXEL_CYCLES) {
  SceneBuilder b;
  const uint32_t m = b.material("black", {0, 0, 0});
  b.quad("plane", {-10, -10, 0}, {20, 0, 0}, {0, 20, 0}, m, res);
  if (light.power > 0) b.light(light, "light");
  if (world) {
    EXPECT_EQ(plm_scene_set_world(b.scene, world), PLM_OK);
  }
  Baked r;
  plm_bake_settings s = settings(photons, 1024, 64);
  s.texel_value = texel_value;
  bake(b, s, r);
  return r.map(0);
}

// Where Cycles 3.4 bakes the point (x, y) of a texel whose centre is (cx, cy),
// on the square [lo, lo + size]^2 that SceneBuilder::quad splits into triangles
// (a, b, d) and (a, d, c) (a = lo corner, d = opposite): in the triangle that
// owns the centre (the later one on the diagonal), folded back into it by
// mirror repeat of the barycentric coordinates u (of its corner 0), then v (of
// corner 1) within [0, 1 - u]. Measured against Cycles in headless Blender:
// docs/design/texels.md, "Where the central square crosses a triangle edge, it
// is folded back into one triangle".
void cycles_fold(double lo, double size, double cx, double cy, double& x, double& y) {
  auto mirror = [](double t, double range) {
    const double q = t / range, f = std::floor(q), r = q - f;
    return (int64_t(f) & 1 ? 1.0 - r : r) * range;
  };
  const double s = (x - lo) / size, t = (y - lo) / size;
  double s2, t2;
  if ((cy - lo) / size >= (cx - lo) / size) {  // (a, d, c): s = v, t = 1 - u
    const double u = mirror(1.0 - t, 1.0), v = mirror(s, 1.0 - u);
    s2 = v, t2 = 1.0 - u;
  } else {  // (a, b, d): s = v + w, t = w
    const double u = mirror(1.0 - s, 1.0), v = mirror(s - t, 1.0 - u);
    s2 = 1.0 - u, t2 = 1.0 - u - v;
  }
  x = lo + s2 * size, y = lo + t2 * size;
}

// The exact value f(x, y) of texel (i, j) of a 20 x 20 m plane at res 20,
// averaged (16 x 16 midpoints) over the texel or over its central half (as
// Cycles bakes it: cycles_fold).
template <typename F>
double texel_truth(F&& f, uint32_t i, uint32_t j, uint32_t texel_value) {
  const bool cycles = texel_value == PLM_TEXEL_CYCLES;
  const double lo = cycles ? 0.25 : 0.0, w = 1.0 - 2.0 * lo;
  double avg = 0.0;
  const int k = 16;
  for (int a = 0; a < k; ++a)
    for (int c = 0; c < k; ++c) {
      double x = i - 10.0 + lo + w * (a + 0.5) / k, y = j - 10.0 + lo + w * (c + 0.5) / k;
      if (cycles) cycles_fold(-10.0, 20.0, i - 9.5, j - 9.5, x, y);
      avg += f(x, y);
    }
  return avg / (k * k);
}

TEST(Bake, PointLightOverPlaneIsInverseSquareCosine) {
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_POINT);
  l.power = 1000.0f;
  l.radius = 0.0f;
  l.matrix[11] = 2.0f;  // 2 m above the plane centre
  const uint32_t res = 20;
  auto exact = [](double x, double y) {
    const double d2 = x * x + y * y + 4.0;
    return 1000.0 / (4 * M_PI) * 2.0 / std::pow(d2, 1.5) / M_PI;
  };
  for (const uint32_t mode : {PLM_TEXEL_CYCLES, PLM_TEXEL_AREA}) {
    SCOPED_TRACE(mode == PLM_TEXEL_CYCLES ? "central half" : "texel average");
    const Lightmap lm = lit_plane(l, res, 4000000, nullptr, mode);
    double worst = 0.0, z2 = 0.0;
    for (uint32_t j = 6; j < 14; ++j) {
      for (uint32_t i = 6; i < 14; ++i) {
        const double truth = texel_truth(exact, i, j, mode);
        const size_t t = j * res + i;
        const double deviation = lm.value(t) - truth;
        worst = std::max(worst, std::fabs(deviation) / truth);
        z2 += deviation * deviation / (double(lm.error[t]) * lm.error[t]);
        EXPECT_NEAR(lm.value(t), truth, 0.02 * truth) << "texel " << i << "," << j;
      }
    }
    EXPECT_LT(worst, 0.02);
    // The reported error is the right size: deviations of unit variance or less
    // (it may over-estimate: it counts part of the texel's gradient as noise).
    EXPECT_LT(z2 / 64.0, 2.0);
    EXPECT_GT(z2 / 64.0, 0.1);
  }
}

// Point lights (radius 0) over the plane z = 0 and their closed form.
struct PointLight {
  double x, y, h, power;
};

void add_point_lights(SceneBuilder& b, const std::vector<PointLight>& points) {
  for (size_t k = 0; k < points.size(); ++k) {
    plm_light l;
    plm_light_default(&l, PLM_LIGHT_POINT);
    l.power = float(points[k].power);
    l.radius = 0.0f;
    l.matrix[3] = float(points[k].x), l.matrix[7] = float(points[k].y), l.matrix[11] = float(points[k].h);
    b.light(l, ("point" + std::to_string(k)).c_str());
  }
}

// Irradiance at (x, y, 0) from the point lights.
double point_irradiance(const std::vector<PointLight>& points, double x, double y) {
  double e = 0.0;
  for (const PointLight& p : points) {
    const double dx = x - p.x, dy = y - p.y, d2 = dx * dx + dy * dy + p.h * p.h;
    e += p.power / (4 * M_PI) * p.h / std::pow(d2, 1.5);
  }
  return e;
}

// Several lights add up, whichever way the direct pass shares its shadow rays
// among them: one ray to each (up to 4 lights), or one to the sun and one to
// a lamp chosen by its unoccluded irradiance at the texel among all lamps (up
// to 32) or among the 32 brightest there (more).
// Point lights of different powers and heights plus a tilted sun over a black
// plane, against the sum of their closed forms, texel by texel.
TEST(Bake, SeveralLightsAddUpWhateverTheLightChoice) {
  for (const int count : {3, 6, 11, 70}) {  // every light-choice path
    SCOPED_TRACE(std::to_string(count) + " lights");
    SceneBuilder b;
    const uint32_t m = b.material("black", {0, 0, 0});
    b.quad("plane", {-10, -10, 0}, {20, 0, 0}, {0, 20, 0}, m, 20);
    std::vector<PointLight> points;
    for (int k = 0; k + 1 < count; ++k)
      points.push_back({-3.0 + 1.7 * (k % 4), -2.0 + 1.3 * (k / 4), 1.0 + 0.5 * (k % 3), 200.0 * (1 + k % 5)});
    add_point_lights(b, points);
    plm_light sun = plm_test::tilted_sun(3.0f, float(M_PI / 3.0));  // 60 degrees from the zenith: irradiance 1.5
    sun.angle = 0.0f;
    b.light(sun, "sun");
    auto exact = [&](double x, double y) { return (1.5 + point_irradiance(points, x, y)) / M_PI; };
    Baked r;
    bake(b, settings(1000, 0, count > 8 ? 1024 : 64), r);  // one ray to one of many lights: noisier
    const Lightmap lm = r.map(0);
    double z2 = 0.0;
    for (uint32_t j = 5; j < 15; ++j)
      for (uint32_t i = 5; i < 15; ++i) {
        const double truth = texel_truth(exact, i, j, PLM_TEXEL_CYCLES);
        const size_t t = j * 20 + i;
        EXPECT_NEAR(lm.value(t), truth, 0.03 * truth) << "texel " << i << "," << j;
        z2 += (lm.value(t) - truth) * (lm.value(t) - truth) / (double(lm.error[t]) * lm.error[t]);
      }
    // The reported error is not too small (mean squared z: one ray to each
    // light 0.02; one chosen by irradiance: 0.77 (6 lights), 0.55 (11), 0.99
    // (70: candidates); 3.9 for 11 lights chosen by power before the choice
    // joined the point's Sobol point and its noise was modelled).
    EXPECT_LT(z2 / 100.0, 2.0) << "mean squared z";
  }
}

// Lamps in a sun's shadow: a black roof 3 m up shades half of a black
// ground from a sun at the zenith (10 W/m^2), eight 100 W lamps 1 m up light
// both halves. The sun's unoccluded irradiance is most of every texel's
// guess, so when it was one of the lights to choose from, the shaded half
// sent it most of its samples for nothing. Every sample now sends a ray to
// the sun and chooses among the lamps. Against the closed forms at 64
// samples a texel: the shaded half's relative RMS error is 0.45 % (31.7 %
// with the sun among the lights to choose), the lit half's 0.17 % (0.56 %).
TEST(Bake, LampsInASunsShadowGetTheSamples) {
  SceneBuilder b;
  const uint32_t m = b.material("black", {0, 0, 0});
  b.quad("ground", {-10, -10, 0}, {20, 0, 0}, {0, 20, 0}, m, 20);
  b.quad("roof", {-10.5, -10.5, 3}, {10.5, 0, 0}, {0, 21, 0}, m, 4);
  std::vector<PointLight> points;
  for (int k = 0; k < 8; ++k) points.push_back({-8.0 + 2.3 * k, -6.0 + 1.7 * (k % 5), 1.0, 100.0});
  add_point_lights(b, points);
  plm_light sun = plm_test::tilted_sun(10.0f, 0.0f);
  sun.angle = 0.0f;
  b.light(sun, "sun");
  auto exact = [&](double x, double y) { return ((x > 0.0 ? 10.0 : 0.0) + point_irradiance(points, x, y)) / M_PI; };
  Baked r;
  bake(b, settings(1000, 0, 64), r);
  const Lightmap lm = r.map(0);
  double squared[2] = {0, 0}, z2 = 0.0;
  for (uint32_t j = 0; j < 20; ++j)
    for (uint32_t i = 0; i < 20; ++i) {
      const double truth = texel_truth(exact, i, j, PLM_TEXEL_CYCLES), d = lm.value(j * 20 + i) - truth;
      squared[i < 10 ? 0 : 1] += d * d / (truth * truth);
      z2 += d * d / (double(lm.error[j * 20 + i]) * lm.error[j * 20 + i]);
    }
  const double shade = std::sqrt(squared[0] / 200.0), lit = std::sqrt(squared[1] / 200.0);
  std::printf("relative RMS error: shaded half %.4f, lit half %.4f; mean squared z %.2f\n", shade, lit, z2 / 400.0);
  EXPECT_LT(shade, 0.02);
  EXPECT_LT(lit, 0.0035);
  EXPECT_LT(z2 / 400.0, 2.0) << "mean squared z";
}

// Cycles 3.4 models a point light of radius r as a disk facing the receiver:
// irradiance I cos / (d^2 + r^2), I = P / (4 pi), at distance d from the centre.
TEST(Bake, PointLightRadiusFollowsCyclesDiskModel) {
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_POINT);
  l.power = 1000.0f;
  l.radius = 0.5f;
  l.matrix[11] = 1.0f;
  const uint32_t res = 20;
  auto exact = [](double x, double y) {
    const double d2 = x * x + y * y + 1.0;
    return 1000.0 / (4 * M_PI) * (1.0 / std::sqrt(d2)) / (d2 + 0.25) / M_PI;
  };
  for (const uint32_t mode : {PLM_TEXEL_CYCLES, PLM_TEXEL_AREA}) {
    const Lightmap lm = lit_plane(l, res, 4000000, nullptr, mode);
    for (uint32_t j = 9; j <= 10; ++j)
      for (uint32_t i = 9; i <= 10; ++i) {
        const double truth = texel_truth(exact, i, j, mode);
        EXPECT_NEAR(lm.value(j * res + i), truth, 0.03 * truth) << "texel " << i << "," << j << " mode " << mode;
      }
  }
}

// A plane lit by the sun straight from above, shadowed for x < 3.3 m by a roof:
// the shadow edge runs 0.3 texel into a column of 1 m texels. Lit fraction of
// the texel's central half [3.25, 3.75] (as Cycles bakes): 0.9; of the whole
// texel: 0.7. Texel (3, 3) lies on the quad's diagonal: Cycles folds the
// half of its window below the diagonal onto the upper triangle, (x, y) ->
// (2y - x, y), which is lit for 2y - x >= 3.3: lit fraction 0.6075.
TEST(Bake, ShadowEdgeInsideATexel) {
  for (const uint32_t mode : {PLM_TEXEL_CYCLES, PLM_TEXEL_AREA}) {
    SceneBuilder b;
    const uint32_t black = b.material("black", {0, 0, 0});
    b.quad("plane", {0, 0, 0}, {8, 0, 0}, {0, 8, 0}, black, 8);  // 1 m texels
    b.quad("roof", {-20, -20, 2}, {0, 40, 0}, {23.3f, 0, 0}, black, 0);
    plm_light sun;
    plm_light_default(&sun, PLM_LIGHT_SUN);
    sun.power = 2.0f;
    sun.angle = 0.0f;  // identity matrix: travels along -z
    b.light(sun, "sun");
    plm_bake_settings s = settings(1000, 0, 1024);  // the folded edge of texel (3, 3) needs more than 64
    s.texel_value = mode;
    Baked r;
    bake(b, s, r);
    const Lightmap lm = r.map(0);
    for (uint32_t j = 1; j < 7; ++j) {
      const double lit = 2.0 / M_PI;
      EXPECT_NEAR(lm.value(j * 8 + 2), 0.0, 1e-6) << "fully shadowed texel, row " << j;
      EXPECT_NEAR(lm.value(j * 8 + 4), lit, 1e-5) << "fully lit texel, row " << j;
      const double edge = (mode == PLM_TEXEL_CYCLES ? (j == 3 ? 0.6075 : 0.9) : 0.7) * lit;
      EXPECT_NEAR(lm.value(j * 8 + 3), edge, 0.03 * lit) << "edge texel, row " << j;
    }
  }
}

TEST(Bake, SunOverPlaneIsStrengthCosineOverPi) {
  // The sun 60 degrees from the zenith (shines along -Z of its frame).
  const plm_light l = plm_test::tilted_sun(3.0f, float(M_PI / 3.0));
  const Lightmap lm = lit_plane(l, 8, 1000000);
  const double exact = 3.0 * 0.5 / M_PI;
  for (size_t t = 0; t < lm.coverage.size(); ++t) EXPECT_NEAR(lm.value(t), exact, 0.03 * exact) << "texel " << t;
}

// UV islands that barely touch neighbouring texels must not turn single
// photon hits into bright dots: every texel stays near the exact value.
TEST(Bake, BarelyCoveredTexelsShowNoOutliers) {
  SceneBuilder b;
  const uint32_t m = b.material("black", {0, 0, 0});
  // A 1 x 1 quad whose UV square starts 1e-3 texels before a texel edge and ends 1e-3 after one.
  const uint32_t res = 16;
  const float lo = (2.0f - 1e-3f) / res, hi = (14.0f + 1e-3f) / res;
  const float pos[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
  const float uv[12] = {lo, lo, hi, lo, hi, hi, lo, lo, hi, hi, lo, hi};
  ASSERT_EQ(plm_scene_add_mesh(b.scene, "quad", pos, 4, idx, 2, uv, nullptr, res, res, nullptr), PLM_OK);
  (void)m;
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_SUN);
  l.power = 2.0f;
  b.light(l, "sun");
  Baked r;
  bake(b, settings(400000), r);
  const Lightmap lm = r.map(0);
  const double exact = 2.0 / M_PI;
  int slivers = 0;
  for (size_t t = 0; t < lm.coverage.size(); ++t) {
    if (lm.coverage[t] <= 0.0f) continue;
    slivers += lm.coverage[t] < 0.01f;
    EXPECT_NEAR(lm.value(t), exact, 0.1 * exact) << "texel " << t << " coverage " << lm.coverage[t];
  }
  EXPECT_GT(slivers, 40);  // the case really has barely covered texels
}

TEST(Bake, WorldLightOnOpenPlaneIsItsRadiance) {
  plm_light none;
  plm_light_default(&none, PLM_LIGHT_POINT);
  none.power = 0.0f;
  const float world[3] = {0.5f, 0.25f, 1.0f};
  const Lightmap lm = lit_plane(none, 4, 2000000, world);
  for (size_t t = 0; t < lm.coverage.size(); ++t) {
    EXPECT_NEAR(lm.rgb[3 * t], 0.5, 0.02) << "texel " << t;
    EXPECT_NEAR(lm.rgb[3 * t + 1], 0.25, 0.01);
    EXPECT_NEAR(lm.rgb[3 * t + 2], 1.0, 0.04);
  }
}

// An open sunlit scene (a ground, a box on it, sun and sky), where the
// indirect light is a small part: the final gather (on by default) lowers
// the error at a given photon count, stays unbiased, and reports its error
// honestly. Reference: the same scene without the gather (max_bounces 63
// turns it off) at 32x the photons and 256 direct samples.
TEST(Bake, FinalGatherLowersOpenSceneErrorUnbiased) {
  SceneBuilder b;
  open_scene(b);
  plm_bake_settings s = settings(131072, 1024, 64, 2);
  Baked gather, photons, ref;
  bake(b, s, gather);
  s.max_bounces = 63;
  bake(b, s, photons);
  s.photon_count = 32 * 131072;
  s.direct_samples = 256;
  s.seed = 7;
  bake(b, s, ref);
  double sq_g = 0, sq_p = 0, est_g = 0, est_p = 0, sum_g = 0, sum_ref = 0, n = 0;
  for (uint32_t mesh = 0; mesh < 2; ++mesh) {
    const Lightmap g = gather.map(mesh), p = photons.map(mesh), r = ref.map(mesh);
    for (size_t t = 0; t < r.coverage.size(); ++t) {
      if (r.coverage[t] < 0.999f) continue;
      sq_g += (g.value(t) - r.value(t)) * (g.value(t) - r.value(t));
      sq_p += (p.value(t) - r.value(t)) * (p.value(t) - r.value(t));
      est_g += double(g.error[t]) * g.error[t];
      est_p += double(p.error[t]) * p.error[t];
      sum_g += g.value(t);
      sum_ref += r.value(t);
      n += 1;
    }
  }
  const double mean = sum_ref / n, err_g = std::sqrt(sq_g / n) / mean, err_p = std::sqrt(sq_p / n) / mean;
  const double rep_g = std::sqrt(est_g / n) / mean, rep_p = std::sqrt(est_p / n) / mean;
  std::printf("[ measured ] open scene, 131072 photons: gather %.2f %% (reported %.2f %%), photons only %.2f %% "
              "(reported %.2f %%)\n", 100 * err_g, 100 * rep_g, 100 * err_p, 100 * rep_p);
  // Measured: gather 0.93 % (reported 0.95 %), photons only 1.10 % (reported 1.46 %).
  EXPECT_LT(err_g, 0.9 * err_p);
  EXPECT_NEAR(sum_g / sum_ref, 1.0, 0.005);
  EXPECT_GT(rep_g, err_g / 2.0);
  EXPECT_LT(rep_g, err_g * 1.5);
  // Under a target the gather runs at the first check; the result depends on
  // the seed alone and stays unbiased.
  plm_bake_settings t = settings(0, 1024, 64, 2);
  t.target_error = 0.015;
  Baked one, two;
  t.thread_count = 1;
  bake(b, t, one);
  t.thread_count = 2;
  bake(b, t, two);
  EXPECT_EQ(one.stats().photons_emitted, two.stats().photons_emitted);
  double sum_t = 0;
  for (uint32_t mesh = 0; mesh < 2; ++mesh) {
    EXPECT_EQ(one.map(mesh).rgb, two.map(mesh).rgb) << "mesh " << mesh;
    EXPECT_EQ(one.map(mesh).error, two.map(mesh).error);
    const Lightmap o = one.map(mesh), r = ref.map(mesh);
    for (size_t k = 0; k < r.coverage.size(); ++k)
      if (r.coverage[k] >= 0.999f) sum_t += o.value(k);
  }
  EXPECT_NEAR(sum_t / sum_ref, 1.0, 0.005);
}

// A texel's value is its central square (what a Cycles bake gives). Ground
// texels whose central square lies under a box standing on the ground are
// dark also where the box's rotated footprint cuts the texel and the part
// outside it is lit: their gather rays see the box's inside from both sides
// of each point (enclosed: known zeros), where the photons' mean over the
// whole texel also holds light from outside the box.
TEST(Bake, TexelsWhoseCentreIsUnderABoxAreDark) {
  SceneBuilder b;
  open_scene(b);  // box 1 x 1 m at the origin, turned 0.35 rad; ground texels 0.25 m
  Baked r;
  bake(b, settings(131072, 1024, 64, 2), r);
  const Lightmap g = r.map(0);
  const float c = std::cos(0.35f), s = std::sin(0.35f);
  auto under = [&](float x, float y) { return std::fabs(c * x + s * y) < 0.5f && std::fabs(-s * x + c * y) < 0.5f; };
  double lit = 0.0, lit_n = 0.0, worst = 0.0;
  int cut = 0;
  for (uint32_t row = 0; row < 32; ++row) {
    for (uint32_t col = 0; col < 32; ++col) {
      const float x = -4.0f + 0.25f * (col + 0.5f), y = -4.0f + 0.25f * (row + 0.5f);
      int centre = 0, whole = 0;  // corners of the central square / of the whole texel under the box
      for (int k = 0; k < 4; ++k) {
        const float dx = (k & 1) ? 0.5f : -0.5f, dy = (k & 2) ? 0.5f : -0.5f;
        centre += under(x + 0.125f * dx, y + 0.125f * dy);
        whole += under(x + 0.25f * dx, y + 0.25f * dy);
      }
      const double v = g.value(row * 32 + col);
      if (whole == 0) lit += v, lit_n += 1;
      if (centre == 4 && whole < 4) {
        ++cut;
        worst = std::max(worst, v);
      }
    }
  }
  std::printf("[ measured ] %d texels cut by the box with their centre under it: at most %.4f (lit ground %.3f)\n",
              cut, worst, lit / lit_n);
  EXPECT_GE(cut, 4);
  EXPECT_LT(worst, 0.002 * lit / lit_n);
}

// The other side of the rule above: backs that photons reach are not dark.
// A room modelled as a box with outward faces (a scaled default cube: the
// walls show their backs inside) with a lamp inside: the floor's gather rays
// all see backs, which are lit (Cycles' diffuse is two-sided), so the floor
// keeps its bounce light. Truth: the same bake without the gather
// (max_bounces 63 turns it off) at 8x the photons.
TEST(Bake, BacksThatPhotonsReachAreNotDark) {
  SceneBuilder b;
  const uint32_t grey = b.material("grey", {0.6f, 0.6f, 0.6f});
  b.quad("floor", {-1.9f, -1.9f, 0.01f}, {3.8f, 0, 0}, {0, 3.8f, 0}, grey, 16);
  b.box("room", {0, 0, 1.25f}, {4, 4, 2.5f}, 0.0f, grey, 0);  // outward faces, no lightmap
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_POINT);
  l.power = 100.0f;
  l.matrix[11] = 2.0f;
  b.light(l, "lamp");
  Baked gather, photons;
  bake(b, settings(262144, 1024, 16, 2), gather);
  plm_bake_settings s = settings(8 * 262144, 63, 16, 2);
  bake(b, s, photons);
  double sum_g = 0.0, sum_p = 0.0;
  const Lightmap g = gather.map(0), p = photons.map(0);
  for (size_t t = 0; t < p.coverage.size(); ++t) sum_g += g.value(t), sum_p += p.value(t);
  std::printf("[ measured ] floor of an inside-out room: with the gather %.4f, photons alone %.4f\n", sum_g, sum_p);
  EXPECT_NEAR(sum_g / sum_p, 1.0, 0.02);
}

// Threads add their batches' hits into the sums in whatever order they
// finish (transport/film/photon_batches.h): the bits must not depend on it, with
// a fixed photon count and with a target checked at fixed batch counts.
TEST(Bake, SameSeedSameResultWhateverTheThreads) {
  SceneBuilder b;
  plm_demo::build_cornell(b, 16);
  for (const double target : {0.0, 0.03}) {
    plm_bake_settings s = target > 0.0 ? settings(uint64_t(1) << 30, 1024, 0) : settings(100000);
    s.target_error = target;
    s.thread_count = 1;
    Baked one, other;
    bake(b, s, one);
    for (const uint32_t threads : {2u, 3u, 8u}) {
      s.thread_count = threads;
      Baked many;
      bake(b, s, many);
      EXPECT_EQ(one.stats().photons_emitted, many.stats().photons_emitted) << threads << " threads";
      EXPECT_EQ(one.stats().rays_traced, many.stats().rays_traced);
      for (uint32_t m = 0; m < 7; ++m) {
        const Lightmap a = one.map(m), c = many.map(m);
        EXPECT_EQ(a.rgb, c.rgb) << "mesh " << m << ", " << threads << " threads, target " << target;
        EXPECT_EQ(a.error, c.error);
        EXPECT_EQ(a.hits, c.hits);
      }
    }
    if (target > 0.0) {  // several checks: the photon count is set by the estimate, not the cap
      EXPECT_GT(one.stats().photons_emitted, 2 * 16 * 4096u);
      EXPECT_LT(one.stats().photons_emitted, uint64_t(1) << 30);
    }
    s.seed = 1;
    s.thread_count = 2;
    bake(b, s, other);
    EXPECT_NE(one.map(0).rgb, other.map(0).rgb);
  }
}

TEST(Bake, CancelReturnsPromptlyWithoutResult) {
  SceneBuilder b;
  plm_demo::build_cornell(b, 16);
  plm_bake_settings s = settings(uint64_t(1) << 36);  // hours of work
  int calls = 0;
  plm_progress_fn stop_at_third = [](void* user, double, const char*) { return ++*static_cast<int*>(user) < 3 ? 1 : 0; };
  plm_result* r = reinterpret_cast<plm_result*>(1);
  EXPECT_EQ(plm_bake(b.scene, &s, stop_at_third, &calls, &r), PLM_ERROR_CANCELLED);
  EXPECT_EQ(r, nullptr);
  EXPECT_EQ(calls, 3);
  EXPECT_NE(std::string(plm_last_error()).find("cancel"), std::string::npos);
}

// Nothing lights the scene: the bake is refused with a message that says so,
// and no result is made.
TEST(Bake, NoLightsIsRefused) {
  SceneBuilder b;
  const uint32_t m = b.material("white", {0.8f, 0.8f, 0.8f});
  b.quad("plane", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, m, 4);
  const plm_bake_settings s = settings(1000);
  plm_result* r = nullptr;
  EXPECT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r), PLM_ERROR_INVALID_SCENE);
  EXPECT_EQ(r, nullptr);
  EXPECT_NE(std::string(plm_last_error()).find("nothing lights the scene"), std::string::npos) << plm_last_error();
}

TEST(Api, BadInputNamesWhatAndWhere) {
  plm_scene* s = nullptr;
  ASSERT_EQ(plm_scene_create(&s), PLM_OK);
  const float albedo[3] = {0.5f, 0.5f, 0.5f}, black[3] = {0, 0, 0};
  ASSERT_EQ(plm_scene_add_material(s, "grey", albedo, black, nullptr), PLM_OK);
  const float nan = std::nanf("");
  const float pos[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, nan, 0};
  const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
  const float uv[12] = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
  EXPECT_EQ(plm_scene_add_mesh(s, "wall", pos, 4, idx, 2, uv, nullptr, 4, 4, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("mesh 'wall': vertex 3"), std::string::npos) << plm_last_error();

  const float good[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  const uint32_t bad_idx[6] = {0, 1, 2, 0, 2, 7};
  EXPECT_EQ(plm_scene_add_mesh(s, "floor", good, 4, bad_idx, 2, uv, nullptr, 4, 4, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("triangle 1 corner 2 uses vertex 7"), std::string::npos) << plm_last_error();
  EXPECT_EQ(plm_scene_add_mesh(s, "floor", good, 4, idx, 2, nullptr, nullptr, 4, 4, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("no lightmap UVs"), std::string::npos) << plm_last_error();
  const uint32_t mats[2] = {0, 5};
  EXPECT_EQ(plm_scene_add_mesh(s, "floor", good, 4, idx, 2, uv, mats, 4, 4, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("triangle 1 uses material 5"), std::string::npos) << plm_last_error();

  plm_light l;
  plm_light_default(&l, PLM_LIGHT_AREA_RECT);
  l.size_x = 0.0f;
  EXPECT_EQ(plm_scene_add_light(s, "lamp", &l, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("light 'lamp'"), std::string::npos) << plm_last_error();
  plm_light_default(&l, PLM_LIGHT_SPOT);
  l.spot_size = -1.0f;
  EXPECT_EQ(plm_scene_add_light(s, "spot", &l, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  const float too_bright[3] = {1.5f, 0.5f, 0.5f};
  EXPECT_EQ(plm_scene_add_material(s, "hot", too_bright, black, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("albedo[0]"), std::string::npos);

  plm_result* r = nullptr;
  EXPECT_EQ(plm_bake(s, nullptr, nullptr, nullptr, &r), PLM_ERROR_INVALID_SCENE);  // no meshes were accepted
  EXPECT_NE(std::string(plm_last_error()).find("no meshes"), std::string::npos);
  EXPECT_EQ(plm_bake(nullptr, nullptr, nullptr, nullptr, &r), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_scene_add_mesh(s, "geometry", good, 4, idx, 2, nullptr, nullptr, 0, 0, nullptr), PLM_OK);
  EXPECT_EQ(plm_bake(s, nullptr, nullptr, nullptr, &r), PLM_ERROR_INVALID_SCENE);
  EXPECT_NE(std::string(plm_last_error()).find("no mesh has a lightmap"), std::string::npos);
  plm_scene_release(s);
}

std::vector<std::string> list_dir(const std::string& dir) {
  std::vector<std::string> names;
  if (DIR* d = opendir(dir.c_str())) {
    while (dirent* e = readdir(d))
      if (e->d_name[0] != '.') names.push_back(e->d_name);
    closedir(d);
  }
  return names;
}

TEST(Api, ExrIsWrittenAtomicallyAndReadsBack) {
  SceneBuilder b;
  plm_demo::build_cornell(b, 8);
  Baked r;
  bake(b, settings(20000), r);
  char tmpl[] = "/tmp/photonlm_exr_XXXXXX";
  const std::string dir = mkdtemp(tmpl);
  const std::string path = dir + "/floor.exr";
  ASSERT_EQ(plm_result_write_exr(r.r, 0, path.c_str()), PLM_OK) << plm_last_error();
  EXPECT_EQ(list_dir(dir), std::vector<std::string>{"floor.exr"});  // no temporary left
  const plm_test::ExrChannels exr = plm_test::read_exr_channels(path);
  std::vector<std::string> names;
  for (const auto& c : exr.channels) names.push_back(c.first);
  EXPECT_EQ(names, (std::vector<std::string>{"B", "G", "R", "error", "hits"}));
  const Lightmap lm = r.map(0);
  ASSERT_EQ(exr.width, int(lm.w));
  ASSERT_EQ(exr.height, int(lm.h));
  for (uint32_t y = 0; y < lm.h; ++y)  // file row 0 = top = lightmap row h - 1
    for (uint32_t x = 0; x < lm.w; ++x) {
      const size_t f = size_t(lm.h - 1 - y) * lm.w + x, t = size_t(y) * lm.w + x;
      EXPECT_EQ(exr.channels.at("R")[f], lm.rgb[3 * t]);
      EXPECT_EQ(exr.channels.at("B")[f], lm.rgb[3 * t + 2]);
      EXPECT_EQ(exr.channels.at("hits")[f], lm.hits[t]);
    }
  EXPECT_EQ(plm_result_write_exr(r.r, 0, (dir + "/missing/x.exr").c_str()), PLM_ERROR_IO);
  EXPECT_NE(std::string(plm_last_error()).find("missing/x.exr"), std::string::npos);
  EXPECT_EQ(list_dir(dir), std::vector<std::string>{"floor.exr"});
  std::remove(path.c_str());
  rmdir(dir.c_str());
}

}  // namespace

namespace {

// Accumulation is in double: 17.6 million equal hits on one texel still sum
// exactly (a float sum would stall at 2^24 hits, 16% short). The tolerance,
// 0.1 %, is about 7 standard deviations of the photon count on the plane:
// seeds 1-8 gave errors of 0.01-0.04 %, and the earlier 0.01 % failed five
// of them (it held for the default seed only).
TEST(Bake, MillionsOfHitsOnOneTexelLoseNothing) {
  SceneBuilder b;
  const uint32_t m = b.material("black", {0, 0, 0});
  b.quad("plane", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, m, 1);
  plm_light sun;
  plm_light_default(&sun, PLM_LIGHT_SUN);
  sun.power = 1.0f;
  sun.angle = 0.0f;
  b.light(sun, "sun");
  Baked r;
  bake(b, raw_photons(28000000, 0), r);  // 63% land on the plane
  const Lightmap lm = r.map(0);
  EXPECT_GT(lm.hits[0], 16777216.0f);
  EXPECT_NEAR(lm.value(0), 1.0 / M_PI, 1e-3 / M_PI);
}

// With a target error the bake stops once the estimate reaches it, and the
// estimate is honest: the measured error against the exact furnace answer is
// within a factor 1.5 of the reported one, or up to 1.75x below it at a loose
// target's first check (16,384 photons, about 19 a texel: the
// reconstruction's bias estimate is noisy and errs on the safe side).
TEST(Bake, TargetErrorIsReachedAndHonest) {
  for (double target : {0.04, 0.02}) {
    SceneBuilder b;
    const float rho = 0.6f;
    const uint32_t m = b.material("furnace", {rho, rho, rho}, {1, 1, 1});
    b.box("furnace", {0, 0, 0}, {2, 2, 2}, 0.0f, m, 12, true);
    plm_bake_settings s = settings(0);
    s.target_error = target;
    Baked r;
    bake(b, s, r);
    const plm_bake_stats st = r.stats();
    EXPECT_LE(st.error_estimate, target);
    // It stopped at the first check where the target was met (4 batches for 4 %, 16 for 2 %,
    // then every 16 batches or more).
    const uint64_t first = (target > 0.03 ? 4 : 16) * 4096;
    EXPECT_TRUE(st.photons_emitted == first || st.error_estimate > 0.5 * target) << st.photons_emitted;
    const Lightmap lm = r.map(0);
    const double exact = 1.0 / (1.0 - rho);
    double sq = 0.0, n = 0.0;
    for (size_t t = 0; t < lm.coverage.size(); ++t) {
      if (lm.coverage[t] <= 0.0f) continue;
      sq += (lm.value(t) - exact) * (lm.value(t) - exact);
      n += 1.0;
    }
    const double measured = std::sqrt(sq / n) / exact;
    EXPECT_LT(measured, 1.5 * st.error_estimate) << "target " << target;
    EXPECT_GT(measured, st.error_estimate / (target > 0.03 ? 1.75 : 1.5)) << "target " << target;
  }
}

// An 8 x 8 m grey ground (res x res texels, mesh 0) under a sun 45 degrees up.
void sunlit_ground(SceneBuilder& b, uint32_t res) {
  b.quad("ground", {-4, -4, 0}, {8, 0, 0}, {0, 8, 0}, b.material("grey", {0.5f, 0.5f, 0.5f}), res);
  b.light(plm_test::tilted_sun(4.0f, float(M_PI / 4.0)), "sun");
}

// The target holds for every object: a closed room lit by a lamp of 4 W
// stands beside a sunlit ground. Photons go by power, so the room gets few
// and its bounce light is noisy; judged with the ground's many bright texels
// its noise would hide and the bake would stop at its first check. Judged
// alone, the room's texels are gathered again with more rays (the ground's
// keep theirs) until the room, too, is under the target.
TEST(Bake, TargetHoldsForEveryObject) {
  auto scene = [](SceneBuilder& b) {
    sunlit_ground(b, 64);
    b.box("room", {8, 0, 1}, {2, 2, 2}, 0.0f, b.material("white", {0.8f, 0.8f, 0.8f}), 8, true);
    plm_light lamp;
    plm_light_default(&lamp, PLM_LIGHT_POINT);
    lamp.power = 4.0f;
    lamp.radius = 0.0f;
    lamp.matrix[3] = 8.0f, lamp.matrix[7] = 0.3f, lamp.matrix[11] = 1.6f;
    b.light(lamp, "lamp");
  };
  const double target = 0.04;
  // Each object's relative RMS error against a reference with 16x the
  // photons (its own noise left in: a quarter of the bake's adds 3 %), and
  // its own estimate; mesh 0 is the ground, mesh 1 the room.
  struct Errors {
    double estimate[2], measured[2];
  };
  auto errors = [](const Baked& r, const Baked& ref) {
    Errors e{};
    for (uint32_t mesh = 0; mesh < 2; ++mesh) {
      const Lightmap lm = r.map(mesh), rl = ref.map(mesh);
      double value = 0.0, var = 0.0, sq = 0.0, n = 0.0;
      for (size_t t = 0; t < lm.coverage.size(); ++t) {
        if (lm.coverage[t] <= 0.0f) continue;
        value += rl.value(t), n += 1.0;
        var += double(lm.error[t]) * lm.error[t];
        sq += (lm.value(t) - rl.value(t)) * (lm.value(t) - rl.value(t));
      }
      e.estimate[mesh] = std::sqrt(var / n) / (value / n);
      e.measured[mesh] = std::sqrt(sq / n) / (value / n);
    }
    return e;
  };
  SceneBuilder b, first_b, ref_b;
  scene(b), scene(first_b), scene(ref_b);
  plm_bake_settings s = settings(0);
  s.target_error = target;
  Baked r, first, ref;
  bake(b, s, r);
  const plm_bake_stats st = r.stats();
  // The bake's photons with one plain gather (16 rays a texel everywhere):
  // the whole under the target, the room above it.
  plm_bake_settings fs = s;
  fs.target_error = 0.0;
  fs.photon_count = st.photons_emitted;
  bake(first_b, fs, first);
  bake(ref_b, settings(std::max<uint64_t>(16 * st.photons_emitted, 1u << 22), 1024, 256), ref);
  const Errors e = errors(r, ref), f = errors(first, ref);
  std::printf("[ every object ] target %.3f: %llu photons, ground estimate %.4f measured %.4f, room estimate %.4f "
              "measured %.4f; whole %.4f, worst %.4f (mesh %u); one plain gather: whole %.4f, room estimate %.4f "
              "measured %.4f\n",
              target, (unsigned long long)st.photons_emitted, e.estimate[0], e.measured[0], e.estimate[1],
              e.measured[1], st.error_estimate, st.error_worst, st.error_worst_mesh, first.stats().error_estimate,
              f.estimate[1], f.measured[1]);
  EXPECT_LT(first.stats().error_estimate, target);
  EXPECT_GT(f.estimate[1], target) << "judged with the ground the room would stop above the target";
  EXPECT_LE(st.error_worst, target);
  EXPECT_EQ(st.error_worst_mesh, 1u) << "the room is the noisier object";
  EXPECT_LT(st.error_estimate, st.error_worst) << "the ground's texels are far more and cleaner";
  // The stats' worst is the room's own estimate (the images' errors are the estimate's after stitching).
  EXPECT_NEAR(e.estimate[1], st.error_worst, 0.05 * st.error_worst);
  for (int mesh = 0; mesh < 2; ++mesh) EXPECT_LT(e.measured[mesh], 1.25 * target) << "mesh " << mesh;
}

// A dim object's direct light is held to the target relative to its own
// light: a closed black room lit by 48 lamps (0.3 W in all, radius 0.3 m,
// some under a shelf) stands beside a sunlit ground. The direct pass's first
// rounds judge the room relative to a tenth of the scene's mean direct light
// (they cannot know its bounce light yet), 35 times the room's own: it
// stopped at 4.1 % measured, its estimate 55 % (the phantom sample, a typical
// one of the ground's, is most of it); now 1.4 %, estimate 2.0 %. At the photon checks, once the room's
// mean is known, it gets the samples its own mean asks for. Black walls: the
// room's light is all direct, against a reference of 1024 samples a texel.
TEST(Bake, DimObjectGetsTheDirectSamplesItsLightNeeds) {
  auto scene = [](SceneBuilder& b) {
    sunlit_ground(b, 64);
    const uint32_t black = b.material("black", {0, 0, 0});
    b.box("room", {8, 0, 1}, {2, 2, 2}, 0.0f, black, 8, true);
    b.box("shelf", {8, 0, 1}, {1.4f, 1.4f, 0.05f}, 0.0f, black, 0);
    plm::Rng rng(11, 48);
    for (int k = 0; k < 48; ++k) {
      plm_light l;
      plm_light_default(&l, PLM_LIGHT_POINT);
      l.power = 0.3f / 48.0f;
      l.radius = 0.3f;
      l.matrix[3] = float(7.2 + 1.6 * rng.next_float()), l.matrix[7] = float(-0.8 + 1.6 * rng.next_float());
      l.matrix[11] = float(k % 3 ? 1.1 + 0.8 * rng.next_float() : 0.1 + 0.8 * rng.next_float());
      b.light(l, ("lamp" + std::to_string(k)).c_str());
    }
  };
  SceneBuilder b, ref_b;
  scene(b), scene(ref_b);
  plm_bake_settings s = settings(uint64_t(4) << 20);
  s.target_error = 0.03;
  Baked r, ref;
  bake(b, s, r);
  bake(ref_b, settings(1u << 16, 1024, 1024), ref);
  const Lightmap lm = r.map(1), rl = ref.map(1), ground = ref.map(0);
  double value = 0.0, var = 0.0, sq = 0.0, n = 0.0, ground_mean = 0.0, ground_n = 0.0;
  for (size_t t = 0; t < lm.coverage.size(); ++t) {
    if (lm.coverage[t] <= 0.0f) continue;
    value += rl.value(t), n += 1.0;
    var += double(lm.error[t]) * lm.error[t];
    sq += (lm.value(t) - rl.value(t)) * (lm.value(t) - rl.value(t));
  }
  for (size_t t = 0; t < ground.coverage.size(); ++t)
    if (ground.coverage[t] > 0.0f) ground_mean += ground.value(t), ground_n += 1.0;
  const double mean = value / n, estimate = std::sqrt(var / n) / mean, measured = std::sqrt(sq / n) / mean;
  const plm_bake_stats st = r.stats();
  std::printf("[ dim object ] room mean %.4f (ground %.4f): measured %.4f, estimate %.4f; %llu direct samples, "
              "%llu photons\n",
              mean, ground_mean / ground_n, measured, estimate, (unsigned long long)st.direct_samples,
              (unsigned long long)st.photons_emitted);
  EXPECT_LT(mean, 0.05 * ground_mean / ground_n) << "the room is dim beside the ground";
  EXPECT_LT(measured, 1.25 * s.target_error);
  EXPECT_LT(measured, 1.25 * estimate) << "not under-reported";
  EXPECT_LT(estimate, 3.0 * measured) << "nor a false alarm: the phantom sample, the ground's, overstates the room";
}

// An object shut in the dark does not hold the bake: a crate in a closed
// shed beside a sunlit ground, lit only by a lamp that leaves it 10^-8 of the
// ground's light. Photons go by power, so next to none enter the shed, and
// the crate's texels keep the variance of one average sample: relative to its
// own mean the crate read 2.5 million times the target (with a warning that
// the target was not reached; in a level of 1,500 objects, where such an
// object's photon part held the error, the bake ran to the photon cap).
// Below kDarkGroupShare of the scene's mean it is dark, and the bake stops at
// the ground's target.
TEST(Bake, ObjectInTheDarkDoesNotHoldTheBake) {
  SceneBuilder b;
  sunlit_ground(b, 32);
  const uint32_t white = b.material("white", {0.8f, 0.8f, 0.8f});
  b.box("shed", {8, 0, 1}, {2, 2, 2}, 0.0f, white, 8);
  b.box("shed inside", {8, 0, 1}, {1.9f, 1.9f, 1.9f}, 0.0f, white, 8, true);
  b.box("crate", {8, 0, 0.3f}, {0.5f, 0.5f, 0.5f}, 0.0f, b.material("wood", {0.6f, 0.5f, 0.4f}), 8);
  plm_light lamp;
  plm_light_default(&lamp, PLM_LIGHT_POINT);
  lamp.power = 4e-6f;
  lamp.radius = 0.0f;
  lamp.matrix[3] = 8.0f, lamp.matrix[7] = 0.0f, lamp.matrix[11] = 1.5f;
  b.light(lamp, "lamp");
  plm_bake_settings s = settings(0);
  s.target_error = 0.05;
  s.photon_count = 8u << 20;  // the cap
  Baked r;
  bake(b, s, r);
  const plm_bake_stats st = r.stats();
  auto covered_mean = [](const Lightmap& lm) {
    double sum = 0.0, n = 0.0;
    for (size_t t = 0; t < lm.coverage.size(); ++t)
      if (lm.coverage[t] > 0.0f) sum += lm.value(t), n += 1.0;
    return sum / n;
  };
  const double crate = covered_mean(r.map(3)), ground = covered_mean(r.map(0));
  std::printf("[ dark object ] %llu photons, worst %.4f (mesh %u), crate mean %.3g of the ground's\n",
              (unsigned long long)st.photons_emitted, st.error_worst, st.error_worst_mesh, crate / ground);
  EXPECT_GT(crate, 0.0) << "the lamp lights the crate";
  EXPECT_LT(crate / ground, 1e-5);
  EXPECT_LE(st.error_worst, s.target_error);
  EXPECT_LT(st.photons_emitted, s.photon_count / 8) << "stopped at the ground's target, not at the cap";
}

// Texels inside another object are never seen and do not hold the bake: a
// crate half inside a closed building on a sunlit ground. Its inner half has
// no light, and its texels there the variance of one average photon (they
// might have had one), so judged by all its texels the crate would stay far
// above the target. The final gather finds the share of each texel light
// can reach (a ray along its normal meets a back no photon reached), and the
// error counts texels by it.
TEST(Bake, TexelsInsideAnotherObjectAreNotJudged) {
  SceneBuilder b;
  sunlit_ground(b, 32);
  b.box("building", {0, 0, 1}, {2, 2, 2}, 0.0f, b.material("white", {0.8f, 0.8f, 0.8f}), 8);
  b.box("crate", {1.0f, 0.2f, 0.3f}, {0.6f, 0.6f, 0.6f}, 0.0f, b.material("wood", {0.6f, 0.5f, 0.4f}), 8);
  plm_bake_settings s = settings(0);
  s.target_error = 0.05;
  s.photon_count = 16u << 20;  // the cap
  Baked r;
  bake(b, s, r);
  const plm_bake_stats st = r.stats();
  std::printf("[ inside ] %llu photons, worst %.4f (mesh %u)\n", (unsigned long long)st.photons_emitted,
              st.error_worst, st.error_worst_mesh);
  EXPECT_LE(st.error_worst, s.target_error);
  // Judged by all its texels, the crate took 10x the photons (655,360).
  EXPECT_LT(st.photons_emitted, 1u << 18);
}

TEST(Bake, TimeBudgetStopsTheBake) {
  SceneBuilder b;
  plm_demo::build_cornell(b, 16);
  plm_bake_settings s = settings(0);
  s.time_budget = 0.5;
  Baked r;
  bake(b, s, r);
  const plm_bake_stats st = r.stats();
  EXPECT_LT(st.seconds_total, 1.5);  // generous: noisy machines
  EXPECT_GT(st.photons_emitted, 0u);
}

}  // namespace

namespace {

// Found by the fuzzer: an area light 4e27 m wide put photon origins beyond
// Embree's range (an assertion abort). Sizes beyond the coordinate range are
// rejected, also when the matrix's scale makes them so.
TEST(Api, OversizedLightsAreRejected) {
  SceneBuilder b;
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_AREA_RECT);
  l.size_x = 4.1e27f;
  EXPECT_EQ(plm_scene_add_light(b.scene, "panel", &l, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("light 'panel': area light size"), std::string::npos)
      << plm_last_error();
  plm_light_default(&l, PLM_LIGHT_AREA_DISK);
  l.size_x = l.size_y = 1e6f;
  l.matrix[0] = l.matrix[5] = 1e7f;
  EXPECT_EQ(plm_scene_add_light(b.scene, "scaled", &l, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  plm_light_default(&l, PLM_LIGHT_POINT);
  l.radius = 1e20f;
  EXPECT_EQ(plm_scene_add_light(b.scene, "bulb", &l, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("radius"), std::string::npos);
}

}  // namespace

namespace {

// Found by the fuzzer: a UV of 1.8e31 overflowed the texel index cast.
TEST(Api, FarOutUvsAreRejected) {
  SceneBuilder b;
  const float pos[9] = {0, 0, 0, 1, 0, 0, 1, 1, 0};
  const uint32_t idx[3] = {0, 1, 2};
  const float uv[6] = {0, 0, 6.8e22f, 1.8e31f, 1, 1};
  EXPECT_EQ(plm_scene_add_mesh(b.scene, "wild", pos, 3, idx, 1, uv, nullptr, 4, 4, nullptr),
            PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("mesh 'wild': triangle 0 corner 1"), std::string::npos)
      << plm_last_error();
}

}  // namespace

namespace {

// Found by the fuzzer: an emission of 1.4e-45 (denormal) gave a triangle a
// flux that underflowed to 0; the light-choice table became 0 / 0 and the
// lightmap NaN. Emitters without flux are now left out.
TEST(Bake, DenormalEmissionIsNoLight) {
  SceneBuilder b;
  const uint32_t m = b.material("faint", {0.5f, 0.5f, 0.5f}, {0, 0, 1.4013e-45f});
  b.quad("quad", {0, 0, 0}, {1e-2f, 0, 0}, {0, 1e-2f, 0}, m, 2);
  const plm_bake_settings s = settings(1000, 16, 0);
  plm_result* r = nullptr;
  EXPECT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r), PLM_ERROR_INVALID_SCENE);
  EXPECT_NE(std::string(plm_last_error()).find("nothing lights the scene"), std::string::npos) << plm_last_error();
}

}  // namespace

namespace {

// Found by the fuzzer: a 1.1e-5 m wide emissive quad made the MIS weights
// inf / inf (cos * area underflowed): NaN texels. Weights are now ratios
// that stay finite.
TEST(Bake, NeedleEmitterGivesFiniteLight) {
  SceneBuilder b;
  const uint32_t glow = b.material("glow", {0, 0, 0}, {0, 0, 0.5f});
  b.quad("needle", {0, -3.25f, 3.875f}, {0.29913f, 0.4f, 0.99f}, {9.32746e-41f, 0, 1.10269e-05f}, glow, 8);
  Baked r;
  bake(b, settings(46, 10, 3), r);
  for (float v : r.map(0).rgb) EXPECT_TRUE(std::isfinite(v) && v >= 0.0f);
  for (float v : r.map(0).error) EXPECT_TRUE(std::isfinite(v) && v >= 0.0f);
}

}  // namespace

namespace {

// Many lights at random places, powers and heights over a black plane, few
// samples per texel: each texel's samples go to the lights that shine on it
// (relative RMS error 4.2 % with 48 lights, 5.8 % with 100, at 16 samples;
// 55 % and 68 % when the light was chosen by power alone, reported errors
// then 2x too small), and the reported error stays honest (mean squared z
// 0.6 and 1.2). Beyond 256 lights the choice is by power as before (72 % error with
// 300 lights; the bake's error is honest, texels' errors near the lights 2x
// too small: mean squared z 3.8).
TEST(Bake, ManyLightsAreChosenWhereTheyShine) {
  for (const int count : {48, 100, 300}) {
    SCOPED_TRACE(std::to_string(count) + " lights");
    SceneBuilder b;
    const uint32_t m = b.material("black", {0, 0, 0});
    b.quad("plane", {-10, -10, 0}, {20, 0, 0}, {0, 20, 0}, m, 20);
    std::vector<PointLight> points;
    plm::Rng rng(7, uint64_t(count));
    for (int k = 0; k < count; ++k)
      points.push_back({-9.0 + 18.0 * rng.next_float(), -9.0 + 18.0 * rng.next_float(), 0.5 + 2.0 * rng.next_float(),
                        100.0 * (1.0 + 9.0 * rng.next_float())});
    add_point_lights(b, points);
    auto exact = [&](double x, double y) { return point_irradiance(points, x, y) / M_PI; };
    Baked r;
    bake(b, settings(1000, 0, 16), r);
    const Lightmap lm = r.map(0);
    double squared = 0.0, z2 = 0.0, deviation = 0.0, total = 0.0;
    for (uint32_t t = 0; t < 400; ++t) {
      const double truth = texel_truth(exact, t % 20, t / 20, PLM_TEXEL_CYCLES), d = lm.value(t) - truth;
      squared += d * d / (truth * truth);
      z2 += d * d / (double(lm.error[t]) * lm.error[t]);
      deviation += d * d;
      total += truth;
    }
    // The bake's error: not too small (the phantom sample makes it 1.6-2x
    // too large at 16 samples: conservative).
    const double measured = std::sqrt(deviation / 400.0) / (total / 400.0);
    EXPECT_GT(r.stats().error_estimate, measured / 1.5);
    if (count <= 256) {
      EXPECT_LT(std::sqrt(squared / 400.0), count > 64 ? 0.10 : 0.06) << "relative RMS error";
      EXPECT_LT(z2 / 400.0, 2.0) << "mean squared z";
    }
  }
}

// The final gather's blend with the photons keeps the light: a room 4 x 4 x
// 2.5 m lit by the sun through an open window of 1.5 x 1 m. The gather and
// the photons each estimate the walls' and ceiling's bounce light without
// bias; their blend, weighted by variances taken from the same samples, must
// too. (It read 1.7-2.3 % low: near the walls each texel's own squared
// difference from the gather lowered its photons' weight exactly where their
// skewed noise ran high.)
TEST(Bake, GatherBlendKeepsTheLight) {
  SceneBuilder b;
  const uint32_t wall = b.material("wall", {0.6f, 0.6f, 0.6f}), floor = b.material("floor", {0.5f, 0.5f, 0.5f});
  b.quad("floor", {-2, -2, 0}, {4, 0, 0}, {0, 4, 0}, floor, 32);
  b.quad("ceiling", {-2, 2, 2.5f}, {4, 0, 0}, {0, -4, 0}, wall, 16);
  b.quad("wall +y", {-2, 2, 0}, {4, 0, 0}, {0, 0, 2.5f}, wall, 16);
  b.quad("wall -x", {-2, -2, 0}, {0, 4, 0}, {0, 0, 2.5f}, wall, 16);
  b.quad("wall +x", {2, 2, 0}, {0, -4, 0}, {0, 0, 2.5f}, wall, 16);
  // The window wall at y = -2, with its hole between z = 0.8 and 1.8 m.
  b.quad("below", {2, -2, 0}, {-4, 0, 0}, {0, 0, 0.8f}, wall, 8);
  b.quad("above", {2, -2, 1.8f}, {-4, 0, 0}, {0, 0, 0.7f}, wall, 8);
  b.quad("left", {2, -2, 0.8f}, {-1.25f, 0, 0}, {0, 0, 1}, wall, 8);
  b.quad("right", {-0.75f, -2, 0.8f}, {-1.25f, 0, 0}, {0, 0, 1}, wall, 8);
  b.light(plm_test::tilted_sun(3.0f, float(55.0 * M_PI / 180.0)), "sun");  // 35 degrees above the horizon
  plm_bake_settings s = settings(8000000, 1024, 64);
  s.texel_value = PLM_TEXEL_AREA;
  Baked gather, photons;
  bake(b, s, gather);
  s.photon_count = 32000000;
  s.max_bounces = 63;  // no gather
  s.filter_radius = 0;
  bake(b, s, photons);
  double sum_g = 0.0, sum_p = 0.0;
  for (uint32_t mesh = 1; mesh <= 4; ++mesh) {
    const Lightmap g = gather.map(mesh), p = photons.map(mesh);
    double mg = 0.0, mp = 0.0;
    for (size_t t = 0; t < p.coverage.size(); ++t)
      if (p.coverage[t] > 0.0f) mg += g.value(t), mp += p.value(t);
    std::printf("[ measured ] %s: gather / photons %.4f\n", b.mesh_names[mesh].c_str(), mg / mp);
    EXPECT_NEAR(mg / mp, 1.0, 0.012) << b.mesh_names[mesh];
    sum_g += mg, sum_p += mp;
  }
  EXPECT_NEAR(sum_g / sum_p, 1.0, 0.006);
}

}  // namespace

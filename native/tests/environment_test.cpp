// Environment maps as the world (scene/environment.h, plm_scene_set_world_map):
// the lookup's conventions, the sampling distribution against its own density
// and quadrature, and bakes against closed forms: a two-tone sky (upper
// hemisphere a, lower b) gives an up-facing plane a, a down-facing one b and a
// vertical one (a + b) / 2; a one-pixel sun gives the irradiance of a sun lamp
// of the same integral, shadows in the same place; a uniform map bakes as the
// uniform world; the rotation turns the light; a portal keeps the answer and
// lowers the noise; bad input is refused naming what is wrong.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <stb/stb_image_write.h>  // the implementation is compiled in image_file_test.cpp

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "demo_scenes.h"
#include "io/scene_file.h"
#include "scene/environment.h"
#include "test_support.h"
#include "util/image_file.h"
#include "util/rng.h"

namespace {

using plm::EnvironmentMap;
using plm::Vec3;
using plm_demo::SceneBuilder;
using plm_demo::V3;

// A W x H map whose upper half of rows is a, lower half b.
std::vector<float> two_tone(uint32_t w, uint32_t h, Vec3 a, Vec3 b) {
  std::vector<float> rgb(size_t(w) * h * 3);
  for (uint32_t r = 0; r < h; ++r)
    for (uint32_t c = 0; c < w; ++c) {
      const Vec3 v = r < h / 2 ? a : b;
      float* p = &rgb[(size_t(r) * w + c) * 3];
      p[0] = v.x, p[1] = v.y, p[2] = v.z;
    }
  return rgb;
}

// The direction of pixel (row, column)'s centre in the map frame.
Vec3 pixel_direction(uint32_t w, uint32_t h, uint32_t row, uint32_t column) {
  const double u = (column + 0.5) / w, v = 1.0 - (row + 0.5) / h;
  const double e = M_PI * (v - 0.5), phi = 2.0 * M_PI * (0.5 - u);
  return {float(std::cos(e) * std::cos(phi)), float(std::cos(e) * std::sin(phi)), float(std::sin(e))};
}

// The integral over the sphere of one pixel of value p under bilinear
// interpolation: a tent one pixel wide each way, in u (2 pi / W) and in
// elevation (d = pi / H), over cos(elevation) dElevation dPhi.
double pixel_integral(uint32_t w, uint32_t h, uint32_t row, double p) {
  const double d = M_PI / h, e = M_PI * (0.5 - (row + 0.5) / h);
  const double sinc = std::sin(d / 2) / (d / 2);
  return p * (2.0 * M_PI / w) * d * std::cos(e) * sinc * sinc;
}

// Per-channel mean of a lightmap's covered texels.
Vec3 mean_rgb(const plm_test::Map& m) {
  double s[3] = {0, 0, 0}, n = 0;
  for (size_t t = 0; t < m.coverage.size(); ++t) {
    if (m.coverage[t] <= 0.0f) continue;
    for (int c = 0; c < 3; ++c) s[c] += m.rgb[3 * t + size_t(c)];
    n += 1;
  }
  return {float(s[0] / n), float(s[1] / n), float(s[2] / n)};
}

plm_bake_settings direct_settings(uint32_t samples = 64) {
  plm_bake_settings s = plm_test::settings_with(20000, samples);
  s.texel_value = PLM_TEXEL_AREA;
  return s;
}

plm_bake_settings photon_settings(uint64_t photons) {
  plm_bake_settings s = plm_test::settings_with(photons, 0);
  s.texel_value = PLM_TEXEL_AREA;
  return s;
}

// A black 1 x 1 plane at the origin facing `facing` (an axis), 4 x 4 texels.
void facing_plane(SceneBuilder& b, V3 facing) {
  const uint32_t black = b.material("black", {0, 0, 0});
  V3 eu, ev;  // cross(eu, ev) = facing
  if (facing.z > 0) eu = {1, 0, 0}, ev = {0, 1, 0};
  else if (facing.z < 0) eu = {0, 1, 0}, ev = {1, 0, 0};
  else if (facing.x > 0) eu = {0, 1, 0}, ev = {0, 0, 1};
  else if (facing.x < 0) eu = {0, 0, 1}, ev = {0, 1, 0};
  else if (facing.y > 0) eu = {0, 0, 1}, ev = {1, 0, 0};
  else eu = {1, 0, 0}, ev = {0, 0, 1};
  const V3 origin{-0.5f * (eu.x + ev.x), -0.5f * (eu.y + ev.y), -0.5f * (eu.z + ev.z)};
  b.quad("plane", origin, eu, ev, black, 4);
}

// The mean RGB a plane facing `facing` bakes under the given map.
Vec3 bake_plane(V3 facing, const std::vector<float>& rgb, uint32_t w, uint32_t h, const float* rotation,
                float strength, const plm_bake_settings& s) {
  SceneBuilder b;
  facing_plane(b, facing);
  EXPECT_EQ(plm_scene_set_world_map(b.scene, rgb.data(), w, h, rotation, strength), PLM_OK) << plm_last_error();
  plm_test::BakeResult r;
  EXPECT_TRUE(b.ok()) << b.error;
  EXPECT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r.r), PLM_OK) << plm_last_error();
  return r.r ? mean_rgb(r.map(0)) : Vec3{};
}

void expect_rgb_near(Vec3 got, Vec3 want, double rel, const std::string& what) {
  EXPECT_NEAR(got.x, want.x, rel * want.x + 1e-6) << what;
  EXPECT_NEAR(got.y, want.y, rel * want.y + 1e-6) << what;
  EXPECT_NEAR(got.z, want.z, rel * want.z + 1e-6) << what;
}

// ---- The map itself -------------------------------------------------------------

TEST(EnvironmentMap, LookupFollowsBlendersEquirectangularConvention) {
  // 8 x 4 pixels, each its own value: direction -> (row, column) as Blender maps it.
  const uint32_t w = 8, h = 4;
  std::vector<float> rgb(w * h * 3);
  for (uint32_t i = 0; i < w * h; ++i) rgb[3 * i] = rgb[3 * i + 1] = rgb[3 * i + 2] = float(i + 1);
  const EnvironmentMap map(rgb.data(), w, h, nullptr, 2.0f, "test");
  for (uint32_t r = 0; r < h; ++r)
    for (uint32_t c = 0; c < w; ++c)
      EXPECT_FLOAT_EQ(map.radiance(pixel_direction(w, h, r, c)).x, 2.0f * float(r * w + c + 1)) << r << " " << c;
  // The image's centre (u = 0.5, v = 0.5: the corner of pixels (1, 3), (1, 4), (2, 3), (2, 4)) looks along +X.
  EXPECT_FLOAT_EQ(map.radiance({1, 0, 0}).x, 2.0f * (12 + 13 + 20 + 21) / 4.0f);
  // -Y is u = 0.75: between columns 5 and 6.
  EXPECT_FLOAT_EQ(map.radiance({0, -1, 0}).x, 2.0f * (14 + 15 + 22 + 23) / 4.0f);
  // The zenith: v = 1, half way between the top row and (REPEAT, as Cycles) the bottom row;
  // u = 0.5: columns 3 and 4.
  EXPECT_FLOAT_EQ(map.radiance({0, 0, 1}).x, 2.0f * (4 + 5 + 28 + 29) / 4.0f);
}

TEST(EnvironmentMap, RotationTakesTheMapFrameIntoTheWorld) {
  const uint32_t w = 16, h = 8;
  std::vector<float> rgb = two_tone(w, h, {1, 1, 1}, {0, 0, 0});
  rgb[(2 * w + 5) * 3] = 50.0f;  // a marked pixel
  const float rx[9] = {1, 0, 0, 0, 0, -1, 0, 1, 0};  // 90 degrees about X: map +Z -> world -Y
  const EnvironmentMap plain(rgb.data(), w, h, nullptr, 1.0f, "plain"), turned(rgb.data(), w, h, rx, 1.0f, "turned");
  plm::Rng rng(7, 0);
  for (int i = 0; i < 100; ++i) {
    const Vec3 d = plm::uniform_sphere(rng.next_float(), rng.next_float());
    const Vec3 world{d.x, -d.z, d.y};  // rx d
    EXPECT_NEAR(turned.radiance(world).x, plain.radiance(d).x, 1e-4f);
    EXPECT_NEAR(turned.pdf(0, world), plain.pdf(0, d), 1e-4f * plain.pdf(0, d));
  }
  // The bright upper half faces -Y (map (0.6, 0, 0.8): 53 degrees up, clear of the pole's and
  // the horizon's blends).
  EXPECT_NEAR(turned.radiance({0.6f, -0.8f, 0}).x, 1.0f, 1e-6f);
  EXPECT_NEAR(turned.radiance({0.6f, 0.8f, 0}).x, 0.0f, 1e-6f);
}

// Each part's sampling against its density and its integral, for a map with a
// sun (split in two parts) and the same map without it (one part).
void check_sampling(const EnvironmentMap& map, const std::vector<int>& parts) {
  // The integrals against a fine quadrature of the lookup (uniform in z and phi: solid angle),
  // and each density's integral (one). Jittered strata: no bias from cell edges that fall
  // between quadrature points.
  const int nz = 2048, np = 2048;
  double quad[3][3] = {}, density[3] = {};
  plm::Rng jitter(9, 0);
  for (int i = 0; i < nz; ++i)
    for (int j = 0; j < np; ++j) {
      const double z = -1.0 + 2.0 * (i + jitter.next_float()) / nz, phi = 2.0 * M_PI * (j + jitter.next_float()) / np;
      const double rho = std::sqrt(1 - z * z);
      const Vec3 d{float(rho * std::cos(phi)), float(rho * std::sin(phi)), float(z)};
      for (int part : parts) {
        const Vec3 L = map.radiance(part, d);
        quad[part][0] += L.x, quad[part][1] += L.y, quad[part][2] += L.z;
        density[part] += map.pdf(part, d);
      }
    }
  const double cell = 4.0 * M_PI / (double(nz) * np);
  for (int part : parts) {
    const Vec3 integral = map.integral(part);
    EXPECT_NEAR(integral.x, quad[part][0] * cell, 2e-3 * quad[part][0] * cell) << "part " << part;
    EXPECT_NEAR(integral.z, quad[part][2] * cell, 2e-3 * quad[part][2] * cell) << "part " << part;
    EXPECT_NEAR(density[part] * cell, 1.0, 2e-3) << "part " << part;
    // Estimates from samples: the integral (L / pdf; pdf > 0 wherever L > 0, sampling and pdf agree).
    plm::Rng rng(3, 1);
    const int n = 200000;
    double sum = 0.0, sum_sq = 0.0;
    int mismatched = 0;
    for (int i = 0; i < n; ++i) {
      float pdf = 0.0f;
      const Vec3 d = map.sample(part, rng.next_float(), rng.next_float(), pdf);
      ASSERT_GT(pdf, 0.0f);
      ASSERT_NEAR(length(d), 1.0f, 1e-5f);
      if (std::fabs(map.pdf(part, d) - pdf) > 1e-3f * pdf) ++mismatched;
      const double f = plm::average(map.radiance(part, d)) / pdf;
      sum += f;
      sum_sq += f * f;
    }
    EXPECT_LT(mismatched, n / 1000) << "part " << part;  // rounding of the place in the cell, where a corner is 0
    const double mean = sum / n, sigma = std::sqrt((sum_sq / n - mean * mean) / n);
    EXPECT_NEAR(mean, plm::average(integral), 4.0 * sigma + 1e-3 * mean) << "part " << part;
  }
}

TEST(EnvironmentMap, SamplingMatchesItsDensityAndTheIntegral) {
  // A map with a dark band and a black pixel next to bright ones, then with a hot pixel too.
  const uint32_t w = 64, h = 32;
  std::vector<float> rgb = two_tone(w, h, {1.0f, 0.8f, 0.6f}, {0.05f, 0.05f, 0.05f});
  for (int c = 0; c < 3; ++c) {
    rgb[(20 * w + 30) * 3 + size_t(c)] = 0.0f;
    for (uint32_t col = 0; col < w; ++col) rgb[(12 * w + col) * 3 + size_t(c)] = 0.0f;
  }
  const float rot[9] = {0, -1, 0, 1, 0, 0, 0, 0, 1};
  const EnvironmentMap sky(rgb.data(), w, h, rot, 1.5f, "sky");
  EXPECT_FALSE(sky.split());
  check_sampling(sky, {0});
  for (int c = 0; c < 3; ++c) rgb[(5 * w + 9) * 3 + size_t(c)] = 4000.0f;
  const EnvironmentMap sun(rgb.data(), w, h, rot, 1.5f, "sun");
  EXPECT_TRUE(sun.split());
  check_sampling(sun, {1, 2});
  // The parts add up to the map, and the sun's part lies where the sun is.
  const Vec3 total = sun.integral(1) + sun.integral(2), whole = sun.integral();
  EXPECT_FLOAT_EQ(total.x, whole.x);
  EXPECT_GT(sun.integral(1).x, 0.7f * whole.x);  // the sun holds 75 % of the red light
  const Vec3 d = pixel_direction(w, h, 5, 9), turned{-d.y, d.x, d.z};  // rot d
  EXPECT_GT(dot(sun.bright_direction(), turned), 0.999f);
  EXPECT_EQ(sun.radiance(1, turned).x, sun.radiance(turned).x);
  EXPECT_EQ(sun.radiance(2, turned).x, 0.0f);
}

TEST(EnvironmentMap, UniformMapIsSampledUniformly) {
  std::vector<float> rgb(32 * 16 * 3, 0.7f);
  const EnvironmentMap map(rgb.data(), 32, 16, nullptr, 1.0f, "test");
  plm::Rng rng(5, 0);
  for (int i = 0; i < 1000; ++i) {
    float pdf;
    map.sample(0, rng.next_float(), rng.next_float(), pdf);
    EXPECT_NEAR(pdf, 1.0 / (4.0 * M_PI), 1e-6);
  }
  EXPECT_NEAR(map.integral().x, 4.0 * M_PI * 0.7, 1e-5);
  EXPECT_NEAR(map.concentration(), 0.01, 0.005);  // the brightest 1 % of directions hold 1 % of the light
  // A one-pixel sun holding 99.9 % of the light (its four cells a third of the brightest 1 %).
  std::vector<float> sun(128 * 64 * 3, 0.01f);
  for (int c = 0; c < 3; ++c) sun[(20 * 128 + 7) * 3 + size_t(c)] = 20000.0f;
  EXPECT_GT(EnvironmentMap(sun.data(), 128, 64, nullptr, 1.0f, "sun").concentration(), 0.99f);
  // Irradiance on a surface: pi L whatever it faces.
  EXPECT_NEAR(map.irradiance(0, {0, 0, 1}).x, M_PI * 0.7, 2e-3);
  EXPECT_NEAR(map.irradiance(0, plm::normalize(Vec3{1, 2, -1})).x, M_PI * 0.7, 2e-3);
  // A two-tone map (upper 1, lower 0): pi up, 0 down, pi / 2 sideways.
  const std::vector<float> half = two_tone(64, 32, {1, 1, 1}, {0, 0, 0});
  const EnvironmentMap sky(half.data(), 64, 32, nullptr, 1.0f, "sky");
  EXPECT_NEAR(sky.irradiance(0, {0, 0, 1}).x, M_PI, 0.01);
  EXPECT_NEAR(sky.irradiance(0, {0, 0, -1}).x, 0.0, 0.01);
  EXPECT_NEAR(sky.irradiance(0, {0, 1, 0}).x, M_PI / 2, 0.01);
}

TEST(EnvironmentMap, OnePixelAndOneRowMapsAreUniformOrBands) {
  const float grey[3] = {0.4f, 0.5f, 0.6f};
  const EnvironmentMap one(grey, 1, 1, nullptr, 2.0f, "one");
  plm::Rng rng(13, 0);
  for (int i = 0; i < 200; ++i) {
    float pdf;
    const Vec3 d = one.sample(0, rng.next_float(), rng.next_float(), pdf);
    EXPECT_NEAR(pdf, 1.0 / (4.0 * M_PI), 1e-6);
    EXPECT_NEAR(one.radiance(d).y, 1.0f, 1e-6f);
  }
  // One row of two pixels: REPEAT blends the row with itself vertically, so only the azimuth varies.
  const float two[6] = {1, 1, 1, 0, 0, 0};
  const EnvironmentMap row(two, 2, 1, nullptr, 1.0f, "row");
  EXPECT_NEAR(row.integral().x, 4.0 * M_PI * 0.5, 1e-4);
  EXPECT_NEAR(row.radiance({0, 1, 0}).x, 1.0f, 1e-6f);   // u = 0.25: pixel 0's centre
  EXPECT_NEAR(row.radiance({0, -1, 0}).x, 0.0f, 1e-6f);  // u = 0.75: pixel 1's centre
  EXPECT_NEAR(row.radiance({1, 0, 0}).x, 0.5f, 1e-6f);   // u = 0.5: half way
  EXPECT_NEAR(row.radiance({0.6f, 0, 0.8f}).x, 0.5f, 1e-6f);  // up or down, the same
  float pdf;
  for (int i = 0; i < 200; ++i) {
    const Vec3 d = row.sample(0, rng.next_float(), rng.next_float(), pdf);
    EXPECT_NEAR(pdf, row.pdf(0, d), 1e-3f * pdf);
    EXPECT_GT(row.radiance(d).x, 0.0f);  // never where the map is black
  }
}

// ---- Bakes against closed forms ---------------------------------------------------

TEST(WorldMap, TwoToneSkyLightsPlanesByTheHemisphereTheySee) {
  const uint32_t w = 128, h = 64;
  const Vec3 a{1.0f, 0.8f, 0.6f}, b{0.2f, 0.25f, 0.3f};
  const std::vector<float> rgb = two_tone(w, h, a, b);
  for (int pass = 0; pass < 2; ++pass) {
    const plm_bake_settings s = pass == 0 ? direct_settings() : photon_settings(400000);
    const std::string what = pass == 0 ? "direct pass" : "photons only";
    expect_rgb_near(bake_plane({0, 0, 1}, rgb, w, h, nullptr, 1.0f, s), a, 0.01, what + ", up");
    expect_rgb_near(bake_plane({0, 0, -1}, rgb, w, h, nullptr, 1.0f, s), b, 0.01, what + ", down");
    expect_rgb_near(bake_plane({1, 0, 0}, rgb, w, h, nullptr, 1.0f, s), (a + b) * 0.5f, 0.01, what + ", +X");
    expect_rgb_near(bake_plane({0, -1, 0}, rgb, w, h, nullptr, 1.0f, s), (a + b) * 0.5f, 0.01, what + ", -Y");
  }
}

TEST(WorldMap, StrengthScalesTheMap) {
  const std::vector<float> rgb = two_tone(32, 16, {1, 1, 1}, {0, 0, 0});
  const Vec3 got = bake_plane({0, 0, 1}, rgb, 32, 16, nullptr, 2.5f, direct_settings());
  expect_rgb_near(got, {2.5f, 2.5f, 2.5f}, 0.01, "strength 2.5");
}

TEST(WorldMap, RotationTurnsTheLighting) {
  const uint32_t w = 128, h = 64;
  const Vec3 a{1, 1, 1}, b{0.1f, 0.1f, 0.1f};
  const std::vector<float> rgb = two_tone(w, h, a, b);
  const float rx[9] = {1, 0, 0, 0, 0, -1, 0, 1, 0};  // map +Z -> world -Y
  const plm_bake_settings s = direct_settings();
  expect_rgb_near(bake_plane({0, -1, 0}, rgb, w, h, rx, 1.0f, s), a, 0.01, "facing -Y");
  expect_rgb_near(bake_plane({0, 1, 0}, rgb, w, h, rx, 1.0f, s), b, 0.01, "facing +Y");
  expect_rgb_near(bake_plane({0, 0, 1}, rgb, w, h, rx, 1.0f, s), (a + b) * 0.5f, 0.01, "facing up");
}

// A one-pixel sun: the image's centre column (+X) at 30 degrees elevation,
// and where the mapping puts u = 0.75 (-Y), and turned by 90 degrees about Z.
TEST(WorldMap, OnePixelSunShinesFromWhereTheMappingPutsIt) {
  const uint32_t w = 256, h = 128;
  const uint32_t row = 42;  // elevation 90 - 180 * 42.5 / 128 = 30.2 degrees
  const double e = M_PI * (0.5 - (row + 0.5) / h);
  const double p = 5000.0;
  const double sun = pixel_integral(w, h, row, p);  // the irradiance it gives a surface facing it
  struct Case {
    uint32_t column;
    bool turned;
    V3 lit, dark;
  } cases[] = {{w / 2, false, {1, 0, 0}, {-1, 0, 0}},      // u = 0.5 + 0.5 / W: just off +X
               {3 * w / 4, false, {0, -1, 0}, {0, 1, 0}},  // u = 0.75: -Y
               {w / 2, true, {0, 1, 0}, {0, -1, 0}}};      // +X turned 90 degrees about Z: +Y
  const float rz[9] = {0, -1, 0, 1, 0, 0, 0, 0, 1};
  for (const Case& c : cases) {
    std::vector<float> rgb(size_t(w) * h * 3, 0.0f);
    for (int k = 0; k < 3; ++k) rgb[(size_t(row) * w + c.column) * 3 + size_t(k)] = float(p);
    const Vec3 d = pixel_direction(w, h, row, c.column);
    const double cos_lit = std::fabs(d.x) > std::fabs(d.y) ? std::fabs(d.x) : std::fabs(d.y);
    const plm_bake_settings s = direct_settings(256);
    const Vec3 lit = bake_plane(c.lit, rgb, w, h, c.turned ? rz : nullptr, 1.0f, s);
    const Vec3 dark = bake_plane(c.dark, rgb, w, h, c.turned ? rz : nullptr, 1.0f, s);
    const double want = sun * cos_lit / M_PI;
    EXPECT_NEAR(lit.x, want, 0.01 * want) << "column " << c.column << " turned " << c.turned;
    EXPECT_LT(dark.x, 1e-6) << "column " << c.column << " turned " << c.turned;
    const Vec3 up = bake_plane({0, 0, 1}, rgb, w, h, c.turned ? rz : nullptr, 1.0f, s);
    EXPECT_NEAR(up.x, sun * std::sin(e) / M_PI, 0.01 * sun * std::sin(e) / M_PI);
  }
}

// Ground 4 x 4 m (32 x 32 texels) with a 1 m box on it, black: direct light only.
void ground_and_box(SceneBuilder& b) {
  const uint32_t black = b.material("black", {0, 0, 0});
  b.quad("ground", {-2, -2, 0}, {4, 0, 0}, {0, 4, 0}, black, 32);
  b.box("box", {0.3f, -0.2f, 0.5f}, {1, 1, 1}, 0.3f, black, 0);
}

// Sun lamp matrix shining along -dir, of angular diameter angle.
plm_light sun_lamp(Vec3 dir, float irradiance, float angle) {
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_SUN);
  Vec3 x, y;
  plm::make_frame(dir, x, y);
  const float m[16] = {x.x, y.x, dir.x, 0, x.y, y.y, dir.y, 0, x.z, y.z, dir.z, 0, 0, 0, 0, 1};
  std::copy(m, m + 16, l.matrix);
  l.power = irradiance;
  l.angle = angle;
  return l;
}

TEST(WorldMap, SunSpotCastsTheShadowOfAnEquivalentSunLamp) {
  const uint32_t w = 512, h = 256, row = 70, column = 300;
  const double p = 20000.0;
  std::vector<float> rgb(size_t(w) * h * 3, 0.0f);
  for (int k = 0; k < 3; ++k) rgb[(size_t(row) * w + column) * 3 + size_t(k)] = float(p);
  const Vec3 dir = pixel_direction(w, h, row, column);
  const float irradiance = float(pixel_integral(w, h, row, p));
  plm_bake_settings s = direct_settings(256);
  s.texel_value = PLM_TEXEL_CYCLES;
  plm_test::Map with_map, with_lamp;
  {
    SceneBuilder b;
    ground_and_box(b);
    ASSERT_EQ(plm_scene_set_world_map(b.scene, rgb.data(), w, h, nullptr, 1.0f), PLM_OK) << plm_last_error();
    plm_test::BakeResult r;
    plm_test::bake(b, s, r);
    with_map = r.map(0);
  }
  {
    SceneBuilder b;
    ground_and_box(b);
    b.light(sun_lamp(dir, irradiance, float(M_PI / h)), "sun");  // about the tent's angular width
    plm_test::BakeResult r;
    plm_test::bake(b, s, r);
    with_lamp = r.map(0);
  }
  double sq = 0.0, sum_map = 0.0, sum_lamp = 0.0;
  size_t n = 0, shadowed = 0;
  for (size_t t = 0; t < with_map.coverage.size(); ++t) {
    const double a = with_map.value(t), b = with_lamp.value(t);
    sq += (a - b) * (a - b);
    sum_map += a, sum_lamp += b;
    if (b < 0.05 * irradiance * dir.z / M_PI) ++shadowed;
    ++n;
  }
  const double lit = irradiance * dir.z / M_PI;
  const double rel_rms = std::sqrt(sq / n) / lit;
  std::printf("[ measured ] sun spot vs sun lamp: mean ratio %.4f, RMS difference %.4f of the lit value, "
              "%zu shadowed texels\n", sum_map / sum_lamp, rel_rms, shadowed);
  EXPECT_GT(shadowed, 20u);  // the box casts a real shadow
  EXPECT_NEAR(sum_map / sum_lamp, 1.0, 0.01);
  EXPECT_LT(rel_rms, 0.03);
}

// A ground with a box under a uniform world of radiance L, set as a colour or as a map.
TEST(WorldMap, UniformMapBakesAsTheUniformWorld) {
  const float L[3] = {0.6f, 0.7f, 0.8f};
  plm_test::Map as_colour, as_map;
  const plm_bake_settings s = plm_test::settings_with(400000, 64);
  for (int k = 0; k < 2; ++k) {
    SceneBuilder b;
    const uint32_t grey = b.material("grey", {0.5f, 0.5f, 0.5f});
    b.quad("ground", {-2, -2, 0}, {4, 0, 0}, {0, 4, 0}, grey, 16);
    b.box("box", {0, 0, 0.5f}, {1, 1, 1}, 0.3f, grey, 8);
    if (k == 0) {
      ASSERT_EQ(plm_scene_set_world(b.scene, L), PLM_OK);
    } else {
      std::vector<float> rgb(64 * 32 * 3);
      for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = L[i % 3];
      ASSERT_EQ(plm_scene_set_world_map(b.scene, rgb.data(), 64, 32, nullptr, 1.0f), PLM_OK) << plm_last_error();
    }
    plm_test::BakeResult r;
    plm_test::bake(b, s, r);
    (k == 0 ? as_colour : as_map) = r.map(0);
  }
  double z2 = 0.0, sum_a = 0.0, sum_b = 0.0, var_sum = 0.0;
  size_t n = 0;
  for (size_t t = 0; t < as_colour.coverage.size(); ++t) {
    if (as_colour.coverage[t] <= 0.0f) continue;
    const double d = as_colour.value(t) - as_map.value(t);
    const double var = double(as_colour.error[t]) * as_colour.error[t] + double(as_map.error[t]) * as_map.error[t];
    z2 += d * d / var;
    var_sum += var;
    sum_a += as_colour.value(t), sum_b += as_map.value(t);
    ++n;
  }
  // The means differ by their noise: four standard errors of the difference of the means
  // (texels taken as independent; photon pooling correlates neighbours a little).
  const double tolerance = 4.0 * std::sqrt(var_sum) / double(n) / (sum_a / double(n));
  std::printf("[ measured ] uniform map vs uniform world: mean ratio %.4f (tolerance %.4f), RMS of difference / "
              "reported error %.3f\n", sum_b / sum_a, tolerance, std::sqrt(z2 / n));
  EXPECT_NEAR(sum_b / sum_a, 1.0, tolerance);
  EXPECT_LT(std::sqrt(z2 / n), 2.0);  // the difference is the noise both report
}

// ---- Portals --------------------------------------------------------------------

// The black room of portal_test.cpp: x, y in [-1, 1], z in [0, 1], a hole
// x, y in [-0.5, 0.5] in the ceiling; the floor (8 x 8 texels) is the lightmap.
void build_room(SceneBuilder& b, bool portal) {
  const uint32_t black = b.material("black", {0, 0, 0});
  b.quad("floor", {-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, black, 8);
  b.quad("ceiling_south", {-1, -1, 1}, {2, 0, 0}, {0, 0.5f, 0}, black, 0);
  b.quad("ceiling_north", {-1, 0.5f, 1}, {2, 0, 0}, {0, 0.5f, 0}, black, 0);
  b.quad("ceiling_west", {-1, -0.5f, 1}, {0.5f, 0, 0}, {0, 1, 0}, black, 0);
  b.quad("ceiling_east", {0.5f, -0.5f, 1}, {0.5f, 0, 0}, {0, 1, 0}, black, 0);
  b.quad("wall_west", {-1, -1, 0}, {0, 2, 0}, {0, 0, 1}, black, 0);
  b.quad("wall_east", {1, 1, 0}, {0, -2, 0}, {0, 0, 1}, black, 0);
  b.quad("wall_south", {1, -1, 0}, {-2, 0, 0}, {0, 0, 1}, black, 0);
  b.quad("wall_north", {-1, 1, 0}, {2, 0, 0}, {0, 0, 1}, black, 0);
  if (portal) b.light(plm_test::portal(1.0f, 1.0f, 0.0f, 1.0f), "window");
}

double overlap(double a0, double a1, double b0, double b1) { return std::fmax(0.0, std::fmin(a1, b1) - std::fmax(a0, b0)); }

// The floor's texel averages under sky radiance `sky` (upper hemisphere; the
// hole sees only it) plus a sun of irradiance `sun` from direction d through the hole.
std::vector<double> room_truth(double sky, double sun, Vec3 d) {
  std::vector<double> out = plm_test::hole_view_factors();
  const double dx = d.x / d.z, dy = d.y / d.z;  // the hole's shadow shifts by -(dx, dy) from z = 1 to 0
  for (int j = 0; j < 8; ++j)
    for (int i = 0; i < 8; ++i) {
      const double x0 = -1.0 + 0.25 * i, y0 = -1.0 + 0.25 * j;
      const double lit = overlap(x0, x0 + 0.25, -0.5 - dx, 0.5 - dx) * overlap(y0, y0 + 0.25, -0.5 - dy, 0.5 - dy) / 0.0625;
      double& v = out[size_t(j) * 8 + size_t(i)];
      v = sky * v + sun * d.z / M_PI * lit;
    }
  return out;
}

struct RoomError {
  double rms[2], ratio[2];  // without, with the portal: relative RMS error and mean ratio to the truth
};

RoomError bake_room(const std::vector<float>& rgb, uint32_t w, uint32_t h, const std::vector<double>& truth,
                    const plm_bake_settings& s, const char* what) {
  double mean_truth = 0.0;
  for (double t : truth) mean_truth += t / 64.0;
  RoomError e{};
  for (int portal = 0; portal < 2; ++portal) {
    SceneBuilder b;
    build_room(b, portal == 1);
    EXPECT_EQ(plm_scene_set_world_map(b.scene, rgb.data(), w, h, nullptr, 1.0f), PLM_OK) << plm_last_error();
    plm_test::BakeResult r;
    plm_test::bake(b, s, r);
    if (!r.r) return e;
    const plm_test::Map m = r.map(0);
    double sq = 0.0, sum = 0.0;
    for (size_t t = 0; t < 64; ++t) {
      sq += (m.value(t) - truth[t]) * (m.value(t) - truth[t]);
      sum += m.value(t);
    }
    e.rms[portal] = std::sqrt(sq / 64.0) / mean_truth;
    e.ratio[portal] = sum / 64.0 / mean_truth;
  }
  std::printf("[ measured ] %s: rel. RMSE / mean ratio: no portal %.4f / %.4f, portal %.4f / %.4f\n", what, e.rms[0],
              e.ratio[0], e.rms[1], e.ratio[1]);
  return e;
}

// Unbiased with and without the portal: four standard errors of the mean over 64
// independent texels (no filter), plus 1 % for the truth's quadrature and the sun's
// penumbra across texel edges.
void expect_unbiased(const RoomError& e, const char* what) {
  for (int portal = 0; portal < 2; ++portal)
    EXPECT_NEAR(e.ratio[portal], 1.0, 4.0 * e.rms[portal] / 8.0 + 0.01) << what << ", portal " << portal;
}

TEST(WorldMap, PortalKeepsTheSkysAnswerWithLowerError) {
  // Upper hemisphere 1, lower 0.5 (which the floor cannot see through the hole).
  const uint32_t w = 256, h = 128;
  const std::vector<float> rgb = two_tone(w, h, {1, 1, 1}, {0.5f, 0.5f, 0.5f});
  const std::vector<double> truth = room_truth(1.0, 0.0, {0, 0, 1});
  plm_bake_settings direct = direct_settings(64), photons = photon_settings(400000);
  direct.filter_radius = photons.filter_radius = 0;
  const RoomError d = bake_room(rgb, w, h, truth, direct, "two-tone map through a ceiling hole, direct (64 samples)");
  const RoomError p = bake_room(rgb, w, h, truth, photons, "two-tone map through a ceiling hole, photons (400 k)");
  expect_unbiased(d, "direct");
  expect_unbiased(p, "photons");
  EXPECT_LT(d.rms[1] * 3.0, d.rms[0]);
  // Without a portal the photons are still aimed at the floor's box (transport/lights/footprint.h).
  EXPECT_LT(p.rms[1] * 2.0, p.rms[0]);
  EXPECT_LT(d.rms[1], 0.05);
  EXPECT_LT(p.rms[1], 0.03);
}

TEST(WorldMap, PortalKeepsTheAnswerWithASunInTheMap) {
  // The sky above plus a one-pixel sun at about 70 degrees elevation, shining through the hole.
  const uint32_t w = 256, h = 128, row = 14, column = 100;
  std::vector<float> rgb = two_tone(w, h, {1, 1, 1}, {0.5f, 0.5f, 0.5f});
  const double p = 30000.0;
  for (int c = 0; c < 3; ++c) rgb[(size_t(row) * w + column) * 3 + size_t(c)] += float(p);
  const std::vector<double> truth = room_truth(1.0, pixel_integral(w, h, row, p), pixel_direction(w, h, row, column));
  plm_bake_settings direct = direct_settings(64), photons = photon_settings(1000000);
  direct.filter_radius = photons.filter_radius = 0;
  const RoomError d = bake_room(rgb, w, h, truth, direct, "sky and sun through a ceiling hole, direct (64 samples)");
  const RoomError ph = bake_room(rgb, w, h, truth, photons, "sky and sun through a ceiling hole, photons (1 M)");
  expect_unbiased(d, "direct");
  expect_unbiased(ph, "photons");
  // The sun is found by the map's samples alone, as many with the portal as without: the
  // direct pass gains only on the sky; photons through the portal carry the sun too.
  EXPECT_LT(d.rms[1], d.rms[0]);
  EXPECT_LT(ph.rms[1] * 2.0, ph.rms[0]);
}

// ---- Bad input ------------------------------------------------------------------

std::string temp_dir() {
  static const std::string dir = [] {
    std::string d = testing::TempDir() + "photonlm_world_" + std::to_string(getpid());
    ::mkdir(d.c_str(), 0700);
    return d;
  }();
  return dir;
}

bool contains(const std::string& s, const char* needle) { return s.find(needle) != std::string::npos; }

TEST(WorldMap, BadInputIsRefusedNamingWhatIsWrong) {
  plm_scene* s = nullptr;
  ASSERT_EQ(plm_scene_create(&s), PLM_OK);
  std::vector<float> rgb(8 * 4 * 3, 1.0f);
  rgb[(2 * 8 + 3) * 3 + 1] = std::nanf("");
  EXPECT_EQ(plm_scene_set_world_map(s, rgb.data(), 8, 4, nullptr, 1.0f), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(contains(plm_last_error(), "row 2, column 3")) << plm_last_error();
  rgb[(2 * 8 + 3) * 3 + 1] = -1.0f;
  EXPECT_EQ(plm_scene_set_world_map(s, rgb.data(), 8, 4, nullptr, 1.0f), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(contains(plm_last_error(), "row 2, column 3")) << plm_last_error();
  rgb[(2 * 8 + 3) * 3 + 1] = 1.0f;
  EXPECT_EQ(plm_scene_set_world_map(s, rgb.data(), 0, 4, nullptr, 1.0f), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(contains(plm_last_error(), "0 x 4")) << plm_last_error();
  EXPECT_EQ(plm_scene_set_world_map(s, nullptr, 8, 4, nullptr, 1.0f), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_scene_set_world_map(s, rgb.data(), 8, 4, nullptr, -2.0f), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(contains(plm_last_error(), "strength")) << plm_last_error();
  EXPECT_EQ(plm_scene_set_world_map(s, rgb.data(), 8, 4, nullptr, INFINITY), PLM_ERROR_INVALID_ARGUMENT);
  const float shear[9] = {1, 0.5f, 0, 0, 1, 0, 0, 0, 1};
  EXPECT_EQ(plm_scene_set_world_map(s, rgb.data(), 8, 4, shear, 1.0f), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(contains(plm_last_error(), "rotation")) << plm_last_error();
  EXPECT_EQ(plm_scene_set_world_map(nullptr, rgb.data(), 8, 4, nullptr, 1.0f), PLM_ERROR_INVALID_ARGUMENT);
  const std::string missing = temp_dir() + "/no_such_sky.exr";
  EXPECT_EQ(plm_scene_set_world_map_file(s, missing.c_str(), nullptr, 1.0f), PLM_ERROR_IO);
  EXPECT_TRUE(contains(plm_last_error(), "no_such_sky.exr")) << plm_last_error();
  EXPECT_EQ(plm_scene_set_world_map_file(s, nullptr, nullptr, 1.0f), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_scene_set_world_map_file(s, "", nullptr, 1.0f), PLM_ERROR_INVALID_ARGUMENT);
  const std::string junk = temp_dir() + "/junk.hdr";
  if (FILE* f = std::fopen(junk.c_str(), "wb")) {
    std::fputs("not an image", f);
    std::fclose(f);
  }
  EXPECT_EQ(plm_scene_set_world_map_file(s, junk.c_str(), nullptr, 1.0f), PLM_ERROR_IO);
  EXPECT_TRUE(contains(plm_last_error(), "junk.hdr")) << plm_last_error();
  plm_scene_release(s);
}

// A black map and no other light: the bake is refused as unlit, like a black world.
TEST(WorldMap, BlackMapLightsNothing) {
  SceneBuilder b;
  facing_plane(b, {0, 0, 1});
  std::vector<float> rgb(16 * 8 * 3, 0.0f);
  ASSERT_EQ(plm_scene_set_world_map(b.scene, rgb.data(), 16, 8, nullptr, 1.0f), PLM_OK);
  const plm_bake_settings s = direct_settings();
  plm_result* r = nullptr;
  EXPECT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r), PLM_ERROR_INVALID_SCENE);
  plm_result_release(r);
}

// A map's pixels (top row first) as a float EXR file.
void write_map_exr(const std::string& path, const std::vector<float>& rgb, uint32_t w, uint32_t h) {
  std::vector<float> bottom_first(rgb.size());  // write_exr_atomic takes rows bottom first
  for (uint32_t y = 0; y < h; ++y)
    std::copy_n(&rgb[size_t(h - 1 - y) * w * 3], w * 3, &bottom_first[size_t(y) * w * 3]);
  plm::write_exr_atomic(path, w, h, {"R", "G", "B"}, bottom_first.data());
}

// Files: a float EXR reads as its pixels, an 8-bit PNG sRGB-decoded; the map
// from the file bakes what the pixels bake.
TEST(WorldMap, FilesAreReadAsTheirPixels) {
  const uint32_t w = 32, h = 16;
  std::vector<float> rgb = two_tone(w, h, {1.0f, 0.5f, 0.25f}, {0.1f, 0.2f, 0.3f});
  const std::string exr = temp_dir() + "/sky.exr", png = temp_dir() + "/sky.png";
  write_map_exr(exr, rgb, w, h);
  const std::vector<uint8_t> grey(size_t(w) * h * 3, 128);
  ASSERT_TRUE(stbi_write_png(png.c_str(), int(w), int(h), 3, grey.data(), int(w) * 3));
  const EnvironmentMap from_pixels(rgb.data(), w, h, nullptr, 2.0f, "pixels");
  const EnvironmentMap from_exr = EnvironmentMap::from_file(exr, nullptr, 2.0f);
  plm::Rng rng(11, 0);
  for (int i = 0; i < 200; ++i) {
    const Vec3 d = plm::uniform_sphere(rng.next_float(), rng.next_float());
    EXPECT_EQ(from_exr.radiance(d).x, from_pixels.radiance(d).x);
    EXPECT_EQ(from_exr.radiance(d).z, from_pixels.radiance(d).z);
  }
  const EnvironmentMap from_png = EnvironmentMap::from_file(png, nullptr, 1.0f);
  const float decoded = std::pow((128.0f / 255.0f + 0.055f) / 1.055f, 2.4f);
  EXPECT_NEAR(from_png.radiance({0, 0, 1}).y, decoded, 1e-5f);
  // Through the C API: an up-facing plane bakes the upper half times the strength.
  SceneBuilder b;
  facing_plane(b, {0, 0, 1});
  ASSERT_EQ(plm_scene_set_world_map_file(b.scene, exr.c_str(), nullptr, 2.0f), PLM_OK) << plm_last_error();
  plm_test::BakeResult r;
  plm_test::bake(b, direct_settings(), r);
  expect_rgb_near(mean_rgb(r.map(0)), {2.0f, 1.0f, 0.5f}, 0.01, "EXR file");
}

// A scene file's world {"map", "rotation", "strength"}: the map relative to the file, turned and scaled.
TEST(WorldMap, SceneFileReadsAMap) {
  const uint32_t w = 32, h = 16;
  const std::vector<float> rgb = two_tone(w, h, {1, 1, 1}, {0.1f, 0.1f, 0.1f});
  const std::string exr = temp_dir() + "/file_sky.exr";
  write_map_exr(exr, rgb, w, h);
  // A plane facing -Y (front along eu x ev = (1,0,0) x (0,0,1)); the map turned so its upper half faces -Y.
  const std::string text = R"({"materials": [{"albedo": 0}],
    "meshes": [{"positions": [-0.5,0,-0.5, 0.5,0,-0.5, -0.5,0,0.5, 0.5,0,0.5], "indices": [0,1,3, 0,3,2],
                "lightmap_uv": [0,0, 1,0, 1,1, 0,0, 1,1, 0,1], "lightmap_resolution": 4}],
    "world": {"map": "file_sky.exr", "rotation": [1,0,0, 0,0,-1, 0,1,0], "strength": 3},
    "settings": {"photon_count": 10000, "direct_samples": 64, "texel_value": "AREA"}})";
  plm::SceneFile f;
  plm::SceneFileOptions options;
  options.base_dir = temp_dir();
  std::string error;
  ASSERT_TRUE(plm::parse_scene_file_text(text, options, f, error)) << error;
  plm_test::BakeResult r;
  ASSERT_EQ(plm_bake(f.scene, &f.settings, nullptr, nullptr, &r.r), PLM_OK) << plm_last_error();
  expect_rgb_near(mean_rgb(r.map(0)), {3.0f, 3.0f, 3.0f}, 0.01, "scene file map");
  options.allow_file_access = false;
  plm::SceneFile g;
  EXPECT_FALSE(plm::parse_scene_file_text(text, options, g, error));
  EXPECT_TRUE(contains(error, "scene.world.map: file access is disabled")) << error;
}

// plm_scene_set_world replaces the map and the map replaces the colour.
TEST(WorldMap, SettingTheWorldReplacesTheMapAndBack) {
  const std::vector<float> rgb = two_tone(32, 16, {1, 1, 1}, {0, 0, 0});
  const float grey[3] = {0.3f, 0.3f, 0.3f};
  SceneBuilder b;
  facing_plane(b, {0, 0, -1});
  ASSERT_EQ(plm_scene_set_world_map(b.scene, rgb.data(), 32, 16, nullptr, 1.0f), PLM_OK);
  ASSERT_EQ(plm_scene_set_world(b.scene, grey), PLM_OK);
  plm_test::BakeResult r;
  plm_test::bake(b, direct_settings(), r);
  expect_rgb_near(mean_rgb(r.map(0)), {0.3f, 0.3f, 0.3f}, 0.01, "colour after map");
  ASSERT_EQ(plm_scene_set_world_map(b.scene, rgb.data(), 32, 16, nullptr, 1.0f), PLM_OK);
  plm_test::BakeResult r2;
  plm_test::bake(b, direct_settings(), r2);
  // Facing down into the black half: only the blends at the horizon and (REPEAT, as Cycles)
  // at the nadir, where the top row bleeds in, reach it: 0.3 % of the upper half on 16 rows.
  EXPECT_LT(mean_rgb(r2.map(0)).x, 0.005f);
}

}  // namespace

// Sun and world photons aimed at what records them (transport/lights/footprint.h):
// the boxes' sampling against their projected areas, and bakes against
// closed-form irradiance, where the lightmapped object is small in a large
// scene and where its light comes only by way of geometry without a lightmap.
#include "transport/lights/footprint.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "demo_scenes.h"
#include "test_support.h"
#include "util/rng.h"

namespace {

using plm_demo::SceneBuilder;
using plm_demo::V3;

TEST(Footprint, BoxPointsCoverItsProjectedAreaUniformly) {
  const plm::Vec3 lo{-1, 0, 2}, hi{3, 0.5f, 2.25f};  // a flat box: one face pair dominates
  plm::Rng rng(7, 0);
  for (int k = 0; k < 20; ++k) {
    const plm::Vec3 d = plm::uniform_sphere(rng.next_float(), rng.next_float());
    // Every point lies on the box and on a face turned towards the line; the
    // line through it crosses the box; the projected area is the sum over the
    // faces seen (a Monte Carlo estimate: the share of a bounding square's
    // lines that cross the box).
    plm::Vec3 t, b;
    plm::make_frame(d, t, b);
    const plm::Vec3 c = (lo + hi) * 0.5f;
    const float half = 0.5f * plm::length(hi - lo);
    int crossing = 0;
    const int n = 20000;
    for (int i = 0; i < n; ++i) {
      const plm::Vec3 p = plm::point_entering_box(lo, hi, d, rng.next_float(), rng.next_float());
      ASSERT_TRUE(plm::line_crosses_box(lo - plm::Vec3{1e-4f, 1e-4f, 1e-4f}, hi + plm::Vec3{1e-4f, 1e-4f, 1e-4f}, p, d));
      const plm::Vec3 q = c + t * ((2.0f * rng.next_float() - 1.0f) * half) + b * ((2.0f * rng.next_float() - 1.0f) * half);
      crossing += plm::line_crosses_box(lo, hi, q, d);
    }
    const double estimate = 4.0 * half * half * crossing / n;
    const double area = plm::projected_area(lo, hi, d);
    EXPECT_NEAR(estimate, area, 4.0 * std::sqrt(area * (4.0 * half * half - area) / n) + 1e-3) << "direction " << k;
  }
}

plm_light sun_at(float angle, float power) {
  plm_light sun = plm_test::tilted_sun(power, angle);  // travels along (0, sin a, -cos a)
  sun.angle = 0.0f;
  return sun;
}

plm_bake_settings photons_only(uint64_t photons) {
  plm_bake_settings s = plm_test::settings_with(photons, 0);
  s.filter_radius = 0;
  s.texel_value = PLM_TEXEL_AREA;
  s.seed = 5;
  return s;
}

double mean_value(const plm_test::Map& m) {
  double sum = 0.0, area = 0.0;
  for (size_t t = 0; t < m.coverage.size(); ++t) {
    sum += m.value(t) * m.coverage[t];
    area += m.coverage[t];
  }
  return sum / area;
}

// A 0.5 m lightmapped plate facing up, 0.5 m over a black 40 x 40 m ground
// without a lightmap: its photons are the ones aimed at it.
void build_small_plate(SceneBuilder& b) {
  const uint32_t grey = b.material("grey", {0.5f, 0.5f, 0.5f});
  const uint32_t black = b.material("black", {0, 0, 0});
  b.quad("plate", {-0.25f, -0.25f, 0.5f}, {0.5f, 0, 0}, {0, 0.5f, 0}, grey, 8);
  b.quad("ground", {-20, -20, 0}, {40, 0, 0}, {0, 40, 0}, black, 0);
}

TEST(Footprint, SmallLightmappedObjectGetsMostPhotonsUnbiased) {
  const float a = float(M_PI / 6.0), S = 3.0f;
  SceneBuilder b;
  build_small_plate(b);
  b.light(sun_at(a, S), "sun");
  plm_test::BakeResult r;
  const uint64_t photons = 200000;
  plm_test::bake(b, photons_only(photons), r);
  const double exact = S * std::cos(a) / M_PI;
  const double value = mean_value(r.map(0));
  const double per_photon = double(r.stats().photon_hits) / double(r.stats().photons_emitted);
  // A disk over the scene's bounding sphere (radius: half the diagonal of 40 x 40 x 0.5 m)
  // would put the plate's projected area over pi R^2 of the photons on it.
  const double radius = 0.5 * std::sqrt(40.0 * 40.0 * 2.0 + 0.25);
  const double disk_share = 0.25 * std::cos(a) / (M_PI * radius * radius);
  std::printf("[ measured ] sun on a small plate: value / exact %.5f, hits per photon %.4f (a disk over the scene: "
              "%.6f, %.0fx fewer)\n",
              value / exact, per_photon, disk_share, per_photon / disk_share);
  EXPECT_NEAR(value / exact, 1.0, 0.01);
  // 3/4 of the photons are aimed at the plate's (padded) box and all of those hit it.
  EXPECT_GT(per_photon, 0.74);
  EXPECT_GT(per_photon / disk_share, 5000.0);

  // A uniform sky of radiance L over the plate: value L, the upper hemisphere unblocked.
  SceneBuilder sky;
  build_small_plate(sky);
  const float L[3] = {0.7f, 0.7f, 0.7f};
  ASSERT_EQ(plm_scene_set_world(sky.scene, L), PLM_OK);
  plm_test::BakeResult rs;
  plm_test::bake(sky, photons_only(400000), rs);
  const double sky_value = mean_value(rs.map(0));
  const double sky_per_photon = double(rs.stats().photon_hits) / double(rs.stats().photons_emitted);
  std::printf("[ measured ] sky on a small plate: value / exact %.5f, hits per photon %.4f\n", sky_value / L[0],
              sky_per_photon);
  EXPECT_NEAR(sky_value / L[0], 1.0, 0.02);
  EXPECT_GT(sky_per_photon, 0.3);  // half the directions come from below and meet the plate's back
}

// A plane alone under the sun: every photon lands on it (its box is the
// scene's), and each texel holds S cos(a) / pi.
TEST(Footprint, SunOnAPlaneGivesItsIrradianceFromEveryPhoton) {
  const float a = float(40.0 * M_PI / 180.0), S = 2.0f;
  SceneBuilder b;
  const uint32_t grey = b.material("grey", {0.5f, 0.5f, 0.5f});
  b.quad("plane", {-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, grey, 16);
  b.light(sun_at(a, S), "sun");
  plm_test::BakeResult r;
  plm_test::bake(b, photons_only(256 * 4000), r);
  const plm_test::Map m = r.map(0);
  const double exact = S * std::cos(a) / M_PI;
  double sq = 0.0;
  for (size_t t = 0; t < m.coverage.size(); ++t) sq += (m.value(t) / exact - 1.0) * (m.value(t) / exact - 1.0);
  const double rms = std::sqrt(sq / double(m.coverage.size()));
  const double per_photon = double(r.stats().photon_hits) / double(r.stats().photons_emitted);
  std::printf("[ measured ] sun on a plane: mean / exact %.5f, texel RMS %.4f, hits per photon %.4f\n",
              mean_value(m) / exact, rms, per_photon);
  EXPECT_NEAR(mean_value(m) / exact, 1.0, 1e-3);
  EXPECT_LT(rms, 4.0 / std::sqrt(4000.0));  // ~4000 photons a texel
  EXPECT_GT(per_photon, 0.999);
}

// Hard cases: a plane 1e5 m from the origin (the boxes' padding and the
// photons' start in float), and a sun that grazes a flat ground (its box seen
// edge-on is only the padding): the irradiance stays S cos(a) / pi, and 0
// with no NaN at grazing.
TEST(Footprint, FarFromTheOriginAndGrazingSunsStayExact) {
  for (int grazing = 0; grazing < 2; ++grazing) {
    const float a = grazing ? float(M_PI / 2.0) : float(40.0 * M_PI / 180.0), S = 2.0f;
    SceneBuilder b;
    const uint32_t grey = b.material("grey", {0.5f, 0.5f, 0.5f});
    const V3 o = grazing ? V3{-1, -1, 0} : V3{1e5f - 1, -1e5f - 1, 1e5f};
    b.quad("plane", o, {2, 0, 0}, {0, 2, 0}, grey, 8);
    b.light(sun_at(a, S), "sun");
    plm_test::BakeResult r;
    plm_test::bake(b, photons_only(100000), r);
    const plm_test::Map m = r.map(0);
    for (size_t t = 0; t < m.coverage.size(); ++t) ASSERT_TRUE(std::isfinite(m.value(t))) << "texel " << t;
    const double exact = S * std::cos(a) / M_PI;
    std::printf("[ measured ] %s: mean %.6f, exact %.6f\n", grazing ? "grazing sun" : "1e5 m from the origin",
                mean_value(m), exact);
    if (grazing) EXPECT_LT(mean_value(m), 1e-3 * S / M_PI);
    else EXPECT_NEAR(mean_value(m) / exact, 1.0, 0.01);  // the padding (a few float steps at 1.4e5 m) takes 10 % of the photons
  }
}

// A black plate facing down 0.5 m over a white 4 x 4 m ground without a
// lightmap, under a sun 30 degrees from the zenith: the plate's light comes
// only from the ground, whose photons are the quarter not aimed at the plate.
// Truth: E(p) = integral over the lit ground of L h^2 / r^4 dA, L = S cos(a) / pi
// outside the plate's shadow, by the midpoint rule.
TEST(Footprint, LightByWayOfGeometryWithoutALightmapStaysUnbiased) {
  const float a = float(M_PI / 6.0), S = 2.0f, h = 0.5f;
  SceneBuilder b;
  const uint32_t white = b.material("white", {1, 1, 1});
  const uint32_t black = b.material("black", {0, 0, 0});
  b.quad("plate", {-0.25f, -0.25f, h}, {0, 0.5f, 0}, {0.5f, 0, 0}, black, 2);
  b.quad("ground", {-2, -2, 0}, {4, 0, 0}, {0, 4, 0}, white, 0);
  b.light(sun_at(a, S), "sun");
  plm_test::BakeResult r;
  plm_test::bake(b, photons_only(3000000), r);
  const double value = mean_value(r.map(0));

  const double L = S * std::cos(a) / M_PI, shift = h * std::tan(a);
  const int n = 400, k = 4;
  double truth = 0.0;
  for (int pi = 0; pi < k; ++pi)
    for (int pj = 0; pj < k; ++pj) {
      const double px = -0.25 + 0.5 * (pi + 0.5) / k, py = -0.25 + 0.5 * (pj + 0.5) / k;
      double e = 0.0;
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
          const double x = -2.0 + 4.0 * (i + 0.5) / n, y = -2.0 + 4.0 * (j + 0.5) / n;
          if (std::fabs(x) < 0.25 && std::fabs(y - shift) < 0.25) continue;  // the plate's shadow
          const double r2 = (x - px) * (x - px) + (y - py) * (y - py) + double(h) * h;
          e += L * double(h) * h / (r2 * r2);
        }
      truth += e * (16.0 / (double(n) * n)) / M_PI / (k * k);
    }
  std::printf("[ measured ] plate lit by a ground without a lightmap: value %.5f, truth %.5f, ratio %.4f, hits %llu\n",
              value, truth, value / truth, (unsigned long long)r.stats().photon_hits);
  EXPECT_NEAR(value / truth, 1.0, 0.05);
}

}  // namespace

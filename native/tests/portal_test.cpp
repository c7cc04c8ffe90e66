// Portals (PLM_LIGHT_PORTAL): sun and sky light sampled through an opening,
// checked against the closed-form light through a hole in a black room.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "demo_scenes.h"
#include "test_support.h"

namespace {

using plm_demo::SceneBuilder;
using plm_demo::V3;

// A black room x, y in [-1, 1], z in [0, 1] whose ceiling has a hole
// x, y in [-0.5, 0.5]; the floor (8 x 8 texels) is the only lightmap.
void build_room(SceneBuilder& b) {
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
}

// A portal x in [x0, x1], y in [-0.5, 0.5] at the ceiling, facing down (-Z of its frame).
void add_portal(SceneBuilder& b, float x0, float x1) {
  b.light(plm_test::portal(x1 - x0, 1.0f, 0.5f * (x0 + x1), 1.0f), "window");
}

// Floor texel averages of the sky (radiance 1) through the hole: value = F.
std::vector<double> sky_truth() { return plm_test::hole_view_factors(); }

struct Error {
  double rms, mean_ratio;
};

Error against(const plm_test::Map& m, const std::vector<double>& truth) {
  double sq = 0.0, sum = 0.0, sum_truth = 0.0;
  for (size_t t = 0; t < truth.size(); ++t) {
    sq += (m.value(t) - truth[t]) * (m.value(t) - truth[t]);
    sum += m.value(t);
    sum_truth += truth[t];
  }
  return {std::sqrt(sq / double(truth.size())) / (sum_truth / double(truth.size())), sum / sum_truth};
}

// Four standard errors of the mean over 64 texels of this relative noise (the
// texels are independent: no filter), and 0.5 % for the quadrature of the truth.
double within_noise(const Error& e) { return 4.0 * e.rms / 8.0 + 0.005; }

void report(const char* what, const Error& none, const Error& whole, const Error& half) {
  std::printf("[ measured ] %s: rel. RMSE / mean ratio: no portal %.4f / %.4f, portal %.4f / %.4f, "
              "half portal %.4f / %.4f\n", what, none.rms, none.mean_ratio, whole.rms, whole.mean_ratio, half.rms,
              half.mean_ratio);
}

plm_bake_settings sky_settings(uint64_t photons, uint32_t direct_samples) {
  plm_bake_settings s;
  plm_bake_settings_default(&s);
  s.photon_count = photons;
  s.direct_samples = direct_samples;
  s.filter_radius = 0;
  s.texel_value = PLM_TEXEL_AREA;
  return s;
}

// portal: 0 none, 1 the whole hole, 2 only its west half.
plm_test::Map bake_sky(int portal, const plm_bake_settings& s) {
  SceneBuilder b;
  build_room(b);
  if (portal == 1) add_portal(b, -0.5f, 0.5f);
  if (portal == 2) add_portal(b, -0.5f, 0.0f);
  const float sky[3] = {1, 1, 1};
  EXPECT_EQ(plm_scene_set_world(b.scene, sky), PLM_OK);
  plm_test::BakeResult r;
  EXPECT_TRUE(b.ok()) << b.error;
  EXPECT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r.r), PLM_OK) << plm_last_error();
  return r.map(0);
}

TEST(Portal, SkyPhotonsThroughAPortalMatchTheViewFactorWithLessNoise) {
  const std::vector<double> truth = sky_truth();
  const plm_bake_settings s = sky_settings(400000, 0);  // photons only: every hit recorded
  const Error none = against(bake_sky(0, s), truth);
  const Error whole = against(bake_sky(1, s), truth);
  plm_bake_settings more = s;
  more.photon_count = 4000000;
  const Error half = against(bake_sky(2, more), truth);
  // Unbiased whatever the portal covers; the portal over the whole hole sends
  // ~90 % of the sky photons in; without it they are aimed at the floor's box
  // (transport/lights/footprint.h), whose roof lets in a smaller share.
  report("sky photons (400 k; half: 4 M)", none, whole, half);
  EXPECT_NEAR(whole.mean_ratio, 1.0, 0.01);
  EXPECT_NEAR(none.mean_ratio, 1.0, within_noise(none));
  // The half the portal misses gets only the other 10 % of the photons: noisier, still unbiased
  // (at 10x the photons).
  EXPECT_NEAR(half.mean_ratio, 1.0, within_noise(half)) << "rms " << half.rms;
  EXPECT_LT(whole.rms, 0.03);
  EXPECT_LT(whole.rms * 2.5, none.rms) << "portal " << whole.rms << " vs none " << none.rms;
}

TEST(Portal, SkyDirectLightThroughAPortalMatchesTheViewFactor) {
  const std::vector<double> truth = sky_truth();
  const plm_bake_settings s = sky_settings(20000, 64);  // black room: the direct pass is the answer
  const Error none = against(bake_sky(0, s), truth);
  const Error whole = against(bake_sky(1, s), truth);
  plm_bake_settings more = s;
  more.direct_samples = 1024;
  const Error half = against(bake_sky(2, more), truth);
  report("sky direct (64 samples; half: 1024)", none, whole, half);
  EXPECT_NEAR(whole.mean_ratio, 1.0, 0.01);
  EXPECT_NEAR(none.mean_ratio, 1.0, within_noise(none));
  EXPECT_NEAR(half.mean_ratio, 1.0, within_noise(half)) << "rms " << half.rms;
  EXPECT_LT(whole.rms, 0.03);
  EXPECT_LT(whole.rms * 3.0, none.rms) << "portal " << whole.rms << " vs none " << none.rms;
}

// The sun 20 degrees from the zenith through the hole: the floor receives the
// flux S cos(20) A_hole through it, with or without a portal.
TEST(Portal, SunThroughAPortalKeepsItsFlux) {
  for (int portal = 0; portal < 3; ++portal) {
    SceneBuilder b;
    build_room(b);
    if (portal == 1) add_portal(b, -0.5f, 0.5f);
    if (portal == 2) add_portal(b, -0.5f, 0.0f);
    const float a = float(M_PI / 9.0);
    b.light(plm_test::tilted_sun(2.0f, a), "sun");
    plm_test::BakeResult r;
    const plm_bake_settings s = sky_settings(200000, 0);
    ASSERT_TRUE(b.ok()) << b.error;
    ASSERT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r.r), PLM_OK) << plm_last_error();
    const plm_test::Map m = r.map(0);
    double flux = 0.0;
    for (size_t t = 0; t < m.coverage.size(); ++t) flux += m.value(t) * M_PI * m.coverage[t] * 0.0625;
    EXPECT_NEAR(flux, 2.0 * std::cos(a) * 1.0, 0.02 * 2.0 * std::cos(a)) << "portal case " << portal;
  }
}

TEST(Portal, BadPortalsAreRejected) {
  SceneBuilder b;
  build_room(b);
  plm_light p;
  plm_light_default(&p, PLM_LIGHT_PORTAL);
  p.size_x = 0.0f;
  uint32_t id = 0;
  EXPECT_EQ(plm_scene_add_light(b.scene, "window", &p, &id), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("portal size 0"), std::string::npos) << plm_last_error();
}

}  // namespace

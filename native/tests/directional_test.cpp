// Directional lightmaps (docs/design/directional.md): the SH L1 of a texel's
// light against analytic answers (a sun's direction, a uniform sky's
// moment), the lightmap itself unchanged by them, and bad requests refused.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "../tools/demo_scenes.h"
#include "photonlm/photonlm.h"
#include "test_support.h"

namespace {

using plm_test::BakeResult;

constexpr double kEval0 = 0.28209479177387814, kEval1 = 0.32573500793527993;  // photonlm.h's evaluation

// The four SH bands of a mesh's lightmap, and per texel and channel the
// moment D (world x, y, z) with which a surface of normal n receives V / 2 + D . n.
struct Sh {
  uint32_t w = 0, h = 0;
  std::vector<float> band[4];
  double value(size_t t, int c) const { return 2.0 * kEval0 * band[0][3 * t + c]; }
  void moment(size_t t, int c, double d[3]) const {
    d[0] = kEval1 * band[3][3 * t + c];  // L1_1: x
    d[1] = kEval1 * band[1][3 * t + c];  // L1_-1: y
    d[2] = kEval1 * band[2][3 * t + c];  // L1_0: z
  }
  // What a surface of unit normal n at texel t receives (channel c), as photonlm.h evaluates it.
  double eval(size_t t, int c, const double n[3]) const {
    return kEval0 * band[0][3 * t + c] +
           kEval1 * (band[1][3 * t + c] * n[1] + band[2][3 * t + c] * n[2] + band[3][3 * t + c] * n[0]);
  }
};

Sh sh_of(const BakeResult& r, uint32_t mesh) {
  Sh s;
  EXPECT_EQ(plm_result_lightmap_size(r.r, mesh, &s.w, &s.h), PLM_OK);
  for (uint32_t b = 0; b < 4; ++b) {
    s.band[b].resize(3 * size_t(s.w) * s.h);
    EXPECT_EQ(plm_result_copy_lightmap_sh(r.r, mesh, b, s.band[b].data()), PLM_OK) << plm_last_error();
  }
  return s;
}

// A 4 x 4 m floor (16 x 16 texels) facing +z, alone under a sun at `zenith`
// from the zenith (towards -y) and/or a uniform sky; nothing to bounce off.
void floor_scene(plm_demo::SceneBuilder& b, bool sun, double zenith, bool sky) {
  const uint32_t grey = b.material("floor", {0.5f, 0.5f, 0.5f});
  b.quad("floor", {-2, -2, 0}, {4, 0, 0}, {0, 4, 0}, grey, 16);
  if (sun) b.light(plm_test::tilted_sun(3.0f, float(zenith)), "sun");
  if (sky) {
    const float radiance[3] = {0.5f, 0.5f, 0.5f};
    EXPECT_EQ(plm_scene_set_world(b.scene, radiance), PLM_OK);
  }
}

plm_bake_settings directional_settings(uint64_t photons, uint32_t direct_samples) {
  plm_bake_settings s = plm_test::settings_with(photons, direct_samples);
  s.directional = 1;
  return s;
}

double angle_deg(const double a[3], const double b[3]) {
  const double la = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
  const double lb = std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
  const double c = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / (la * lb);
  return std::acos(std::fmax(-1.0, std::fmin(1.0, c))) * 180.0 / M_PI;
}

// Under one sun, every texel's light points at the sun: D + V n / 2 is
// along the sun's direction (a sun of direction s gives D = V (s / cos - n / 2)),
// and a tilted normal receives V (s . n') / cos + V (1 - n . n') / 2.
TEST(Directional, AFloorUnderOneSunPointsAtTheSun) {
  for (const double zenith : {0.3, 0.7, 1.2}) {
    plm_demo::SceneBuilder b;
    floor_scene(b, true, zenith, false);
    BakeResult r;
    plm_test::bake(b, directional_settings(20000, 16), r);
    ASSERT_EQ(plm_result_directional(r.r), 1u);
    const Sh sh = sh_of(r, 0);
    const double sun[3] = {0.0, -std::sin(zenith), std::cos(zenith)};
    const plm_test::Map map = r.map(0);
    double worst = 0.0, worst_tilt = 0.0;
    for (size_t t = 0; t < size_t(sh.w) * sh.h; ++t) {
      if (!(map.coverage[t] > 0.0f)) continue;
      for (int c = 0; c < 3; ++c) {
        const double v = sh.value(t, c);
        ASSERT_GT(v, 0.0);
        EXPECT_NEAR(v, map.rgb[3 * t + c], 1e-5 * v);  // L0 is the lightmap's
        double d[3];
        sh.moment(t, c, d);
        const double light[3] = {d[0], d[1], d[2] + 0.5 * v};
        worst = std::fmax(worst, angle_deg(light, sun));
        // A normal tilted 25 degrees towards the sun and one tilted away.
        for (const double tilt : {0.436, -0.436}) {
          const double n[3] = {0.0, -std::sin(tilt), std::cos(tilt)};
          const double cos_n = sun[1] * n[1] + sun[2] * n[2];  // the linear model, unclamped
          const double want = v * cos_n / std::cos(zenith) + 0.5 * v * (1.0 - n[2]);
          worst_tilt = std::fmax(worst_tilt, std::fabs(sh.eval(t, c, n) - want) / v);
        }
      }
    }
    EXPECT_LT(worst, 1.0) << "zenith " << zenith;
    EXPECT_LT(worst_tilt, 0.01) << "zenith " << zenith;
  }
}

// Under a uniform sky alone, light comes from the whole hemisphere alike:
// D = V n / 2 (no side is brighter), and a normal tilted by a receives
// V (1 + cos a) / 2, what the sky gives it exactly. Per texel the moment
// carries the samples' noise; over the floor it averages out.
TEST(Directional, AUniformSkyHasNoDirectionButItsHemisphere) {
  plm_demo::SceneBuilder b;
  floor_scene(b, false, 0.0, true);
  BakeResult r;
  plm_test::bake(b, directional_settings(20000, 256), r);
  const Sh sh = sh_of(r, 0);
  const plm_test::Map map = r.map(0);
  double sum_x = 0.0, sum_y = 0.0, sum_z = 0.0, sum_v = 0.0, sum_tilt = 0.0, sum_want = 0.0, sq_t = 0.0;
  size_t texels = 0;
  const double a = 0.5;
  const double n[3] = {std::sin(a), 0.0, std::cos(a)};
  for (size_t t = 0; t < size_t(sh.w) * sh.h; ++t) {
    if (!(map.coverage[t] > 0.0f)) continue;
    ++texels;
    for (int c = 0; c < 3; ++c) {
      double d[3];
      sh.moment(t, c, d);
      const double v = sh.value(t, c);
      sum_x += d[0], sum_y += d[1], sum_z += d[2], sum_v += v;
      sq_t += (d[0] * d[0] + d[1] * d[1]) / (v * v);
      sum_tilt += sh.eval(t, c, n);
      sum_want += v * (1.0 + std::cos(a)) / 2.0;
    }
  }
  ASSERT_GT(texels, 200u);
  EXPECT_NEAR(sum_z / sum_v, 0.5, 0.01);  // the cosine floor (split.h) moves it by 0.3 %
  EXPECT_LT(std::fabs(sum_x / sum_v), 0.01);
  EXPECT_LT(std::fabs(sum_y / sum_v), 0.01);
  EXPECT_NEAR(sum_tilt / sum_want, 1.0, 0.005);
  EXPECT_LT(std::sqrt(sq_t / double(3 * texels)), 0.1);  // a texel's own noise, 256 samples
}

// The directions are kept beside the sums: a directional bake's lightmap is
// the plain bake's bit for bit, with the gather and photons of a scene with
// indirect light.
TEST(Directional, TheLightmapIsThePlainBakesBitForBit) {
  plm_demo::SceneBuilder b;
  plm_test::open_scene(b, true, true, 16);
  ASSERT_TRUE(b.ok()) << b.error;
  plm_bake_settings s = plm_test::settings_with(200000, 16);
  BakeResult plain, directional;
  plm_test::bake(b, s, plain);
  EXPECT_EQ(plm_result_directional(plain.r), 0u);
  s.directional = 1;
  plm_test::bake(b, s, directional);
  EXPECT_EQ(plm_result_directional(directional.r), 1u);
  for (uint32_t m = 0; m < 2; ++m) {
    const plm_test::Map a = plain.map(m), c = directional.map(m);
    ASSERT_EQ(a.rgb.size(), c.rgb.size());
    EXPECT_EQ(0, std::memcmp(a.rgb.data(), c.rgb.data(), a.rgb.size() * sizeof(float))) << "mesh " << m;
    EXPECT_EQ(0, std::memcmp(a.error.data(), c.error.data(), a.error.size() * sizeof(float))) << "mesh " << m;
    // The box's faces and the ground: the moment is finite everywhere, and
    // the light's direction (D + V n / 2) leans to the sun's side on the ground.
    const Sh sh = sh_of(directional, m);
    for (uint32_t band = 0; band < 4; ++band)
      for (float v : sh.band[band]) ASSERT_TRUE(std::isfinite(v));
  }
  const Sh ground = sh_of(directional, 0);
  const plm_test::Map map = directional.map(0);
  double toward_sun = 0.0, v_sum = 0.0;
  for (size_t t = 0; t < size_t(ground.w) * ground.h; ++t) {
    if (!(map.coverage[t] > 0.0f)) continue;
    double d[3];
    ground.moment(t, 1, d);
    toward_sun += -d[1];  // the sun is towards -y
    v_sum += ground.value(t, 1);
  }
  EXPECT_GT(toward_sun / v_sum, 0.3);
}

// With glass in the scene its caustic photons have sums of their own, and
// the moments' slots hold them with the ordinary hits: a glass box on the
// floor under the sun, the floor's light still points at the sun, and L0 is
// the lightmap wherever the caustics fall.
TEST(Directional, CausticPhotonsKeepTheirDirection) {
  plm_demo::SceneBuilder b;
  floor_scene(b, true, 0.4, false);
  const uint32_t glass = b.material("glass", {0.0f, 0.0f, 0.0f});
  plm_lobe lobe;
  plm_lobe_default(&lobe, PLM_LOBE_GLASS);
  ASSERT_EQ(plm_scene_add_material_lobe(b.scene, glass, &lobe), PLM_OK) << plm_last_error();
  b.box("block", {0.5f, 0.5f, 0.6f}, {0.6f, 0.6f, 0.6f}, 0.0f, glass, 0);
  BakeResult r;
  plm_test::bake(b, directional_settings(200000, 16), r);
  const Sh sh = sh_of(r, 0);
  const plm_test::Map map = r.map(0);
  const double sun[3] = {0.0, -std::sin(0.4), std::cos(0.4)};
  double light[3] = {0, 0, 0};
  for (size_t t = 0; t < size_t(sh.w) * sh.h; ++t) {
    if (!(map.coverage[t] > 0.0f)) continue;
    for (int c = 0; c < 3; ++c) {
      const double v = sh.value(t, c);
      EXPECT_NEAR(v, map.rgb[3 * t + c], 1e-5 * v + 1e-9);
      double d[3];
      sh.moment(t, c, d);
      for (int a = 0; a < 3; ++a) ASSERT_TRUE(std::isfinite(d[a]));
      light[0] += d[0], light[1] += d[1], light[2] += d[2] + 0.5 * v;
    }
  }
  EXPECT_LT(angle_deg(light, sun), 3.0);
}

// In a furnace (a closed box whose faces all emit and reflect alike) light
// comes from everywhere alike: every texel's moment is V n / 2 (its part
// across the face 0). The final gather's rays carry the control variate of
// their directions (final_gather.cpp), so their geometric spread adds no
// noise: the parts across the faces stay within the photons' noise.
TEST(Directional, AFurnaceHasNoDirection) {
  plm_demo::SceneBuilder b;
  plm_demo::build_furnace(b, 0.5f, 1.0f, 16);
  plm_bake_settings s = directional_settings(0, 16);
  s.target_error = 0.02;
  BakeResult r;
  plm_test::bake(b, s, r);
  double sq_t = 0.0, normal = 0.0, v_sum = 0.0;
  size_t count = 0;
  for (uint32_t m = 0; m < b.mesh_names.size(); ++m) {
    const Sh sh = sh_of(r, m);
    const plm_test::Map map = r.map(m);
    for (size_t t = 0; t < size_t(sh.w) * sh.h; ++t) {
      if (!(map.coverage[t] > 0.0f)) continue;
      for (int c = 0; c < 3; ++c) {
        double d[3];
        sh.moment(t, c, d);
        const double v = sh.value(t, c);
        // The face's normal is the axis along which |D| is largest.
        int axis = 0;
        for (int a = 1; a < 3; ++a)
          if (std::fabs(d[a]) > std::fabs(d[axis])) axis = a;
        for (int a = 0; a < 3; ++a)
          if (a != axis) sq_t += d[a] * d[a] / (v * v);
        normal += std::fabs(d[axis]);
        v_sum += v;
        ++count;
      }
    }
  }
  ASSERT_GT(count, 1000u);
  EXPECT_NEAR(normal / v_sum, 0.5, 0.01);
  EXPECT_LT(std::sqrt(sq_t / double(count)), 0.05);
}

TEST(Directional, BadRequestsAreRefusedNamingWhatIsWrong) {
  plm_demo::SceneBuilder b;
  floor_scene(b, true, 0.5, false);
  BakeResult plain;
  plm_test::bake(b, plm_test::settings_with(10000, 4), plain);
  std::vector<float> rgb(3 * 16 * 16);
  EXPECT_EQ(plm_result_copy_lightmap_sh(plain.r, 0, 0, rgb.data()), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("no directional lightmaps"), std::string::npos) << plm_last_error();
  BakeResult r;
  plm_test::bake(b, directional_settings(10000, 4), r);
  EXPECT_EQ(plm_result_copy_lightmap_sh(r.r, 0, 4, rgb.data()), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("band 4"), std::string::npos) << plm_last_error();
  EXPECT_EQ(plm_result_copy_lightmap_sh(r.r, 1, 0, rgb.data()), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_result_copy_lightmap_sh(r.r, 0, 0, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  // With light groups: refused before anything is baked.
  uint32_t g = 0;
  ASSERT_EQ(plm_scene_add_light_group(b.scene, "sun", &g), PLM_OK);
  ASSERT_EQ(plm_scene_set_light_group(b.scene, 0, g), PLM_OK);
  const plm_bake_settings s = directional_settings(10000, 4);
  BakeResult refused;
  EXPECT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &refused.r), PLM_ERROR_INVALID_SCENE);
  EXPECT_NE(std::string(plm_last_error()).find("directional lightmaps"), std::string::npos) << plm_last_error();
  EXPECT_NE(std::string(plm_last_error()).find("light groups"), std::string::npos) << plm_last_error();
}

}  // namespace

// Burley's diffuse (Blender 3.x's Principled BSDF, plm_scene_set_material_diffuse)
// against truth: the law's symmetry and its known values, its directional
// albedo table against an independent quadrature in angles and its closed
// forms, and the bake of a Burley plane under the sun at grazing and under a
// uniform sky against what Cycles 3.4 bakes for it (the viewer along the
// normal: light at cos weighted by 1 - F / 2 + r (1 + cos) F, F = (1 - cos)^5).
#include <gtest/gtest.h>

#include <cmath>

#include "demo_scenes.h"
#include "test_support.h"
#include "transport/materials/bsdf.h"

namespace {

using plm_demo::SceneBuilder;
using plm_test::BakeResult;
using namespace plm::bsdf;

constexpr double kPiT = 3.14159265358979323846;

double schlick(double c) { return std::pow(1.0 - c, 5.0); }

// Burley's factor in double from the angles (Burley 2012/2015, as Cycles 3.4 writes it).
double factor(double th_l, double th_v, double dphi, double r) {
  const double cl = std::cos(th_l), cv = std::cos(th_v);
  const double ldv = std::sin(th_l) * std::sin(th_v) * std::cos(dphi) + cl * cv;
  const double fl = schlick(cl), fv = schlick(cv), rr = r * (1.0 + ldv);
  return (1.0 - 0.5 * fl) * (1.0 - 0.5 * fv) + rr * (fl + fv + fl * fv * (rr - 1.0));
}

// The directional albedo over Lambert's, integral of factor cos / pi over the hemisphere, in theta and phi.
double albedo_angles(double mu, double r) {
  constexpr int kTheta = 400, kPhi = 200;
  const double th_v = std::acos(mu);
  double sum = 0.0;
  for (int i = 0; i < kTheta; ++i) {
    const double th = (i + 0.5) * 0.5 * kPiT / kTheta;
    for (int j = 0; j < kPhi; ++j) {
      const double ph = (j + 0.5) * 2.0 * kPiT / kPhi;
      sum += factor(th, th_v, ph, r) * std::cos(th) * std::sin(th);
    }
  }
  return sum * (0.5 * kPiT / kTheta) * (2.0 * kPiT / kPhi) / kPiT;
}

TEST(Burley, TheLawIsSymmetricAndHasItsKnownValues) {
  for (double r : {0.0, 0.3, 1.0})
    for (double tl : {0.1, 0.7, 1.5})
      for (double tv : {0.0, 0.9, 1.55})
        for (double dphi : {0.0, 2.0, 3.1}) {
          const double ldv = std::sin(tl) * std::sin(tv) * std::cos(dphi) + std::cos(tl) * std::cos(tv);
          const float f = burley_factor(float(std::cos(tl)), float(std::cos(tv)), float(ldv), float(r));
          EXPECT_NEAR(f, factor(tl, tv, dphi, r), 1e-5) << tl << " " << tv << " " << dphi << " " << r;
          EXPECT_FLOAT_EQ(f, burley_factor(float(std::cos(tv)), float(std::cos(tl)), float(ldv), float(r)));
        }
  // Both along the normal: F = 0, the factor is 1 whatever the roughness (Lambert's value).
  EXPECT_FLOAT_EQ(burley_factor(1.0f, 1.0f, 1.0f, 0.7f), 1.0f);
  // Both at grazing, opposite: F = 1, R = 0: (1/2)^2.
  EXPECT_FLOAT_EQ(burley_factor(0.0f, 0.0f, -1.0f, 0.7f), 0.25f);
  // The receiving weight is the factor with the viewer along the normal.
  for (float c : {0.0f, 0.1f, 0.5f, 1.0f})
    for (float r : {0.0f, 0.5f, 1.0f}) EXPECT_FLOAT_EQ(burley_receive(c, r), burley_factor(c, 1.0f, c, r));
}

TEST(Burley, DirectionalAlbedoMatchesAQuadratureInAnglesAndItsClosedForms) {
  for (float r : {0.0f, 0.2f, 0.5f, 0.9f, 1.0f}) {
    float t[kLayerNodes];
    make_burley_albedo(r, t);
    for (int j : {0, 4, 8, 16, 24, 32}) {
      const double mu = double(j) / (kLayerNodes - 1);
      EXPECT_NEAR(t[j], albedo_angles(std::fmax(mu, 1e-6), r), 2e-3) << "roughness " << r << " cos " << mu;
    }
    // Along the normal: 1 - E[F] / 2 + r E[(1 + cos) F], E[F] = 1/21, E[cos F] = 1/84 (cosine-weighted).
    EXPECT_NEAR(t[kLayerNodes - 1], 1.0 - 1.0 / 42.0 + r * 5.0 / 84.0, 5e-4) << r;
    // Roughness 0: (1 - F(v) / 2)(1 - 1/42).
    if (r == 0.0f)
      for (int j = 0; j < kLayerNodes; ++j) {
        const double mu = double(j) / (kLayerNodes - 1);
        EXPECT_NEAR(t[j], (1.0 - 0.5 * schlick(mu)) * (1.0 - 1.0 / 42.0), 5e-4) << mu;
      }
  }
}

// A 2 m Burley plane (roughness r) lit by `sky` and a sun of strength 1 at cos_sun, direct light only.
double plane_value(float r, float cos_sun, float sky, bool burley = true) {
  SceneBuilder b;
  const uint32_t m = b.material("plane", {0.8f, 0.8f, 0.8f});
  if (burley) {
    EXPECT_EQ(plm_scene_set_material_diffuse(b.scene, m, PLM_DIFFUSE_BURLEY, r), PLM_OK) << plm_last_error();
  }
  b.quad("plane", {-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, m, 4);
  if (cos_sun > 0.0f) {
    plm_light l;
    plm_light_default(&l, PLM_LIGHT_SUN);
    l.power = 1.0f;
    l.angle = 0.0f;
    // Shining along its -Z, tilted about y: -Z = (sin, 0, -cos).
    const float s = std::sqrt(1.0f - cos_sun * cos_sun);
    const float frame[12] = {cos_sun, 0, s, 0, 0, 1, 0, 0, -s, 0, cos_sun, 0};  // rows: X Y Z axes in columns
    for (int i = 0; i < 12; ++i) l.matrix[i] = frame[i];
    b.light(l, "sun");
  }
  if (sky > 0.0f) {
    const float radiance[3] = {sky, sky, sky};
    EXPECT_EQ(plm_scene_set_world(b.scene, radiance), PLM_OK);
  }
  plm_bake_settings s = plm_test::settings_with(1000, 256, 0);
  s.seed = 3;
  BakeResult res;
  plm_test::bake(b, s, res);
  if (!res.r) return -1.0;
  const plm_test::Map map = res.map(0);
  double sum = 0.0;
  for (size_t t = 0; t < size_t(map.w) * map.h; ++t) sum += map.value(t);
  return sum / (double(map.w) * map.h);
}

TEST(Burley, ASunAtGrazingBakesAsCycles34BakesABurleySurface) {
  const float c = 0.17f;  // about 80 degrees from the normal
  const double lambert = c / kPiT;
  EXPECT_NEAR(plane_value(0.0f, c, 0.0f, false), lambert, 1e-3 * lambert);
  for (float r : {0.0f, 0.5f, 1.0f}) {
    const double want = lambert * (1.0 - 0.5 * schlick(c) + r * (1.0 + c) * schlick(c));
    EXPECT_NEAR(plane_value(r, c, 0.0f), want, 2e-3 * want) << "roughness " << r;
  }
}

TEST(Burley, AUniformSkyBakesTheDirectionalAlbedoAlongTheNormal) {
  for (float r : {0.0f, 1.0f}) {
    const double want = 1.0 - 1.0 / 42.0 + r * 5.0 / 84.0;
    EXPECT_NEAR(plane_value(r, 0.0f, 1.0f), want, 5e-3) << "roughness " << r;
  }
}

TEST(Burley, BadModelsAndRoughnessesAreRefused) {
  SceneBuilder b;
  const uint32_t m = b.material("m", {0.5f, 0.5f, 0.5f});
  EXPECT_EQ(plm_scene_set_material_diffuse(b.scene, m, 2, 0.5f), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_scene_set_material_diffuse(b.scene, m, PLM_DIFFUSE_BURLEY, 1.5f), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_scene_set_material_diffuse(b.scene, m, PLM_DIFFUSE_BURLEY, NAN), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_scene_set_material_diffuse(b.scene, m + 1, PLM_DIFFUSE_BURLEY, 0.5f), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_scene_set_material_diffuse(nullptr, m, PLM_DIFFUSE_BURLEY, 0.5f), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_scene_set_material_diffuse(b.scene, m, PLM_DIFFUSE_LAMBERT, 0.0f), PLM_OK);
}

}  // namespace

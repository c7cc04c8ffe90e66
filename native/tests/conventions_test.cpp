// Cycles versions' conventions (docs/design/cycles-versions.md) against
// closed forms: an area light's irradiance on its axis and a spot's intensity
// in and around its cone under Cycles 3.4's and Cycles 4's conventions, and
// Cycles 4's Principled specular layer (SPECULAR lobe): its tabulated albedo
// against an independent quadrature, and the white furnace of the layer over
// a white diffuse base.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "photonlm/photonlm.h"
#include "scene/scene.h"
#include "transport/lights/emitters.h"
#include "transport/materials/bsdf.h"
#include "transport/materials/material_table.h"
#include "util/math.h"

namespace plm {
namespace {

constexpr double kPiT = 3.14159265358979323846;

// A light 2 m up at the origin, shining down (-Z, Blender's default orientation).
plm_light light_above(plm_light_type type, float height) {
  plm_light l;
  plm_light_default(&l, type);
  l.power = 100.0f;
  l.radius = 0.0f;
  l.matrix[11] = height;
  return l;
}

std::vector<Emitter> emitters_of(const plm_light& l, int32_t conventions) {
  Scene scene;
  scene.set_conventions(conventions);
  scene.lights.push_back({"light", l});
  return build_emitters(scene, {0, 0, 0}, 10.0f);
}

// Mean of sample_direct's irradiance at p (normal n) over an n x n stratified grid.
double mean_irradiance(const Emitter& e, Vec3 p, Vec3 n, int grid = 256) {
  double sum = 0.0;
  for (int i = 0; i < grid; ++i)
    for (int j = 0; j < grid; ++j) {
      const float u[3] = {(i + 0.5f) / grid, (j + 0.5f) / grid, 0.5f};
      sum += average(sample_direct(e, p, n, u).irradiance);
    }
  return sum / (double(grid) * grid);
}

// A disk of radius R and radiance L, seen on its axis from distance h:
// E = pi L R^2 / (h^2 + R^2). Cycles 3.4: L = P / (4 pi R^2); Cycles 4: L = P / (pi^2 R^2).
TEST(Conventions, AreaDiskIrradianceOnItsAxis) {
  const float h = 2.0f, R = 0.5f;
  plm_light l = light_above(PLM_LIGHT_AREA_DISK, h);
  l.size_x = l.size_y = 2.0f * R;
  const double P = l.power, A = kPiT * R * R;
  const double expect34 = kPiT * (P / (4.0 * A)) * R * R / (h * h + R * R);
  const double expect4 = kPiT * (P / (kPiT * A)) * R * R / (h * h + R * R);
  const Emitter e34 = emitters_of(l, PLM_CONVENTIONS_CYCLES_3_4)[0];
  const Emitter e4 = emitters_of(l, PLM_CONVENTIONS_CYCLES_4)[0];
  EXPECT_NEAR(mean_irradiance(e34, {0, 0, 0}, {0, 0, 1}) / expect34, 1.0, 2e-3);
  EXPECT_NEAR(mean_irradiance(e4, {0, 0, 0}, {0, 0, 1}) / expect4, 1.0, 2e-3);
  // The flux: pi L A, pi P / 4 against P.
  EXPECT_NEAR(e34.flux.x, kPiT * P / 4.0, 1e-3 * P);
  EXPECT_NEAR(e4.flux.x, P, 1e-3 * P);
  EXPECT_NEAR(e34.radiance.x, P / (4.0 * A), 1e-4 * P);
  EXPECT_NEAR(e4.radiance.x, P / (kPiT * A), 1e-4 * P);
}

// A square of half side a at distance h on its axis: E = 4 L (a / sqrt(a^2 + h^2)) atan(a / sqrt(a^2 + h^2))
// (the form factor of a rectangle from a point on its corner normal, four corners).
TEST(Conventions, AreaSquareIrradianceOnItsAxis) {
  const float h = 1.5f, a = 0.5f;
  plm_light l = light_above(PLM_LIGHT_AREA_RECT, h);
  l.size_x = l.size_y = 2.0f * a;
  const double P = l.power, A = 4.0 * a * a;
  const double c = a / std::sqrt(double(a) * a + double(h) * h);
  const double per_radiance = 4.0 * c * std::atan(c);  // E / L
  for (int32_t conv : {PLM_CONVENTIONS_CYCLES_3_4, PLM_CONVENTIONS_CYCLES_4}) {
    const double L = conv == PLM_CONVENTIONS_CYCLES_4 ? P / (kPiT * A) : P / (4.0 * A);
    const Emitter e = emitters_of(l, conv)[0];
    EXPECT_NEAR(mean_irradiance(e, {0, 0, 0}, {0, 0, 1}) / (L * per_radiance), 1.0, 2e-3) << conv;
  }
  // Cycles 3.4 over Cycles 4: pi / 4, the ratio the two Blenders' bakes show.
  EXPECT_NEAR(emitters_of(l, PLM_CONVENTIONS_CYCLES_3_4)[0].radiance.x /
                  emitters_of(l, PLM_CONVENTIONS_CYCLES_4)[0].radiance.x,
              kPiT / 4.0, 1e-5);
}

double smoothstep(double x) { return x <= 0.0 ? 0.0 : x >= 1.0 ? 1.0 : x * x * (3.0 - 2.0 * x); }

// A spot of cone angle 120 degrees, blend 0.3, radius 0: the intensity
// d^2 E toward a receiver facing it at angle theta from the axis is
// P / (4 pi) x [cos theta] x smoothstep((cos theta - cos 60) / ((1 - cos 60) blend)),
// the cosine factor only under Cycles 3.4.
TEST(Conventions, SpotIntensityShape) {
  plm_light l = light_above(PLM_LIGHT_SPOT, 0.0f);
  l.spot_size = float(kPiT * 120.0 / 180.0);
  l.spot_blend = 0.3f;
  const double P = l.power, cos_half = std::cos(0.5 * l.spot_size);
  const Emitter e34 = emitters_of(l, PLM_CONVENTIONS_CYCLES_3_4)[0];
  const Emitter e4 = emitters_of(l, PLM_CONVENTIONS_CYCLES_4)[0];
  const double d = 3.0;
  for (double deg : {0.0, 20.0, 40.0, 50.0, 55.0, 58.0, 59.5, 61.0, 80.0}) {
    const double th = deg * kPiT / 180.0;
    const Vec3 w{float(std::sin(th)), 0.0f, float(-std::cos(th))};  // from the light, below it
    const Vec3 p = w * float(d);
    const Vec3 n = -w;
    const double shape = smoothstep((std::cos(th) - cos_half) / ((1.0 - cos_half) * l.spot_blend));
    const float u[3] = {0.5f, 0.5f, 0.5f};
    const double i34 = average(sample_direct(e34, p, n, u).irradiance) * d * d;
    const double i4 = average(sample_direct(e4, p, n, u).irradiance) * d * d;
    EXPECT_NEAR(i34, P / (4.0 * kPiT) * std::cos(th) * shape, 1e-4 * P) << deg;
    EXPECT_NEAR(i4, P / (4.0 * kPiT) * shape, 1e-4 * P) << deg;
  }
  // The flux without blend is the intensity over the cone: P / (4 pi) 2 pi (1 - cos 60) = P / 4
  // (Cycles 4); with the cosine factor P / (4 pi) pi (1 - cos^2 60) = 3 P / 16 (Cycles 3.4).
  l.spot_blend = 0.0f;
  EXPECT_NEAR(emitters_of(l, PLM_CONVENTIONS_CYCLES_4)[0].flux.x, P / 4.0, 1e-3 * P);
  EXPECT_NEAR(emitters_of(l, PLM_CONVENTIONS_CYCLES_3_4)[0].flux.x, 3.0 * P / 16.0, 1e-3 * P);
}

// Point and sun lights are the same under both conventions, bit for bit.
TEST(Conventions, PointAndSunDoNotChange) {
  for (plm_light_type t : {PLM_LIGHT_POINT, PLM_LIGHT_SUN}) {
    plm_light l = light_above(t, 2.0f);
    l.radius = 0.1f;
    const Emitter a = emitters_of(l, PLM_CONVENTIONS_CYCLES_3_4)[0];
    const Emitter b = emitters_of(l, PLM_CONVENTIONS_CYCLES_4)[0];
    EXPECT_EQ(a.flux.x, b.flux.x);
    EXPECT_EQ(a.radiance.x, b.radiance.x);
  }
}

TEST(Conventions, UnknownValuesAreRefused) {
  plm_scene* s = nullptr;
  ASSERT_EQ(plm_scene_create(&s), PLM_OK);
  int32_t c = -1;
  ASSERT_EQ(plm_scene_get_conventions(s, &c), PLM_OK);
  EXPECT_EQ(c, PLM_CONVENTIONS_CYCLES_3_4);
  EXPECT_EQ(plm_scene_set_conventions(s, 7), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("conventions"), std::string::npos);
  ASSERT_EQ(plm_scene_set_conventions(s, PLM_CONVENTIONS_CYCLES_4), PLM_OK);
  ASSERT_EQ(plm_scene_get_conventions(s, &c), PLM_OK);
  EXPECT_EQ(c, PLM_CONVENTIONS_CYCLES_4);
  plm_scene_release(s);
}

bsdf::LobeParams specular(float roughness, float ior, Vec3 f0) {
  Lobe l;
  l.type = PLM_LOBE_SPECULAR;
  l.roughness = roughness;
  l.ior = ior;
  l.color = f0;
  return bsdf::lobe_params(l);
}

// Integral over the hemisphere of eval_lobe(v, l).f_cos = f(v, l) cos(l), by
// a (theta, phi) midpoint rule fine enough for roughness >= 0.2.
double hemisphere_albedo(const bsdf::LobeParams& p, Vec3 v) {
  const int nt = 512, np = 512;
  double sum = 0.0;
  for (int i = 0; i < nt; ++i) {
    const double th = (i + 0.5) / nt * 0.5 * kPiT;
    for (int j = 0; j < np; ++j) {
      const double ph = (j + 0.5) / np * 2.0 * kPiT;
      const Vec3 l{float(std::sin(th) * std::cos(ph)), float(std::sin(th) * std::sin(ph)), float(std::cos(th))};
      sum += average(bsdf::eval_lobe(p, v, l, true, p.ior).f_cos) * std::sin(th);
    }
  }
  return sum * (0.5 * kPiT / nt) * (2.0 * kPiT / np);
}

// E (single scattering, Fresnel 1) against the quadrature of the lobe with F0 = 1.
TEST(SpecularLayer, SingleScatteringAlbedoMatchesQuadrature) {
  float previous = 1.0f;
  for (float rough : {0.3f, 0.6f, 1.0f}) {
    const bsdf::LobeParams p = specular(rough, 1.5f, {1, 1, 1});
    const bsdf::LayerTable t = bsdf::make_layer_table(p);
    for (double mu : {0.15, 0.5, 0.9}) {
      const Vec3 v{float(std::sqrt(1.0 - mu * mu)), 0.0f, float(mu)};
      EXPECT_NEAR(bsdf::layer_lookup(t.E, float(mu)), hemisphere_albedo(p, v), 1e-2)
          << rough << " " << mu;
    }
    // GGX loses energy to single scattering, more the rougher it is (none when smooth).
    EXPECT_LT(t.E[bsdf::kLayerNodes - 1], previous);
    previous = t.E[bsdf::kLayerNodes - 1];
  }
  const bsdf::LayerTable smooth = bsdf::make_layer_table(specular(0.0f, 1.5f, {0.04f, 0.04f, 0.04f}));
  EXPECT_EQ(smooth.E[5], 1.0f);
  // Smooth: A is the Fresnel curve itself, 0.04 at normal incidence.
  EXPECT_NEAR(smooth.A[bsdf::kLayerNodes - 1], 0.04f, 1e-6f);
}

// The white furnace of Cycles 4's Principled BSDF without metal or glass:
// a white diffuse base under the specular layer reflects, toward any v,
// (1 - A(v)) from the base plus the compensated layer's albedo, which the
// table's A estimates: the sum stays near 1 and never much above it.
TEST(SpecularLayer, WhiteFurnaceOfTheLayeredStack) {
  for (float rough : {0.2f, 0.5f, 0.8f}) {
    for (float ior : {1.33f, 1.5f, 2.0f}) {
      const float F0 = float(std::pow((ior - 1.0) / (ior + 1.0), 2.0));
      const bsdf::LobeParams p = specular(rough, ior, {F0, F0, F0});
      const bsdf::LayerTable t = bsdf::make_layer_table(p);
      for (double mu : {0.2, 0.5, 0.8, 1.0}) {
        const Vec3 v{float(std::sqrt(1.0 - mu * mu)), 0.0f, float(mu)};
        const double spec = hemisphere_albedo(p, v) * t.compensation(float(mu)).x;
        const double a = t.albedo(float(mu));
        // A is Cycles' estimate (E x the mean Fresnel rise, not the mean of their product):
        // within 8 % of the compensated layer's albedo, closest toward normal incidence.
        EXPECT_NEAR(spec, a, 0.08 * a + 2e-3) << rough << " " << ior << " " << mu;
        const double total = spec + (1.0 - a);
        EXPECT_LE(total, 1.01) << rough << " " << ior << " " << mu;
        EXPECT_GE(total, 0.97) << rough << " " << ior << " " << mu;
      }
    }
  }
}

// The material table: one SPECULAR layer scales the diffuse part by exactly 1 - A;
// layer_mean is that scale's cosine-weighted mean; materials without one keep 1.
TEST(SpecularLayer, MaterialTableScalesTheDiffusePart) {
  Scene scene;
  const float white[3] = {1, 1, 1}, black[3] = {0, 0, 0};
  scene.add_material("plain", white, black);
  scene.add_material("layered", white, black);
  plm_lobe l;
  plm_lobe_default(&l, PLM_LOBE_SPECULAR);
  l.color[0] = l.color[1] = l.color[2] = 0.04f;
  l.roughness = 0.5f;
  l.ior = 1.5f;
  scene.add_material_lobe(1, l);
  const MaterialTable table(scene);
  EXPECT_EQ(table.material(0).layer_scale, MaterialLobes::kNoLayer);
  EXPECT_EQ(table.material(0).layer_mean, 1.0f);
  const MaterialLobes& m = table.material(1);
  ASSERT_NE(m.layer_scale, MaterialLobes::kNoLayer);
  const bsdf::LayerTable& t = table.layer(m.first);
  double mean = 0.0;
  const int n = 2000;
  for (int i = 0; i < n; ++i) {
    const float mu = (i + 0.5f) / n;
    EXPECT_NEAR(table.diffuse_scale(m.layer_scale, mu), 1.0f - t.albedo(mu), 1e-6f);
    mean += 2.0 * table.diffuse_scale(m.layer_scale, mu) * mu / n;
  }
  EXPECT_NEAR(m.layer_mean, mean, 1e-3);
  EXPECT_GT(m.layer_mean, 0.8f);
  EXPECT_LT(m.layer_mean, 0.96f);
}

}  // namespace
}  // namespace plm

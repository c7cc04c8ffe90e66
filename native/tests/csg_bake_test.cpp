// CSG solids in the bake, through the C API: traced exactly, their light
// gathered on their own (split) texels and handed to a carrier mesh's
// lightmap. Checked against energy balance and closed forms.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "demo_scenes.h"
#include "test_support.h"

namespace {

using plm_demo::SceneBuilder;
using plm_demo::V3;
using Baked = plm_test::BakeResult;

constexpr uint32_t kNode = sizeof(plm_csg_node);  // every node's struct_size

plm_csg_primitive prim(plm_csg_shape shape, double scale, V3 at, uint32_t material) {
  plm_csg_primitive p = plm_test::sized<plm_csg_primitive>();
  p.shape = shape;
  p.material = material;
  const double m[12] = {scale, 0, 0, at.x, 0, scale, 0, at.y, 0, 0, scale, at.z};
  for (int i = 0; i < 12; ++i) p.matrix[i] = m[i];
  p.major_radius = 1.0;
  p.minor_radius = 0.25;
  return p;
}

// Solid = primitive a minus primitive b (nodes: difference, leaf a, leaf b).
uint32_t add_difference(SceneBuilder& b, const char* name, plm_csg_primitive a, plm_csg_primitive c) {
  const plm_csg_primitive prims[2] = {a, c};
  const plm_csg_node nodes[3] = {
      {kNode, PLM_CSG_DIFFERENCE, 0, 2}, {kNode, PLM_CSG_LEAF, 0, 0}, {kNode, PLM_CSG_LEAF, 1, 0}};
  const uint32_t children[2] = {1, 2};
  uint32_t id = 99;
  EXPECT_EQ(plm_scene_add_csg(b.scene, name, prims, 2, nodes, 3, children, 2, 0, &id), PLM_OK) << plm_last_error();
  return id;
}

plm_bake_settings settings(uint64_t photons, uint32_t direct_samples) {
  return plm_test::settings_with(photons, direct_samples);
}

double recorded_flux(const plm_test::Map& m, double world_area_per_texel) {
  double sum = 0.0;
  for (size_t t = 0; t < m.coverage.size(); ++t)
    if (m.coverage[t] > 0) sum += m.value(t) * M_PI * m.coverage[t] * world_area_per_texel;
  return sum;
}

// A black CSG shell (box 2 minus box 1.5, half sizes) around a point light:
// every photon is absorbed at its first hit on the cavity wall, so the carrier
// (the cavity's inward box mesh, not traced) records the light's power P, in
// both modes; nothing leaks out.
TEST(CsgBake, BlackShellAroundPointLightHoldsItsPower) {
  for (const uint32_t direct : {0u, 16u}) {
    SceneBuilder b;
    const uint32_t black = b.material("black", {0, 0, 0});
    const uint32_t shell = add_difference(b, "shell", prim(PLM_CSG_BOX, 2.0, {0, 0, 0}, black),
                                          prim(PLM_CSG_BOX, 1.5, {0, 0, 0}, black));
    const uint32_t face_res = 8;
    const uint32_t carrier = b.box("cavity", {0, 0, 0}, {3, 3, 3}, 0.0f, black, face_res, true);
    ASSERT_EQ(plm_scene_set_csg_carrier(b.scene, shell, carrier), PLM_OK) << plm_last_error();
    // An outside plane: no light may reach it through the shell.
    const uint32_t outside = b.quad("outside", {-5, -5, -3}, {10, 0, 0}, {0, 10, 0}, black, 8);
    plm_light l;
    plm_light_default(&l, PLM_LIGHT_POINT);
    l.power = 100.0f;
    l.radius = 0.0f;
    l.matrix[3] = 0.2f, l.matrix[7] = -0.1f, l.matrix[11] = 0.3f;
    b.light(l, "bulb");
    Baked r;
    ASSERT_TRUE(b.ok()) << b.error;
    const plm_bake_settings s = settings(400000, direct);
    ASSERT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r.r), PLM_OK)
        << plm_last_error();
    const plm_test::Map cav = r.map(carrier);
    // The box builder leaves a one-texel margin: 6 x 6 covered texels per 3 x 3 m face.
    const double flux = recorded_flux(cav, 9.0 / 36.0);
    std::printf("[ measured ] black shell (direct samples %u): carrier records %.4f W of 100 W\n", direct, flux);
    EXPECT_NEAR(flux, 100.0, 2.0) << "direct samples " << direct;
    const plm_test::Map out = r.map(outside);
    double outside_max = 0.0;
    for (size_t t = 0; t < out.coverage.size(); ++t) outside_max = std::max(outside_max, out.value(t));
    EXPECT_EQ(outside_max, 0.0) << "light leaked through the shell";
  }
}

// Two chambers cut out of one block with a 1 mm wall between them (block
// minus two boxes): a light in chamber A leaves chamber B exactly dark; the
// photons do land on chamber A's walls.
TEST(CsgBake, ThinWallStopsAllPhotons) {
  SceneBuilder b;
  const uint32_t grey = b.material("grey", {0.5f, 0.5f, 0.5f});
  plm_csg_primitive prims[3] = {prim(PLM_CSG_BOX, 1.0, {0, 0, 0}, grey), prim(PLM_CSG_BOX, 1.0, {0, 0, 0}, grey),
                                prim(PLM_CSG_BOX, 1.0, {0, 0, 0}, grey)};
  // Block [-2, 2] x [-1, 1] x [-1, 1]; chamber A x in [-1.9, -0.0005], chamber B x in [0.0005, 1.9].
  const double block[12] = {2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
  const double a[12] = {0.94975, 0, 0, -0.95025, 0, 0.9, 0, 0, 0, 0, 0.9, 0};
  const double c[12] = {0.94975, 0, 0, 0.95025, 0, 0.9, 0, 0, 0, 0, 0.9, 0};
  std::copy(block, block + 12, prims[0].matrix);
  std::copy(a, a + 12, prims[1].matrix);
  std::copy(c, c + 12, prims[2].matrix);
  const plm_csg_node nodes[4] = {{kNode, PLM_CSG_DIFFERENCE, 0, 3}, {kNode, PLM_CSG_LEAF, 0, 0},
                                 {kNode, PLM_CSG_LEAF, 1, 0}, {kNode, PLM_CSG_LEAF, 2, 0}};
  const uint32_t kids[3] = {1, 2, 3};
  uint32_t solid = 0;
  ASSERT_EQ(plm_scene_add_csg(b.scene, "block", prims, 3, nodes, 4, kids, 3, 0, &solid), PLM_OK) << plm_last_error();
  // The carrier is chamber B's inward box: the dark side, checked texel by texel.
  const uint32_t chamber_b = b.box("chamber B", {0.95025f, 0, 0}, {1.8995f, 1.8f, 1.8f}, 0.0f, grey, 8, true);
  ASSERT_EQ(plm_scene_set_csg_carrier(b.scene, solid, chamber_b), PLM_OK) << plm_last_error();
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_POINT);
  l.power = 1000.0f;
  l.radius = 0.0f;
  l.matrix[3] = -0.95f;  // in chamber A
  b.light(l, "bulb");
  ASSERT_TRUE(b.ok()) << b.error;
  for (const uint32_t direct : {0u, 16u}) {
    const plm_bake_settings s = settings(300000, direct);
    Baked r;
    ASSERT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r.r), PLM_OK) << plm_last_error();
    const plm_test::Map m = r.map(chamber_b);
    double worst = 0.0, hits = 0.0;
    for (size_t t = 0; t < m.coverage.size(); ++t) {
      worst = std::max(worst, m.value(t));
      hits += m.hits[t];
    }
    EXPECT_EQ(worst, 0.0) << "light crossed the 1 mm wall (direct samples " << direct << ")";
    EXPECT_EQ(hits, 0.0);
    EXPECT_GT(r.stats().photon_hits, 0u) << "photons did land in chamber A's walls";
  }
}

// A CSG sphere (radius 1) lit by the sun straight from above, direct light
// only: a carrier texel at normal n holds S max(0, n_z) / pi. The carrier is a
// UV sphere; its texel normals come from its lightmap layout (latitude-
// longitude), so the check uses the texel centre's direction.
TEST(CsgBake, SphereUnderTheSunIsCosineOverPi) {
  SceneBuilder b;
  const uint32_t grey = b.material("grey", {0.5f, 0.5f, 0.5f});
  const plm_csg_primitive ball = prim(PLM_CSG_SPHERE, 1.0, {0, 0, 0}, grey);
  const plm_csg_node leaf = {kNode, PLM_CSG_LEAF, 0, 0};
  uint32_t solid = 0;
  ASSERT_EQ(plm_scene_add_csg(b.scene, "ball", &ball, 1, &leaf, 1, nullptr, 0, 0, &solid), PLM_OK) << plm_last_error();
  // Carrier: a 64 x 32 latitude-longitude sphere, u = longitude, v = latitude.
  const uint32_t nu = 64, nv = 32;
  const double centre[3] = {0, 0, 0};
  const uint32_t carrier = plm_test::add_latlong_sphere(b.scene, "ball mesh", centre, 1.0, nu, nv, grey);
  ASSERT_EQ(plm_scene_set_csg_carrier(b.scene, solid, carrier), PLM_OK) << plm_last_error();
  plm_light sun;
  plm_light_default(&sun, PLM_LIGHT_SUN);
  sun.power = 3.0f;
  sun.angle = 0.0f;
  b.light(sun, "sun");
  plm_bake_settings s = settings(1000, 64);
  s.max_bounces = 0;
  Baked r;
  ASSERT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r.r), PLM_OK) << plm_last_error();
  const plm_test::Map m = r.map(carrier);
  double worst = 0.0;
  int checked = 0;
  for (uint32_t j = 1; j + 1 < nv; ++j) {  // skip the pole rows (degenerate-ish cells)
    for (uint32_t i = 0; i < nu; ++i) {
      const double theta = M_PI * (j + 0.5) / nv;
      const double nz = -std::cos(theta);
      const double exact = 3.0 * std::max(0.0, nz) / M_PI;
      if (std::fabs(nz) < 0.15) continue;  // the terminator: value varies fast across the texel
      const double got = m.value(j * nu + i);
      worst = std::max(worst, std::fabs(got - exact));
      // The carrier's texel averages the solid's texels over its footprint:
      // a resampling error up to ~ texel size x gradient.
      EXPECT_NEAR(got, exact, 0.04 * 3.0 / M_PI) << "texel " << i << ", " << j;
      ++checked;
    }
  }
  std::printf("[ measured ] CSG sphere under the sun: %d texels, worst |error| %.4f (of %.4f)\n", checked, worst,
              3.0 / M_PI);
  EXPECT_GT(checked, 1000);
}

// Bad input names the solid and the offending primitive or node; carriers
// need a lightmap.
TEST(CsgBake, BadInputNamesSolidAndItem) {
  SceneBuilder b;
  const uint32_t grey = b.material("grey", {0.5f, 0.5f, 0.5f});
  plm_csg_primitive p = prim(PLM_CSG_SPHERE, 1.0, {0, 0, 0}, grey);
  const plm_csg_node leaf = {kNode, PLM_CSG_LEAF, 0, 0};
  uint32_t id = 0;
  p.matrix[0] = NAN;
  EXPECT_EQ(plm_scene_add_csg(b.scene, "nan ball", &p, 1, &leaf, 1, nullptr, 0, 0, &id), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("nan ball"), std::string::npos) << plm_last_error();
  p = prim(PLM_CSG_SPHERE, 1.0, {0, 0, 0}, 7);
  EXPECT_EQ(plm_scene_add_csg(b.scene, "ball", &p, 1, &leaf, 1, nullptr, 0, 0, &id), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("material 7"), std::string::npos) << plm_last_error();
  p = prim(PLM_CSG_SPHERE, 1.0, {0, 0, 0}, grey);
  p.shape = 42;
  EXPECT_EQ(plm_scene_add_csg(b.scene, "ball", &p, 1, &leaf, 1, nullptr, 0, 0, &id), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("primitive 0"), std::string::npos) << plm_last_error();
  p.shape = PLM_CSG_SPHERE;
  const plm_csg_node bad = {kNode, PLM_CSG_UNION, 0, 3};
  const uint32_t kids[3] = {5, 6, 7};
  EXPECT_NE(plm_scene_add_csg(b.scene, "tree", &p, 1, &bad, 1, kids, 3, 0, &id), PLM_OK);
  EXPECT_NE(std::string(plm_last_error()).find("tree"), std::string::npos) << plm_last_error();
  ASSERT_EQ(plm_scene_add_csg(b.scene, "ok", &p, 1, &leaf, 1, nullptr, 0, 0, &id), PLM_OK) << plm_last_error();
  const uint32_t bare = b.quad("bare", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, grey, 0);
  EXPECT_EQ(plm_scene_set_csg_carrier(b.scene, id, bare), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("no lightmap"), std::string::npos) << plm_last_error();
  EXPECT_EQ(plm_scene_set_csg_carrier(b.scene, 9, bare), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_scene_set_csg_carrier(b.scene, id, 99), PLM_ERROR_INVALID_ARGUMENT);
}

}  // namespace

// L-system objects baked through the C API ([Thesis ch. 7]): energy balance in
// a closed black box, a cylinder under the sun against the exact cosine law,
// the shadow a plant casts on a lightmapped floor, bad input, and flattening.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "csg/primitive.h"
#include "demo_scenes.h"
#include "lsystem/graph/graph.h"
#include "lsystem/language/lsystem.h"
#include "test_support.h"
#include "util/rng.h"

namespace {

using plm_demo::SceneBuilder;
using Baked = plm_test::BakeResult;

plm_bake_settings settings(uint64_t photons, uint32_t direct_samples) {
  plm_bake_settings s;
  plm_bake_settings_default(&s);
  s.photon_count = photons;
  s.direct_samples = direct_samples;
  return s;
}

// A binary plant: 7 cylinders (1 + 2 + 4), 3 levels.
const char* kPlant =
    "angle: 30\n"
    "step: 0.3\n"
    "width: 0.05\n"
    "depth: 3\n"
    "axiom: A\n"
    "A -> F [+A] [-A]\n";

plm_lsystem_settings placed(double x, double y, double z) {
  plm_lsystem_settings s;
  plm_lsystem_settings_default(&s);
  s.matrix[3] = x;
  s.matrix[7] = y;
  s.matrix[11] = z;
  return s;
}

uint32_t add_lsystem(SceneBuilder& b, const char* name, const char* rules, const plm_lsystem_settings& s) {
  uint32_t id = ~0u;
  EXPECT_EQ(plm_scene_add_lsystem(b.scene, name, rules, &s, &id), PLM_OK) << plm_last_error();
  return id;
}

plm_lsystem_stats lsystem_stats(const Baked& r, uint32_t id) {
  plm_lsystem_stats st = plm_test::sized<plm_lsystem_stats>();
  EXPECT_EQ(plm_result_lsystem_stats(r.r, id, &st), PLM_OK) << plm_last_error();
  return st;
}

float lookup(const Baked& r, uint32_t id, std::vector<float> p, std::vector<float> n) {
  float rgb[3] = {-1, -1, -1};
  EXPECT_EQ(plm_result_lsystem_lookup(r.r, id, 1, p.data(), n.data(), rgb), PLM_OK) << plm_last_error();
  return (rgb[0] + rgb[1] + rgb[2]) / 3.0f;
}

// (a) A black plant in a closed black cube (2 m, lightmapped, inward) around
// a point light: every photon ends on the cube or the plant, so the cube's
// recorded flux plus the plant's (sum over its root OL of value pi area) is P.
TEST(LSystemBake, BlackPlantInBlackBoxHoldsThePower) {
  SceneBuilder b;
  const uint32_t black = b.material("black", {0, 0, 0});
  const uint32_t res = 16;
  const uint32_t box = b.box("box", {0, 0, 0}, {2, 2, 2}, 0.0f, black, res, true);
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_POINT);
  l.power = 100.0f;
  l.radius = 0.0f;
  l.matrix[3] = 0.35f;
  l.matrix[7] = 0.25f;
  l.matrix[11] = 0.6f;
  b.light(l, "lamp");
  plm_lsystem_settings ls = placed(0.0, 0.0, -0.95);
  ls.ol_level = 2;  // level 1 is the axiom's A (the whole plant); level 2 its two branches
  ls.materials = &black;
  ls.material_count = 1;
  const uint32_t plant = add_lsystem(b, "plant", kPlant, ls);
  ASSERT_TRUE(b.ok()) << b.error;
  plm_bake_settings s = settings(400000, 0);
  s.filter_radius = 0;
  s.dilation = 0;
  s.texel_value = PLM_TEXEL_AREA;
  Baked r;
  ASSERT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r.r), PLM_OK) << plm_last_error();
  const plm_test::Map m = r.map(box);
  // Every texel has the same world size (six equal faces): 24 m^2 over the covered texels.
  double cover = 0.0, box_flux = 0.0;
  for (size_t t = 0; t < m.hits.size(); ++t) cover += m.coverage[t];
  for (size_t t = 0; t < m.hits.size(); ++t) box_flux += m.value(t) * M_PI * (24.0 / cover) * m.coverage[t];
  const plm_lsystem_stats st = lsystem_stats(r, plant);
  std::printf("[ plant in box ] box %.4f W + plant %.4f W = %.4f W of 100 W; plant hits %llu, area %.4f m^2, "
              "%llu stubs hit of %llu, %llu primitives, %llu classes, cache %llu hits / %llu misses\n",
              box_flux, st.flux, box_flux + st.flux, (unsigned long long)st.hits, st.area,
              (unsigned long long)st.stubs, (unsigned long long)st.stub_instances,
              (unsigned long long)st.primitives, (unsigned long long)st.classes,
              (unsigned long long)st.cache_hits, (unsigned long long)st.cache_misses);
  EXPECT_GT(st.flux, 0.1);  // the plant is in the light's way
  EXPECT_NEAR(box_flux + st.flux, 100.0, 0.5);
  EXPECT_EQ(st.primitives, 7u);
  // 7 cylinders of radius 0.025 and length 0.3 (sides and caps)
  const double area = 7 * (2 * M_PI * 0.025 * 0.3 + 2 * M_PI * 0.025 * 0.025);
  EXPECT_NEAR(st.area, area, 0.02 * area);
  EXPECT_EQ(st.stub_instances, 3u);  // the trunk (drawn at level 1) and the two branches
  EXPECT_GE(st.stubs, 2u);
  EXPECT_EQ(st.truncated, 0u);
  EXPECT_EQ(r.stats().photons_emitted, 400000u);
}

// (b) A vertical cylinder (radius 0.1, z in [0, 1]) under a sun of strength
// S from 45 degrees (direction to the sun (sin 45, 0, cos 45)): its side at
// azimuth phi receives S sin45 max(0, cos phi), the top S cos45, the bottom 0.
TEST(LSystemBake, CylinderUnderSunFollowsTheCosineLaw) {
  const double S = 3.0, c45 = std::sqrt(0.5);
  SceneBuilder b;
  const uint32_t grey = b.material("grey", {0.5f, 0.5f, 0.5f});
  plm_light sun;
  plm_light_default(&sun, PLM_LIGHT_SUN);
  sun.power = float(S);
  sun.angle = 0.0f;
  // Rotation about y by +45 degrees: the light's -z axis becomes (-s, 0, -c).
  sun.matrix[0] = float(c45);
  sun.matrix[2] = float(c45);
  sun.matrix[8] = float(-c45);
  sun.matrix[10] = float(c45);
  b.light(sun, "sun");
  plm_lsystem_settings ls = placed(0, 0, 0);
  ls.materials = &grey;
  ls.material_count = 1;
  ls.ol_resolution = 16;
  const uint32_t plant = add_lsystem(b, "stick", "step: 1\nwidth: 0.2\naxiom: F\n", ls);
  ASSERT_TRUE(b.ok()) << b.error;
  Baked r;
  ASSERT_EQ(plm_bake(b.scene, nullptr, nullptr, nullptr, &r.r), PLM_OK) << plm_last_error();
  const double top = lookup(r, plant, {0, 0, 1}, {0, 0, 1});
  const double bottom = lookup(r, plant, {0, 0, 0}, {0, 0, -1});
  std::printf("[ stick under sun ] top %.4f (exact %.4f), bottom %.4f\n", top, S * c45 / M_PI, bottom);
  EXPECT_NEAR(top, S * c45 / M_PI, 0.03 * S * c45 / M_PI);
  EXPECT_EQ(bottom, 0.0);
  double worst = 0.0;
  for (double phi_deg : {-40.0, -20.0, 0.0, 20.0, 40.0, 120.0, 180.0, 240.0}) {
    const double phi = phi_deg * M_PI / 180.0;
    const float cx = float(std::cos(phi)), sy = float(std::sin(phi));
    const double v = lookup(r, plant, {0.1f * cx, 0.1f * sy, 0.5f}, {cx, sy, 0.0f});
    const double exact = S * c45 * std::max(0.0, std::cos(phi)) / M_PI;
    std::printf("[ stick under sun ] side phi %6.1f: %.4f (exact %.4f)\n", phi_deg, v, exact);
    // A bin spans ~22 degrees of azimuth: the bilinear value of cos over it is
    // within ~4% of the point value near the sun's azimuth.
    if (exact > 0.0) {
      EXPECT_NEAR(v, exact, 0.06 * S * c45 / M_PI) << "phi " << phi_deg;
      worst = std::max(worst, std::fabs(v - exact) / (S * c45 / M_PI));
    } else {
      EXPECT_NEAR(v, 0.0, 0.02 * S * c45 / M_PI) << "phi " << phi_deg << " faces away from the sun";
    }
  }
  std::printf("[ stick under sun ] worst lit side error %.2f%% of the peak\n", 100.0 * worst);
}

// (c) A plant between the sun (from straight above) and a lightmapped floor
// shades the floor under it, in the direct pass (shadow rays) and in the
// photon-only bake.
TEST(LSystemBake, PlantShadowsTheFloor) {
  for (const uint32_t direct : {16u, 0u}) {
    SceneBuilder b;
    const uint32_t white = b.material("white", {0.8f, 0.8f, 0.8f});
    const uint32_t black = b.material("black", {0, 0, 0});
    const uint32_t res = 32;
    const uint32_t floor = b.quad("floor", {-2, -2, 0}, {4, 0, 0}, {0, 4, 0}, white, res);
    plm_light sun;
    plm_light_default(&sun, PLM_LIGHT_SUN);
    sun.power = 2.0f;
    sun.angle = 0.0f;
    b.light(sun, "sun");
    plm_lsystem_settings ls = placed(0, 0, 1.0);
    ls.materials = &black;
    ls.material_count = 1;
    add_lsystem(b, "ball", "axiom: @O(0.6)\n", ls);
    ASSERT_TRUE(b.ok()) << b.error;
    Baked r;
    const plm_bake_settings s = settings(direct ? 200000 : 1000000, direct);
    ASSERT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r.r), PLM_OK) << plm_last_error();
    const plm_test::Map m = r.map(floor);
    double under = 0.0, open = 0.0;
    int nu = 0, no = 0;
    for (uint32_t y = 0; y < res; ++y) {
      for (uint32_t x = 0; x < res; ++x) {
        const double px = -2.0 + 4.0 * (x + 0.5) / res, py = -2.0 + 4.0 * (y + 0.5) / res;
        const double rr = std::sqrt(px * px + py * py);
        if (rr < 0.4) under += m.value(y * res + x), ++nu;
        if (rr > 1.2) open += m.value(y * res + x), ++no;
      }
    }
    under /= nu;
    open /= no;
    std::printf("[ shadow, direct_samples %u ] under the ball %.4f, in the open %.4f (exact %.4f)\n", direct, under,
                open, 2.0 / M_PI);
    EXPECT_LT(under, 0.05 * open);
    EXPECT_NEAR(open, 2.0 / M_PI, 0.05 * 2.0 / M_PI);
  }
}

// Photon hits are merged in batch order: the OLs do not depend on the thread count.
TEST(LSystemBake, SameSeedSameOlsWhateverTheThreads) {
  double flux[2] = {0, 0};
  float light[2][6] = {};
  uint64_t stubs[2] = {0, 0};
  for (int k = 0; k < 2; ++k) {
    SceneBuilder b;
    const uint32_t white = b.material("white", {0.8f, 0.8f, 0.8f});
    b.quad("floor", {-2, -2, 0}, {4, 0, 0}, {0, 4, 0}, white, 16);
    plm_light sun;
    plm_light_default(&sun, PLM_LIGHT_SUN);
    b.light(sun, "sun");
    plm_lsystem_settings ls = placed(0, 0, 0.2);
    ls.ol_level = 2;
    const uint32_t plant = add_lsystem(b, "plant", kPlant, ls);
    plm_bake_settings s = settings(100000, 4);
    s.thread_count = k ? 2 : 1;
    Baked r;
    ASSERT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r.r), PLM_OK) << plm_last_error();
    const plm_lsystem_stats st = lsystem_stats(r, plant);
    flux[k] = st.flux;
    stubs[k] = st.stubs;
    const float p[6] = {0.025f, 0, 0.35f, 0, 0, 0.5f}, n[6] = {1, 0, 0, 0, 0, 1};
    ASSERT_EQ(plm_result_lsystem_lookup(r.r, plant, 2, p, n, light[k]), PLM_OK) << plm_last_error();
  }
  EXPECT_EQ(flux[0], flux[1]);
  EXPECT_EQ(stubs[0], stubs[1]);
  for (int i = 0; i < 6; ++i) EXPECT_EQ(light[0][i], light[1][i]) << i;
}

// (d) Bad input is rejected with messages naming the object.
TEST(LSystemApi, BadInputNamesTheObject) {
  SceneBuilder b;
  b.material("grey", {0.5f, 0.5f, 0.5f});
  plm_lsystem_settings s = placed(0, 0, 0);
  uint32_t id = 0;
  EXPECT_EQ(plm_scene_add_lsystem(b.scene, "weed", "axiom: F\nA -> F(\n", &s, &id), PLM_ERROR_INVALID_ARGUMENT);
  const std::string parse_error = plm_last_error();
  EXPECT_NE(parse_error.find("weed"), std::string::npos) << parse_error;
  EXPECT_NE(parse_error.find("line 2, column"), std::string::npos) << parse_error;

  const uint32_t bad_material = 5;
  s.materials = &bad_material;
  s.material_count = 1;
  EXPECT_EQ(plm_scene_add_lsystem(b.scene, "weed", "axiom: F\n", &s, &id), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("materials[0] = 5"), std::string::npos) << plm_last_error();

  s = placed(0, 0, 0);
  s.matrix[5] = NAN;
  EXPECT_EQ(plm_scene_add_lsystem(b.scene, "weed", "axiom: F\n", &s, &id), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("matrix element 5"), std::string::npos) << plm_last_error();
  s = placed(0, 0, 0);
  s.matrix[0] = 2.0;  // non-uniform scale
  EXPECT_EQ(plm_scene_add_lsystem(b.scene, "weed", "axiom: F\n", &s, &id), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("uniform scale"), std::string::npos) << plm_last_error();

  s = placed(0, 0, 0);
  s.depth = 1000;
  EXPECT_EQ(plm_scene_add_lsystem(b.scene, "weed", "axiom: A\nA -> F A\n", &s, &id), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("depth 1000"), std::string::npos) << plm_last_error();
  // A depth in the rules over the limit: the graph's message, still naming the object.
  EXPECT_EQ(plm_scene_add_lsystem(b.scene, "weed", "depth: 200\naxiom: A\nA -> F A\n", nullptr, &id),
            PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("'weed'"), std::string::npos) << plm_last_error();
  EXPECT_NE(std::string(plm_last_error()).find("depth 200"), std::string::npos) << plm_last_error();

  s = placed(0, 0, 0);
  s.ol_resolution = 5000;
  EXPECT_EQ(plm_scene_add_lsystem(b.scene, "weed", "axiom: F\n", &s, &id), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_scene_add_lsystem(b.scene, "weed", nullptr, nullptr, &id), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_scene_add_lsystem(b.scene, "good", "axiom: F\n", nullptr, &id), PLM_OK) << plm_last_error();
  EXPECT_EQ(id, 0u);
  float rgb[3];
  const float p[3] = {0, 0, 0}, n[3] = {0, 0, 1};
  EXPECT_EQ(plm_result_lsystem_lookup(nullptr, 0, 1, p, n, rgb), PLM_ERROR_INVALID_ARGUMENT);
}

// (e) Flattening: counts, truncation, placement, and the bake's primitive count.
TEST(LSystemApi, FlattenCountsMatchTheGraph) {
  uint64_t count = 0;
  int truncated = -1;
  ASSERT_EQ(plm_lsystem_flatten(kPlant, nullptr, 1000, nullptr, nullptr, nullptr, &count, &truncated), PLM_OK)
      << plm_last_error();
  EXPECT_EQ(count, 7u);  // 1 + 2 + 4 cylinders
  EXPECT_EQ(truncated, 0);
  ASSERT_EQ(plm_lsystem_flatten(kPlant, nullptr, 5, nullptr, nullptr, nullptr, &count, &truncated), PLM_OK);
  EXPECT_EQ(count, 5u);
  EXPECT_EQ(truncated, 1);

  plm_lsystem_settings s = placed(10, 20, 30);
  s.depth = 2;
  const uint32_t mats[2] = {7, 9};
  s.materials = mats;
  s.material_count = 2;
  std::vector<uint32_t> shapes(100), materials(100);
  std::vector<double> m(1200);
  ASSERT_EQ(plm_lsystem_flatten(kPlant, &s, 100, shapes.data(), m.data(), materials.data(), &count, &truncated),
            PLM_OK)
      << plm_last_error();
  EXPECT_EQ(count, 3u);
  for (uint64_t i = 0; i < count; ++i) {
    EXPECT_EQ(shapes[i], uint32_t(PLM_CSG_CYLINDER));
    EXPECT_EQ(materials[i], 7u);
  }
  // The trunk: radius 0.025 across, half length 0.15 along z, centred 0.15 above the placement.
  EXPECT_NEAR(m[3], 10.0, 1e-12);
  EXPECT_NEAR(m[7], 20.0, 1e-12);
  EXPECT_NEAR(m[11], 30.15, 1e-12);
  EXPECT_NEAR(m[10], 0.15, 1e-12);

  // The bake's area estimate flattens the same primitives.
  SceneBuilder b;
  const uint32_t grey = b.material("grey", {0.5f, 0.5f, 0.5f});
  b.quad("floor", {-2, -2, 0}, {4, 0, 0}, {0, 4, 0}, grey, 8);
  plm_light sun;
  plm_light_default(&sun, PLM_LIGHT_SUN);
  b.light(sun, "sun");
  const uint32_t plant = add_lsystem(b, "plant", kPlant, placed(0, 0, 0));
  Baked r;
  const plm_bake_settings bs = settings(20000, 4);
  ASSERT_EQ(plm_bake(b.scene, &bs, nullptr, nullptr, &r.r), PLM_OK) << plm_last_error();
  const plm_lsystem_stats st = lsystem_stats(r, plant);
  EXPECT_EQ(st.primitives, 7u);
  EXPECT_GT(st.classes, 0u);
  EXPECT_EQ(st.stubs, 0u);  // ol_level 0: the root OL only
  EXPECT_GT(st.hits, 0u);
  EXPECT_EQ(plm_result_lsystem_stats(r.r, 1, nullptr), PLM_ERROR_INVALID_ARGUMENT);
}

// Stub keys: the key flatten(cap, level) gives a primitive is the
// ancestor_key(hit, level) of a ray hit on it, so stub areas (from the
// flattened primitives) and stub hits (from the traversal) agree.
TEST(LSystemGraphKeys, FlattenKeysMatchHitAncestorKeys) {
  const plm::lsystem::LSystem sys = plm::lsystem::parse(
      "angle: 35\nstep: 0.4\nwidth: 0.08\ndepth: 4\naxiom: A\nA -> F [+A] [&A] [-A]\n");
  const plm::lsystem::Graph graph(sys);
  for (const int level : {0, 1, 2, 3, 6}) {
    const plm::lsystem::FlattenResult flat = graph.flatten(100000, level);
    ASSERT_EQ(flat.keys.size(), flat.primitives.size());
    std::vector<plm::csg::Primitive> prims;
    for (const auto& p : flat.primitives) {
      plm::csg::PrimitiveDesc d;
      d.shape = plm::csg::Shape::Cylinder;
      std::copy(p.to_world, p.to_world + 12, d.to_world);
      prims.push_back(plm::csg::make_primitive(d));
    }
    const plm::Vec3d lo = graph.bounds_lo(), hi = graph.bounds_hi();
    plm::Rng rng(7, uint64_t(level));
    int checked = 0;
    for (int k = 0; k < 2000; ++k) {
      const plm::Vec3d target{lo.x + (hi.x - lo.x) * plm::csg::next_double(rng),
                                   lo.y + (hi.y - lo.y) * plm::csg::next_double(rng),
                                   lo.z + (hi.z - lo.z) * plm::csg::next_double(rng)};
      const plm::Vec3d o{target.x + 10.0, target.y + 3.0, target.z + 1.0};
      plm::lsystem::GraphHit hit;
      if (!graph.first_hit(o, target - o, 0.0, 10.0, &hit)) continue;
      const plm::Vec3d p = o + (target - o) * hit.t;
      const uint64_t key = graph.ancestor_key(hit, level);
      bool found = false;
      for (size_t i = 0; i < prims.size() && !found; ++i)
        found = flat.keys[i] == key && plm::csg::classify(prims[i], p) == plm::csg::Side::Boundary;
      EXPECT_TRUE(found) << "level " << level << " ray " << k;
      ++checked;
    }
    EXPECT_GT(checked, 100) << "level " << level;
  }
}

}  // namespace

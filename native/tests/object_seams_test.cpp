// Seams between objects: which shared borders are seams (coplanar tiles yes,
// a 90 degree corner no; far from the origin, at a tiny scale, with
// degenerate triangles on the border), and that stitching closes the jump
// across them, also between lightmaps of different resolutions.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "lightmap/object_seams.h"
#include "scene/scene.h"

namespace {

using plm::Mesh;
using plm::Vec3;

// A square tile of side `size` at `origin`, spanned by the edge directions
// `u` (its first side) and `v`, as two triangles (0,0)(1,0)(1,1) and
// (0,0)(1,1)(0,1) in (u, v); its lightmap one island over [0.05, 0.95]^2.
Mesh tile(const char* name, Vec3 origin, Vec3 u, Vec3 v, float size, uint32_t resolution) {
  Mesh m;
  m.name = name;
  const Vec3 su = u * size, sv = v * size;
  m.positions = {origin, origin + su, origin + su + sv, origin + sv};
  m.vertex_count = 4;
  m.positions.push_back(origin);  // Embree's padding
  m.indices = {0, 1, 2, 0, 2, 3};
  m.uv = {0.05f, 0.05f, 0.95f, 0.05f, 0.95f, 0.95f, 0.05f, 0.05f, 0.95f, 0.95f, 0.05f, 0.95f};
  m.material_ids = {0, 0};
  m.lightmap_width = m.lightmap_height = resolution;
  return m;
}

TEST(ObjectSeams, CoplanarTilesAreStitchedACornerIsNot) {
  const Vec3 o{0, 0, 0};
  plm::Scene flat;  // the second tile continues the first beyond x = 1
  flat.meshes.push_back(tile("a", o, {1, 0, 0}, {0, 1, 0}, 1.0f, 32));
  flat.meshes.push_back(tile("b", {1, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1.0f, 32));
  const plm::SceneSeams s = plm::find_scene_seams(flat);
  ASSERT_EQ(s.between.size(), 1u) << "the shared edge x = 1";
  EXPECT_EQ(s.joint, (std::vector<uint8_t>{1, 1}));
  // Side a along u = 0.95 (tile a's right edge), side b along u = 0.05 (tile b's left edge).
  const plm::SeamEdge& e = s.between[0].edge;
  EXPECT_FLOAT_EQ(e.a0[0], 0.95f);
  EXPECT_FLOAT_EQ(e.a1[0], 0.95f);
  EXPECT_FLOAT_EQ(e.b0[0], 0.05f);
  EXPECT_FLOAT_EQ(e.b1[0], 0.05f);
  EXPECT_FLOAT_EQ(e.a0[1], e.b0[1]) << "the same end of the edge on both sides";
  EXPECT_FLOAT_EQ(e.a1[1], e.b1[1]);

  plm::Scene corner;  // a wall standing on the floor tile's right edge
  corner.meshes.push_back(tile("floor", o, {1, 0, 0}, {0, 1, 0}, 1.0f, 32));
  corner.meshes.push_back(tile("wall", {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, 1.0f, 32));
  EXPECT_TRUE(plm::find_scene_seams(corner).between.empty()) << "a 90 degree corner is no seam";
  plm::Scene bent;  // the second tile tilted up by 5 degrees
  bent.meshes.push_back(tile("a", o, {1, 0, 0}, {0, 1, 0}, 1.0f, 32));
  bent.meshes.push_back(tile("b", {1, 0, 0}, {float(std::cos(0.087)), 0, float(std::sin(0.087))}, {0, 1, 0}, 1.0f, 32));
  EXPECT_TRUE(plm::find_scene_seams(bent).between.empty()) << "flat faces 5 degrees apart";

  plm::Scene stacked;  // the second tile folded back on top of the first: overlapping, not continuing
  stacked.meshes.push_back(tile("a", o, {1, 0, 0}, {0, 1, 0}, 1.0f, 32));
  stacked.meshes.push_back(tile("b", {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, 1.0f, 32));
  EXPECT_TRUE(plm::find_scene_seams(stacked).between.empty()) << "one tile on top of the other";

  plm::Scene gap;  // a gap of 1e-3 of the tile between them
  gap.meshes.push_back(tile("a", o, {1, 0, 0}, {0, 1, 0}, 1.0f, 32));
  gap.meshes.push_back(tile("b", {1.001f, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1.0f, 32));
  EXPECT_TRUE(plm::find_scene_seams(gap).between.empty()) << "borders 1 mm apart";

  plm::Scene three;  // a third tile on the same edge: no unique partner, left alone
  three.meshes = flat.meshes;
  three.meshes.push_back(tile("c", {1, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1.0f, 32));
  EXPECT_TRUE(plm::find_scene_seams(three).between.empty());

  plm::Scene no_lightmap;  // only meshes whose lightmaps the bake writes take part
  no_lightmap.meshes = flat.meshes;
  no_lightmap.meshes[1].lightmap_width = no_lightmap.meshes[1].lightmap_height = 0;
  no_lightmap.meshes[1].uv.clear();
  EXPECT_TRUE(plm::find_scene_seams(no_lightmap).between.empty());
  plm::Scene carrier;
  carrier.meshes = flat.meshes;
  carrier.meshes[1].csg_carrier = 0;
  EXPECT_TRUE(plm::find_scene_seams(carrier).between.empty()) << "a CSG carrier takes no part";
}

TEST(ObjectSeams, SmoothHalvesAreStitched) {
  // Two smooth-shaded tiles meeting at a 20 degree fold whose shading normals
  // agree along the edge (like two halves of a smooth model): a seam.
  plm::Scene s;
  const float a = 0.35f;
  s.meshes.push_back(tile("a", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1.0f, 32));
  s.meshes.push_back(tile("b", {1, 0, 0}, {std::cos(a), 0, std::sin(a)}, {0, 1, 0}, 1.0f, 32));
  const Vec3 mid{-std::sin(0.5f * a), 0, std::cos(0.5f * a)}, up{0, 0, 1}, tilt{-std::sin(a), 0, std::cos(a)};
  // Per corner of (0,1,2), (0,2,3): edge corners (x = 1) get the mid normal.
  s.meshes[0].normals = {up, mid, mid, up, mid, up};
  s.meshes[1].normals = {mid, tilt, tilt, mid, tilt, mid};
  EXPECT_EQ(plm::find_scene_seams(s).between.size(), 1u);
  s.meshes[1].normals = {tilt, tilt, tilt, tilt, tilt, tilt};  // a sharp edge: split normals
  EXPECT_TRUE(plm::find_scene_seams(s).between.empty());
}

TEST(ObjectSeams, FarFromTheOriginAndTinyScale) {
  // 1e5 m from the origin, each tile placed by its own float arithmetic, so
  // their shared corners differ by float rounding (8 mm steps there).
  const float far = 1.0e5f;
  plm::Scene s;
  s.meshes.push_back(tile("a", {far, far, 3.0f}, {1, 0, 0}, {0, 1, 0}, 1.0f, 32));
  s.meshes.push_back(tile("b", {far + 1.0f, far, 3.0f}, {1, 0, 0}, {0, 1, 0}, 1.0f, 32));
  s.meshes[0].positions[1] = {float(double(far) + 1.0 + 0.004), far, 3.0f};  // one float step off
  EXPECT_EQ(plm::find_scene_seams(s).between.size(), 1u) << "1e5 m from the origin";
  // Tiles of 0.1 mm: the tolerance follows the scene's size.
  plm::Scene tiny;
  tiny.meshes.push_back(tile("a", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1e-4f, 32));
  tiny.meshes.push_back(tile("b", {1e-4f, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1e-4f, 32));
  EXPECT_EQ(plm::find_scene_seams(tiny).between.size(), 1u) << "0.1 mm tiles";
  plm::Scene tiny_gap;  // 1e-3 of the tile apart: not one edge
  tiny_gap.meshes.push_back(tile("a", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1e-4f, 32));
  tiny_gap.meshes.push_back(tile("b", {1.001e-4f, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1e-4f, 32));
  EXPECT_TRUE(plm::find_scene_seams(tiny_gap).between.empty()) << "0.1 um apart at 0.1 mm";
}

TEST(ObjectSeams, DegenerateTrianglesOnTheBorder) {
  plm::Scene s;
  s.meshes.push_back(tile("a", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1.0f, 32));
  s.meshes.push_back(tile("b", {1, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1.0f, 32));
  Mesh& a = s.meshes[0];
  // A zero-area triangle on tile a's border edge (1,0)-(1,1), through its midpoint...
  a.positions.insert(a.positions.begin() + 4, Vec3{1, 0.5f, 0});
  a.vertex_count = 5;
  a.indices.insert(a.indices.end(), {1, 4, 2});
  a.uv.insert(a.uv.end(), {0.95f, 0.05f, 0.95f, 0.5f, 0.95f, 0.95f});
  a.material_ids.push_back(0);
  // ... and a needle on tile b's border (two corners at one point).
  Mesh& b = s.meshes[1];
  b.indices.insert(b.indices.end(), {0, 0, 3});
  b.uv.insert(b.uv.end(), {0.05f, 0.05f, 0.05f, 0.05f, 0.05f, 0.95f});
  b.material_ids.push_back(0);
  const plm::SceneSeams seams = plm::find_scene_seams(s);
  ASSERT_EQ(seams.between.size(), 1u) << "degenerate triangles along the edge are not borders";
  EXPECT_FLOAT_EQ(seams.between[0].edge.a0[0], 0.95f);
  EXPECT_FLOAT_EQ(seams.between[0].edge.b0[0], 0.05f);
}

// Both tiles hold the smooth field f(x, y) = 1 + 0.5 x + 0.25 y of the
// surface point (x from 0 to 2 across both), with 3 % independent noise, and
// borders dilated from it; stitching closes the jump across the shared edge
// and moves covered texels by less than their noise.
void check_stitch(uint32_t res_a, uint32_t res_b) {
  plm::Scene s;
  s.meshes.push_back(tile("a", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1.0f, res_a));
  s.meshes.push_back(tile("b", {1, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1.0f, res_b));
  const plm::SceneSeams seams = plm::find_scene_seams(s);
  ASSERT_EQ(seams.between.size(), 1u);
  std::mt19937 rng(11);
  std::normal_distribution<float> noise(0.0f, 0.03f);
  struct Image {
    std::vector<float> rgb, error, truth;
    std::vector<uint8_t> covered;
  };
  std::vector<Image> img(2);
  std::vector<plm::SeamImage> view(2);
  for (int k = 0; k < 2; ++k) {
    const uint32_t n = k == 0 ? res_a : res_b;
    Image& im = img[size_t(k)];
    im.rgb.assign(size_t(n) * n * 3, 0.0f);
    im.error.assign(size_t(n) * n, 0.0f);
    im.truth.assign(size_t(n) * n, 0.0f);
    im.covered.assign(size_t(n) * n, 0);
    // Covered: texel centres inside the island; the others take the value of
    // the nearest covered texel along rows and columns, as dilation leaves them.
    auto inside = [&](uint32_t i) { const float u = (float(i) + 0.5f) / float(n); return u > 0.05f && u < 0.95f; };
    uint32_t first = 0, last = n - 1;
    while (!inside(first)) ++first;
    while (!inside(last)) --last;
    for (uint32_t j = 0; j < n; ++j)
      for (uint32_t i = 0; i < n; ++i) {
        const float u = (float(i) + 0.5f) / float(n), v = (float(j) + 0.5f) / float(n);
        const float x = float(k) + (u - 0.05f) / 0.9f, y = (v - 0.05f) / 0.9f;
        const size_t t = size_t(j) * n + i;
        im.truth[t] = 1.0f + 0.5f * x + 0.25f * y;
        im.covered[t] = inside(i) && inside(j);
        if (!im.covered[t]) continue;
        const float value = im.truth[t] * (1.0f + noise(rng));
        for (int c = 0; c < 3; ++c) im.rgb[3 * t + c] = value;
        im.error[t] = 0.03f * im.truth[t];
      }
    for (uint32_t j = 0; j < n; ++j)
      for (uint32_t i = 0; i < n; ++i) {
        const size_t t = size_t(j) * n + i;
        if (im.covered[t]) continue;
        const size_t from = size_t(std::clamp(j, first, last)) * n + std::clamp(i, first, last);
        for (int c = 0; c < 3; ++c) im.rgb[3 * t + c] = im.rgb[3 * from + c];
      }
    view[size_t(k)] = {im.rgb.data(), 3, im.error.data(), 1, im.covered.data(), n, n};
  }
  const std::vector<Image> before = img;
  const plm::SeamStats st = plm::stitch_scene_seams(seams, view);
  std::printf("[ seam ] between objects (%u and %u texels): jump %.4f -> %.4f of the value (%zu points)\n", res_a,
              res_b, st.jump_before, st.jump_after, st.samples);
  EXPECT_EQ(st.edges, 1u);
  EXPECT_GT(st.jump_before, 0.02);
  EXPECT_LT(st.jump_after, 0.35 * st.jump_before);
  double moved = 0.0, noise_sq = 0.0, err_before = 0.0, err_after = 0.0;
  size_t count = 0;
  for (int k = 0; k < 2; ++k)
    for (size_t t = 0; t < img[size_t(k)].truth.size(); ++t) {
      const Image &a = img[size_t(k)], &b = before[size_t(k)];
      EXPECT_EQ(a.error[t], b.error[t]);
      if (!a.covered[t]) continue;
      moved += (a.rgb[3 * t] - b.rgb[3 * t]) * (a.rgb[3 * t] - b.rgb[3 * t]);
      noise_sq += (b.rgb[3 * t] - a.truth[t]) * (b.rgb[3 * t] - a.truth[t]);
      err_before += (b.rgb[3 * t] - a.truth[t]) * (b.rgb[3 * t] - a.truth[t]);
      err_after += (a.rgb[3 * t] - a.truth[t]) * (a.rgb[3 * t] - a.truth[t]);
      ++count;
    }
  EXPECT_LT(std::sqrt(moved / double(count)), 0.5 * std::sqrt(noise_sq / double(count)));
  EXPECT_LE(err_after, err_before);
}

TEST(ObjectSeams, StitchingClosesTheJump) { check_stitch(32, 32); }
TEST(ObjectSeams, StitchingClosesTheJumpAtMismatchedResolutions) { check_stitch(32, 8); }

TEST(ObjectSeams, NoSharedEdgesNothingToDo) {
  plm::Scene s;
  s.meshes.push_back(tile("a", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1.0f, 16));
  s.meshes.push_back(tile("b", {3, 0, 0}, {1, 0, 0}, {0, 1, 0}, 1.0f, 16));
  const plm::SceneSeams seams = plm::find_scene_seams(s);
  EXPECT_TRUE(seams.between.empty());
  EXPECT_EQ(seams.joint, (std::vector<uint8_t>{0, 0}));
  EXPECT_EQ(plm::stitch_scene_seams(seams, std::vector<plm::SeamImage>(2)).edges, 0u);
}

}  // namespace

namespace {

// docs/benchmarks/geometry.md: the cost of finding seams in a scene of many borders
// that meet nowhere (run with --gtest_also_run_disabled_tests
// --gtest_filter=ObjectSeams.DISABLED_CostWithoutSharedBorders).
TEST(ObjectSeams, DISABLED_CostWithoutSharedBorders) {
  plm::Scene s;
  for (int part = 0; part < 2; ++part) {  // two meshes of 100 k separate cards (400 k border edges each)
    Mesh m;
    m.name = part ? "cards b" : "cards a";
    for (int k = 0; k < 100000; ++k) {
      const float x = float(k % 300) * 1.5f + float(part) * 0.7f, y = float(k / 300) * 1.5f, z = float(part) * 0.3f;
      const uint32_t b = uint32_t(m.positions.size());
      for (const Vec3& p : {Vec3{x, y, z}, Vec3{x + 1, y, z}, Vec3{x + 1, y + 1, z}, Vec3{x, y + 1, z}})
        m.positions.push_back(p);
      for (uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) m.indices.push_back(b + i);
      for (float u : {0.f, 0.f, 1.f, 0.f, 1.f, 1.f, 0.f, 0.f, 1.f, 1.f, 0.f, 1.f}) m.uv.push_back(u);
      m.material_ids.insert(m.material_ids.end(), {0, 0});
    }
    m.vertex_count = uint32_t(m.positions.size());
    m.positions.push_back({0, 0, 0});
    m.lightmap_width = m.lightmap_height = 4096;
    s.meshes.push_back(std::move(m));
  }
  auto seconds = [](auto since) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
  };
  auto start = std::chrono::steady_clock::now();
  size_t within = 0;
  for (const Mesh& m : s.meshes) within += plm::find_seams(m).size();
  const double alone = seconds(start);
  start = std::chrono::steady_clock::now();
  const plm::SceneSeams seams = plm::find_scene_seams(s);
  const double all = seconds(start);
  std::printf("[ cost ] 800 k border edges in 2 meshes: seams within %.3f s, within and between %.3f s (%zu, %zu)\n",
              alone, all, within, seams.between.size());
  EXPECT_TRUE(seams.between.empty());
}

}  // namespace

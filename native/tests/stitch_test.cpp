// Seam stitching: which edges are seams, and that stitching closes the jump
// across them while barely moving the texels the islands cover.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "lightmap/stitch.h"
#include "scene/scene.h"

namespace {

using plm::Mesh;
using plm::Vec3;

// Two triangles of the unit square in z = 0 (or folded up by `fold` radians
// about the diagonal), each given its own UV island.
Mesh two_triangles(double fold, bool split_vertices, bool smooth_normals, bool same_normals = true) {
  Mesh m;
  const float lift = float(std::sin(fold)), flat = float(std::cos(fold));
  // Triangle 0: (0,0) (1,0) (1,1); triangle 1: (0,0) (1,1) (0,1) folded about the diagonal.
  std::vector<Vec3> p = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0.5f - 0.5f * flat, 0.5f + 0.5f * flat, lift}};
  if (split_vertices) p.push_back({0, 0, 0}), p.push_back({1, 1, 0});
  m.positions = p;
  m.vertex_count = uint32_t(p.size());
  m.positions.push_back({0, 0, 0});  // Embree's padding
  m.indices = {0, 1, 2, split_vertices ? 4u : 0u, split_vertices ? 5u : 2u, 3};
  // Island A in the lower-left quarter, island B (the same shape) in the upper right.
  m.uv = {0.05f, 0.05f, 0.45f, 0.05f, 0.45f, 0.45f,   // triangle 0
          0.55f, 0.55f, 0.95f, 0.95f, 0.55f, 0.95f};  // triangle 1: diagonal (0.55,0.55)-(0.95,0.95)
  m.lightmap_width = m.lightmap_height = 32;
  if (smooth_normals) {
    const Vec3 up{0, 0, 1}, tilted{0, 0.6f, 0.8f};
    m.normals = {up, up, up, up, same_normals ? up : tilted, up};
  }
  return m;
}

TEST(Stitch, SeamsAreCutSmoothEdges) {
  EXPECT_EQ(plm::find_seams(two_triangles(0.0, false, false)).size(), 1u) << "coplanar, two islands";
  EXPECT_EQ(plm::find_seams(two_triangles(0.0, true, false)).size(), 1u) << "vertices split along the seam";
  EXPECT_EQ(plm::find_seams(two_triangles(0.3, false, false)).size(), 0u) << "flat faces 17 degrees apart";
  EXPECT_EQ(plm::find_seams(two_triangles(0.01, false, false)).size(), 1u) << "flat faces within a degree";
  EXPECT_EQ(plm::find_seams(two_triangles(M_PI / 2, false, false)).size(), 0u) << "a 90 degree crease";
  EXPECT_EQ(plm::find_seams(two_triangles(M_PI / 2, false, true)).size(), 1u) << "smooth normals across it";
  EXPECT_EQ(plm::find_seams(two_triangles(0.0, false, true, false)).size(), 0u) << "a sharp edge (split normals)";
  Mesh joined = two_triangles(0.0, false, false);
  joined.uv = {0.1f, 0.1f, 0.9f, 0.1f, 0.9f, 0.9f, 0.1f, 0.1f, 0.9f, 0.9f, 0.1f, 0.9f};
  EXPECT_EQ(plm::find_seams(joined).size(), 0u) << "one island: no seam";
  Mesh flat_no_uv = two_triangles(0.0, false, false);
  flat_no_uv.uv.clear();
  EXPECT_TRUE(plm::find_seams(flat_no_uv).empty());
}

TEST(Stitch, ClosesTheJumpAndKeepsCoveredTexels) {
  const Mesh m = two_triangles(0.0, false, false);
  const auto seams = plm::find_seams(m);
  ASSERT_EQ(seams.size(), 1u);
  // Both islands hold the same smooth field f(x, y) = 1 + x + 0.5 y of the
  // surface point, with 3 % independent noise, plus dilated borders.
  const uint32_t n = 32;
  std::vector<float> values(size_t(n) * n * 4, 0.0f), truth(size_t(n) * n, 0.0f);
  std::vector<uint8_t> covered(size_t(n) * n, 0);
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 0.03f);
  for (uint32_t j = 0; j < n; ++j)
    for (uint32_t i = 0; i < n; ++i) {
      const float u = (float(i) + 0.5f) / n, v = (float(j) + 0.5f) / n;
      float x, y;  // the surface point whose texel this is (islands map linearly to the square)
      bool in;
      if (u < 0.5f && v < 0.5f) {
        x = (u - 0.05f) / 0.4f, y = (v - 0.05f) / 0.4f, in = y <= x;
      } else if (u > 0.5f && v > 0.5f) {
        x = (u - 0.55f) / 0.4f, y = (v - 0.55f) / 0.4f, in = y >= x;
      } else {
        continue;
      }
      const float f = 1.0f + x + 0.5f * y;
      const size_t t = size_t(j) * n + i;
      truth[t] = f;
      // Texels beside the island's edge hold the field extrapolated (as dilation leaves it), off by 10 %.
      const bool inside = in && x >= 0 && y >= 0 && x <= 1 && y <= 1;
      covered[t] = inside;
      const float value = inside ? f * (1.0f + noise(rng)) : 1.1f * f;
      for (int c = 0; c < 3; ++c) values[t * 4 + c] = value;
      values[t * 4 + 3] = inside ? 0.03f * f : 0.0f;  // the error channel
    }
  const std::vector<float> before = values;
  const plm::SeamStats s = plm::stitch_seams(seams, covered, values, 4, n, n);
  std::printf("[ seam ] jump across the seam %.4f -> %.4f of the value (%zu points)\n", s.jump_before, s.jump_after,
              s.samples);
  EXPECT_EQ(s.edges, 1u);
  EXPECT_GE(s.samples, 20u);
  EXPECT_GT(s.jump_before, 0.02);
  EXPECT_LT(s.jump_after, 0.35 * s.jump_before) << s.jump_before << " -> " << s.jump_after;
  double moved = 0.0, noise_sq = 0.0;
  size_t count = 0;
  for (size_t t = 0; t < truth.size(); ++t) {
    EXPECT_EQ(values[t * 4 + 3], before[t * 4 + 3]);  // the error channel: left alone
    if (!covered[t]) continue;
    moved += (values[t * 4] - before[t * 4]) * (values[t * 4] - before[t * 4]);
    noise_sq += (before[t * 4] - truth[t]) * (before[t * 4] - truth[t]);
    ++count;
  }
  // Covered texels move by less than their own noise (towards the other
  // side's estimate of the same points, so no further from the truth).
  EXPECT_LT(std::sqrt(moved / count), 0.5 * std::sqrt(noise_sq / count));
  double err_before = 0.0, err_after = 0.0;
  for (size_t t = 0; t < truth.size(); ++t)
    if (covered[t]) {
      err_before += (before[t * 4] - truth[t]) * (before[t * 4] - truth[t]);
      err_after += (values[t * 4] - truth[t]) * (values[t * 4] - truth[t]);
    }
  EXPECT_LE(err_after, err_before);
  // An exact texel (no error) does not move at all.
  std::vector<float> exact = before;
  for (size_t t = 0; t < truth.size(); ++t) exact[t * 4 + 3] = 0.0f;
  const std::vector<float> exact_before = exact;
  plm::stitch_seams(seams, covered, exact, 4, n, n);
  for (size_t t = 0; t < truth.size(); ++t) {
    if (covered[t]) {
      EXPECT_EQ(exact[t * 4], exact_before[t * 4]);
    }
  }
}

TEST(Stitch, NothingToDoLeavesValuesAlone) {
  std::vector<float> values(16 * 4, 1.0f);
  const std::vector<float> before = values;
  const plm::SeamStats s = plm::stitch_seams({}, std::vector<uint8_t>(16, 1), values, 4, 4, 4);
  EXPECT_EQ(s.edges, 0u);
  EXPECT_EQ(values, before);
}

}  // namespace

#include "lightmap/texel_area.h"

#include <gtest/gtest.h>

#include <random>

#include "lightmap/dilate.h"

namespace plm {
namespace {

double grid_total(const double tri[6], uint32_t w, uint32_t h) {
  double total = 0.0;
  clip_triangle_to_grid(tri, w, h, [&](uint32_t, double a, double, double) { total += a; });
  return total;
}

TEST(TexelArea, ClippedPiecesSumToTriangleArea) {
  std::mt19937 gen(7);
  std::uniform_real_distribution<double> u(0.0, 16.0);
  for (int i = 0; i < 1000; ++i) {
    const double tri[6] = {u(gen), u(gen), u(gen), u(gen), u(gen), u(gen)};
    EXPECT_NEAR(grid_total(tri, 16, 16), polygon_area(tri, 3), 1e-9 * 256);
  }
}

TEST(TexelArea, SliverAndTinyTriangles) {
  const double sliver[6] = {0.5, 0.5, 15.5, 0.5000001, 15.5, 0.5000002};
  EXPECT_NEAR(grid_total(sliver, 16, 16), polygon_area(sliver, 3), 1e-12);
  const double tiny[6] = {3.1, 3.1, 3.1000001, 3.1, 3.1, 3.1000001};
  const double leg = 3.1000001 - 3.1;  // what the double inputs really hold
  EXPECT_NEAR(grid_total(tiny, 16, 16), 0.5 * leg * leg, 1e-9 * leg * leg);
}

TEST(TexelArea, PartOutsideTheSquareIsDropped) {
  // Right triangle (-4,0)-(4,0)-(-4,8): its part with x >= 0 is the triangle
  // (0,0)-(4,0)-(0,4) of area 8.
  const double tri[6] = {-4, 0, 4, 0, -4, 8};
  EXPECT_NEAR(grid_total(tri, 16, 16), 8.0, 1e-12);
}

TEST(TexelArea, UnitSquareQuadHasEqualTexels) {
  Mesh m;
  m.name = "quad";
  m.positions = {{0, 0, 0}, {2, 0, 0}, {2, 3, 0}, {0, 3, 0}, {0, 0, 0}};
  m.vertex_count = 4;
  m.indices = {0, 1, 2, 0, 2, 3};
  m.uv = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
  m.material_ids = {0, 0};
  m.lightmap_width = 8;
  m.lightmap_height = 4;
  const TexelAreas a = compute_texel_areas(m);
  for (size_t t = 0; t < a.area.size(); ++t) {
    EXPECT_NEAR(a.area[t], 6.0 / 32.0, 1e-12) << "texel " << t;
    EXPECT_NEAR(a.coverage[t], 1.0f, 1e-6f);
  }
  EXPECT_EQ(a.overlapping_texels, 0u);
}

TEST(TexelArea, ReportsOverlapZeroUvAndOutside) {
  Mesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 0}};
  m.vertex_count = 4;
  m.indices = {0, 1, 2, 0, 2, 3, 0, 1, 2};
  // Triangle 2 reuses triangle 0's UVs (overlap); then a zero-UV-area one below.
  m.uv = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1, 0, 0, 1, 0, 1, 1};
  m.lightmap_width = m.lightmap_height = 4;
  TexelAreas a = compute_texel_areas(m);
  EXPECT_GT(a.overlapping_texels, 0u);
  m.uv = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f};
  a = compute_texel_areas(m);
  EXPECT_EQ(a.zero_uv_triangles, 1u);
  EXPECT_EQ(a.first_zero_uv_triangle, 2u);
  m.uv = {0, 0, 1.5f, 0, 1, 1, 0, 0, 1, 1, 0, 1, 0, 0, 1, 0, 1, 1};
  a = compute_texel_areas(m);
  EXPECT_EQ(a.outside_triangles, 1u);
}

// Two quads side by side in UV, each with a sliver reaching into the other's
// texels: the slivers merge into their own quad's texels, never across.
TEST(TexelArea, SparseTexelsMergeOnlyWithinTheirSurface) {
  Mesh m;
  // Quad A at z = 0 (UV x in [0, 0.501]), quad B at z = 5 facing the same way (UV x in [0.501, 1]).
  m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 5}, {1, 0, 5}, {1, 1, 5}, {0, 1, 5}, {}};
  m.vertex_count = 8;
  m.indices = {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7};
  const float s = 0.501f;
  m.uv = {0, 0, s, 0, s, 1, 0, 0, s, 1, 0, 1, s, 0, 1, 0, 1, 1, s, 0, 1, 1, s, 1};
  m.lightmap_width = 4;
  m.lightmap_height = 4;
  const TexelAreas a = compute_texel_areas(m);
  const std::vector<uint32_t> shown = merge_sparse_texels(a, 4, 4);
  for (uint32_t y = 0; y < 4; ++y) {
    const uint32_t t = y * 4 + 2;  // texel 2 holds a sliver of A (0.004 wide) and most of B
    EXPECT_EQ(shown[t], t);         // well covered: not merged
    EXPECT_EQ(shown[y * 4 + 1], y * 4 + 1);
  }
  // A sliver-only texel: move A's right edge to 0.2505 so texel 1 holds 0.002 of A.
  const float r = 0.2505f;
  m.uv = {0, 0, r, 0, r, 1, 0, 0, r, 1, 0, 1, 0.6f, 0, 1, 0, 1, 1, 0.6f, 0, 1, 1, 0.6f, 1};
  const TexelAreas b = compute_texel_areas(m);
  const std::vector<uint32_t> shown_b = merge_sparse_texels(b, 4, 4);
  for (uint32_t y = 0; y < 4; ++y) {
    EXPECT_LT(b.coverage[y * 4 + 1], 0.01f);
    EXPECT_EQ(shown_b[y * 4 + 1] % 4, 0u) << "row " << y;  // into A's texel 0, not B's texel 2
    EXPECT_EQ(shown_b[y * 4 + 2], y * 4 + 2u);  // B's partly covered texel (0.6) stays itself
  }
}

TEST(Dilate, FillsRingsFromFilledNeighbours) {
  std::vector<float> v(5 * 5, 0.0f);
  std::vector<uint8_t> filled(25, 0);
  v[12] = 4.0f;
  filled[12] = 1;
  dilate(v, 1, filled, 5, 5, 1);
  for (int y = 1; y <= 3; ++y)
    for (int x = 1; x <= 3; ++x) EXPECT_EQ(v[y * 5 + x], 4.0f);
  EXPECT_EQ(filled[0], 0);
  dilate(v, 1, filled, 5, 5, 8);
  for (float x : v) EXPECT_EQ(x, 4.0f);
}

}  // namespace
}  // namespace plm

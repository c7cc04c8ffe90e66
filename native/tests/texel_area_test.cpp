#include "lightmap/texel_area.h"

#include <gtest/gtest.h>

#include <random>

#include "lightmap/dilate.h"

namespace plm {
namespace {

double grid_total(const double tri[6], uint32_t w, uint32_t h) {
  double total = 0.0;
  clip_triangle_to_grid(tri, w, h, [&](uint32_t, double a) { total += a; });
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

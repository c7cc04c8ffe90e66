#include "lightmap/texel_area.h"

#include <gtest/gtest.h>

#include <random>

#include "lightmap/dilate.h"
#include "lightmap/reconstruct.h"

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

// Two quads side by side in UV but 5 m apart in the world: the barely
// covered texels pool with their own quad's texels, never across.
TEST(Reconstruct, PoolsOnlyWithinTheSameSurface) {
  Mesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 5}, {1, 0, 5}, {1, 1, 5}, {0, 1, 5}, {}};
  m.vertex_count = 8;
  m.indices = {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7};
  // Quad A covers UV x in [0, 0.2505] (texel 1 holds a 0.002 sliver), B covers [0.6, 1].
  const float r = 0.2505f;
  m.uv = {0, 0, r, 0, r, 1, 0, 0, r, 1, 0, 1, 0.6f, 0, 1, 0, 1, 1, 0.6f, 0, 1, 1, 0.6f, 1};
  m.lightmap_width = m.lightmap_height = 4;
  const TexelAreas a = compute_texel_areas(m);
  // Exact photon sums: flux density 1 on A (per unit area), 100 on B.
  std::vector<double> flux(3 * 16, 0.0), sq(16, 0.0);
  std::vector<uint32_t> hits(16, 0);
  for (uint32_t t = 0; t < 16; ++t) {
    const bool on_b = t % 4 >= 2;
    for (int c = 0; c < 3; ++c) flux[3 * t + c] = (on_b ? 100.0 : 1.0) * a.area[t] * kPiD;
  }
  ReconstructParams params;
  std::vector<double> value, mse;
  // Noise-free sums: any pooling only adds bias, so the lightmap keeps radius 0...
  EXPECT_EQ(reconstruct_indirect(a, 4, 4, {flux.data(), sq.data(), hits.data()}, params, value, mse), 0u);
  for (uint32_t y = 0; y < 4; ++y) {
    EXPECT_LT(a.coverage[y * 4 + 1], 0.01f);
    EXPECT_NEAR(value[3 * (y * 4 + 1)], 1.0, 1e-9);    // ...the sliver pools with A only (not 100)
    EXPECT_NEAR(value[3 * (y * 4 + 2)], 100.0, 1e-9);  // B stays B
    EXPECT_NEAR(value[3 * (y * 4 + 0)], 1.0, 1e-9);
  }
}

// A 16 x 16 m square with a 16 x 16 lightmap: 1 m texels.
Mesh square16() {
  Mesh m;
  m.positions = {{0, 0, 0}, {16, 0, 0}, {16, 16, 0}, {0, 16, 0}, {}};
  m.vertex_count = 4;
  m.indices = {0, 1, 2, 0, 2, 3};
  m.uv = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
  m.lightmap_width = m.lightmap_height = 16;
  return m;
}

// The radius follows the estimated error: noisy sums of a flat field pool
// widely; exact sums of a steep field stay unpooled.
TEST(Reconstruct, ChoosesTheRadiusWithTheLeastEstimatedError) {
  const TexelAreas a = compute_texel_areas(square16());
  std::vector<double> flux(3 * 256), sq(256);
  std::vector<uint32_t> hits(256);
  std::mt19937 gen(3);
  std::poisson_distribution<int> poisson(4.0);
  for (uint32_t t = 0; t < 256; ++t) {  // flat field, about 4 hits of flux 1 per texel
    hits[t] = uint32_t(poisson(gen));
    for (int c = 0; c < 3; ++c) flux[3 * t + c] = hits[t];
    sq[t] = hits[t];
  }
  ReconstructParams params;
  std::vector<double> value, mse;
  EXPECT_EQ(reconstruct_indirect(a, 16, 16, {flux.data(), sq.data(), hits.data()}, params, value, mse), 2u);
  double err = 0.0;  // the pooled values are close to the truth, 4 / pi
  for (uint32_t y = 2; y < 14; ++y)
    for (uint32_t x = 2; x < 14; ++x) err = std::max(err, std::fabs(value[3 * (y * 16 + x)] - 4.0 / kPiD));
  EXPECT_LT(err, 0.5 * 4.0 / kPiD);
  for (uint32_t t = 0; t < 256; ++t) {  // steep exact field: 1000 hits, value grows 10x per texel
    const double v = std::pow(10.0, (t % 16) / 4.0);
    for (int c = 0; c < 3; ++c) flux[3 * t + c] = v * kPiD;
    hits[t] = 1000;
    sq[t] = v * v * kPiD * kPiD / 1000.0;
  }
  EXPECT_EQ(reconstruct_indirect(a, 16, 16, {flux.data(), sq.data(), hits.data()}, params, value, mse), 0u);
}

// A sliver texel (1 % covered, pooling with nobody) under uniform light: the
// error it reports is its true error, as for a whole texel. Photons hit it
// 100x less often than a whole texel, so its variance is 1 / (its area) x
// that of a texel's worth of area, not 1 / area^2: a whole phantom hit on it
// reported 2.5x its true error here (6x its variance; on the subdivided
// monkeys' island borders 140x their variance), and held a courtyard's error
// estimate above its target.
TEST(Reconstruct, SliverReportsItsTrueError) {
  Mesh m;
  // A: an 8 x 16 m floor on the map's left half (1 m^2 texels); S: a 0.1 x 0.1 m
  // wall far away (another normal: it pools with nothing) in 1 % of texel (12, 8).
  m.positions = {{0, 0, 0}, {8, 0, 0}, {8, 16, 0}, {0, 16, 0}, {20, 0, 0}, {20, 0.1f, 0}, {20, 0.1f, 0.1f},
                 {20, 0, 0.1f}, {}};
  m.vertex_count = 8;
  m.indices = {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7};
  const float u0 = 12.0f / 16, u1 = 12.1f / 16, v0 = 8.0f / 16, v1 = 8.1f / 16;
  m.uv = {0, 0, 0.5f, 0, 0.5f, 1, 0, 0, 0.5f, 1, 0, 1, u0, v0, u1, v0, u1, v1, u0, v0, u1, v1, u0, v1};
  m.lightmap_width = m.lightmap_height = 16;
  const TexelAreas a = compute_texel_areas(m);
  const uint32_t sliver = 8 * 16 + 12;
  ASSERT_NEAR(a.coverage[sliver], 0.01, 1e-4);
  double total_area = 0.0;
  for (double x : a.area) total_area += x;
  // Photons of flux 1 spread uniformly: texel t gets Poisson(N area_t / total) hits;
  // every texel's true value is 1 / (pi total). N: 20 hits per whole texel.
  const double photons = 20.0 * total_area / 1.0, truth = 1.0 / (kPiD * total_area);
  ReconstructParams params;
  params.photons = photons;
  params.phantom_sq = 1.0;
  std::mt19937 gen(11);
  std::vector<double> flux(3 * 256), sq(256), value, mse;
  std::vector<uint32_t> hits(256);
  double true_sq = 0.0, reported = 0.0;
  const int trials = 4000;
  for (int k = 0; k < trials; ++k) {
    for (uint32_t t = 0; t < 256; ++t) {
      hits[t] = a.area[t] > 0.0 ? uint32_t(std::poisson_distribution<int>(photons * a.area[t] / total_area)(gen)) : 0;
      for (int c = 0; c < 3; ++c) flux[3 * t + c] = hits[t];
      sq[t] = hits[t];
    }
    reconstruct_indirect(a, 16, 16, {flux.data(), sq.data(), hits.data()}, params, value, mse);
    true_sq += (value[3 * sliver] - truth) * (value[3 * sliver] - truth);
    reported += mse[sliver];
  }
  const double ratio = std::sqrt(reported / true_sq);  // reported / true RMS error
  EXPECT_GT(ratio, 0.8);
  EXPECT_LT(ratio, 1.25);
}

// Photons so sparse that a pool of texels holds one in ten bakes: a texel's
// own error keeps the whole phantom hit (its error is unknown where no photon
// landed), while the error the final gather's lookups see, averaged over
// many pools, is the mean of the pool's squared hits and the hits the
// lightmap's density lets a pool expect (each unbiased for the variance; the
// larger of the two overstated it 2x) and is close to the true error; the
// phantom overstates it ~4x (14x in variance) and made an open scene's
// gather look 3x worse than it was.
TEST(Reconstruct, LookupErrorFollowsTheTrueErrorWherePhotonsAreSparse) {
  const TexelAreas a = compute_texel_areas(square16());
  ReconstructParams params;
  params.photons = 256.0 * 0.004;  // 0.004 hits of flux 1 per 1 m^2 texel: 0.1 per 5 x 5 pool
  params.phantom_sq = 1.0;
  const double truth = 1.0 / (kPiD * 256.0);
  std::mt19937 gen(5);
  std::poisson_distribution<int> poisson(0.004);
  std::vector<double> flux(3 * 256), sq(256), value, mse;
  LookupError lookup;
  std::vector<uint32_t> hits(256);
  double true_sq = 0.0, reported = 0.0, looked_up = 0.0;
  for (int k = 0; k < 4000; ++k) {
    for (uint32_t t = 0; t < 256; ++t) {
      hits[t] = uint32_t(poisson(gen));
      for (int c = 0; c < 3; ++c) flux[3 * t + c] = hits[t];
      sq[t] = hits[t];
    }
    EXPECT_EQ(reconstruct_indirect(a, 16, 16, {flux.data(), sq.data(), hits.data()}, params, value, mse, &lookup), 2u);
    for (uint32_t t = 0; t < 256; ++t) {
      true_sq += (value[3 * t] - truth) * (value[3 * t] - truth);
      reported += mse[t];
      looked_up += lookup.local[t] + lookup.wide[t];
    }
  }
  const double own = std::sqrt(reported / true_sq), lookups = std::sqrt(looked_up / true_sq);
  std::printf("[ measured ] sparse photons, reported / true RMS error: own %.2f, lookups %.2f\n", own, lookups);
  EXPECT_GT(own, 2.5);
  EXPECT_GT(lookups, 0.85);
  EXPECT_LT(lookups, 1.2);
}

// With the direct light as a guide, pooling stops at a contact shadow: a
// noisy lit half next to a dark half (no light at all) leaks nothing into it.
TEST(Reconstruct, GuideStopsPoolingAtShadowEdges) {
  const TexelAreas a = compute_texel_areas(square16());
  std::vector<double> flux(3 * 256, 0.0), sq(256, 0.0), guide(256, 0.0);
  std::vector<uint32_t> hits(256, 0);
  std::mt19937 gen(5);
  std::poisson_distribution<int> poisson(4.0);
  for (uint32_t t = 0; t < 256; ++t) {
    if (t % 16 >= 8) continue;  // right half: in the box's contact shadow
    guide[t] = 1.0;
    hits[t] = uint32_t(poisson(gen));
    for (int c = 0; c < 3; ++c) flux[3 * t + c] = hits[t];
    sq[t] = hits[t];
  }
  ReconstructParams params;
  params.guide = guide.data();
  std::vector<double> value, mse;
  EXPECT_GT(reconstruct_indirect(a, 16, 16, {flux.data(), sq.data(), hits.data()}, params, value, mse), 0u);
  for (uint32_t t = 0; t < 256; ++t) {
    if (t % 16 >= 8) {
      EXPECT_EQ(value[3 * t], 0.0) << "texel " << t;
    }
  }
  params.guide = nullptr;  // without the guide the edge blurs
  reconstruct_indirect(a, 16, 16, {flux.data(), sq.data(), hits.data()}, params, value, mse);
  EXPECT_GT(value[3 * (5 * 16 + 8)], 0.0);
}

// The local linear fit (the final gather's smoothing) reproduces a linear
// field exactly, also where the guide cuts the neighbourhood to one side (a
// wall's foot, where a mean would be biased), and its variance is the
// intercept's: 1/25 of a texel's over a full 5 x 5 window.
TEST(Reconstruct, LinearFitIsExactOnLinearFieldsEvenOneSided) {
  const TexelAreas a = compute_texel_areas(square16());
  std::vector<double> mean(3 * 256), var(256, 1.0), guide(256), value, out_var;
  for (uint32_t t = 0; t < 256; ++t) {
    const double x = t % 16, y = t / 16;
    for (int c = 0; c < 3; ++c) mean[3 * t + c] = 2.0 + 0.5 * x - 0.25 * y + c;
    guide[t] = x < 8 ? 1.0 : 100.0;  // no pooling across x = 7.5
  }
  guide[5 * 16 + 5] = -1.0;  // pools with no other
  mean[3 * (5 * 16 + 5)] = 1000.0;
  reconstruct_linear(a, 16, 16, mean.data(), var.data(), guide.data(), 2, value, out_var);
  for (uint32_t t = 0; t < 256; ++t) {
    if (t == 5 * 16 + 5) continue;
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(value[3 * t + c], mean[3 * t + c], 1e-9) << "texel " << t;
  }
  EXPECT_NEAR(value[3 * (5 * 16 + 5)], 1000.0, 1e-9);
  EXPECT_NEAR(out_var[10 * 16 + 3], 1.0 / 25.0, 1e-12);  // full window
  EXPECT_GT(out_var[10 * 16 + 7], 1.0 / 25.0);            // one-sided: fewer neighbours, more variance
  EXPECT_LT(out_var[10 * 16 + 7], 1.0);
}

// The fit keeps a lightmap's total where the field curves near its edges:
// bounce light peaking inside a surface and falling towards its edges (a
// ceiling over a sunlit patch), where the fits' windows are one-sided or
// their radius changes from texel to texel (the gather's reach).
TEST(Reconstruct, LinearFitKeepsTheTotal) {
  const TexelAreas a = compute_texel_areas(square16());
  std::vector<double> mean(3 * 256), var(256, 1.0), value, out_var;
  std::vector<uint8_t> radius(256, 2);
  double total = 0.0;
  for (uint32_t t = 0; t < 256; ++t) {
    const double x = t % 16 - 9.0, y = t / 16 - 6.0;
    for (int c = 0; c < 3; ++c) mean[3 * t + c] = std::exp(-(x * x + y * y) / 30.0) * (1.0 + c);
    total += mean[3 * t];
    if (t % 16 == 0 || t / 16 == 15) radius[t] = 0;  // next to a wall
  }
  reconstruct_linear(a, 16, 16, mean.data(), var.data(), nullptr, 2, value, out_var, radius.data());
  double kept = 0.0, kept_blue = 0.0;
  for (uint32_t t = 0; t < 256; ++t) kept += value[3 * t], kept_blue += value[3 * t + 2];
  std::printf("[ measured ] the fit keeps %.5f of the total\n", kept / total);
  EXPECT_NEAR(kept / total, 1.0, 0.005);  // 0.955 without the scale
  EXPECT_NEAR(kept_blue / kept, 3.0, 1e-12);  // the same scale for every channel of a grey field
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

// A texel between two islands that touches one by an edge and the other by a
// corner takes the first alone: bilinear filtering at the first island's
// border then reads its own value, not a blend with its neighbour's.
TEST(Dilate, EdgeNeighboursBeforeCorners) {
  std::vector<float> v(3 * 3, 0.0f);
  std::vector<uint8_t> filled(9, 0);
  v[3] = 1.0f, filled[3] = 1;  // (0, 1): an edge neighbour of the centre
  v[2] = 9.0f, filled[2] = 1;  // (2, 0): a corner neighbour of the centre
  dilate(v, 1, filled, 3, 3, 1);
  EXPECT_EQ(v[4], 1.0f);
  EXPECT_EQ(v[1], 9.0f);  // (1, 0): (2, 0) by an edge, (0, 1) by a corner
  EXPECT_EQ(v[8], 0.0f);  // (2, 2): no filled neighbour yet
  EXPECT_EQ(filled[8], 0);
}

}  // namespace
}  // namespace plm

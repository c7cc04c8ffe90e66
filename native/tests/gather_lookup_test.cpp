// The texel a final-gather ray looks up: a hit on a triangle's edge that lies
// on a texel boundary rounds into the texel beyond it, which the triangle does
// not cover (no area, nothing to look up). The gather then counted the ray as
// unknown and dropped the texel's whole gather; on a subdivided monkey's island
// borders one such ray in 256 left a barely covered texel with the photon
// estimate of a sliver (docs/design/error-and-gather.md, "Where the gather is
// not used").
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "lightmap/texel_area.h"
#include "transport/rays/tracing.h"

namespace plm {
namespace {

// One triangle whose UVs cover the left half of a 2 x 1 lightmap's texel 0,
// (0, 0)-(0.5, 0)-(0.5, 1), its right edge on the boundary with texel 1.
Mesh half_texel_triangle() {
  Mesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 2, 0}, {0, 0, 0}};  // one padding element
  m.vertex_count = 3;
  m.indices = {0, 1, 2};
  m.uv = {0.0f, 0.0f, 0.5f, 0.0f, 0.5f, 1.0f};
  m.material_ids = {0};
  m.lightmap_width = 2;
  m.lightmap_height = 1;
  return m;
}

TEST(GatherLookup, HitOnAnIslandEdgeLooksUpTheTexelItsTriangleCovers) {
  const Mesh m = half_texel_triangle();
  const TexelAreas ta = compute_texel_areas(m);
  ASSERT_GT(ta.area[0], 0.0);
  ASSERT_EQ(ta.area[1], 0.0);  // the triangle does not reach texel 1
  // Points on the edge from corner 1 to corner 2 (u = 0.5): barycentrics bu + bv = 1.
  int rounded_beyond = 0;
  for (int i = 1; i < 100; ++i) {
    const float bv = float(i) / 100.0f, bu = 1.0f - bv;
    const int64_t plain = uv_texel(m.uv.data(), bu, bv, 2, 1);
    rounded_beyond += plain == 1;
    EXPECT_EQ(covered_uv_texel(m.uv.data(), bu, bv, 2, 1, ta.area.data()), 0) << "bv " << bv;
  }
  EXPECT_GT(rounded_beyond, 0);  // the cause: the edge's points land in the uncovered texel
  // Inside the triangle nothing moves.
  EXPECT_EQ(covered_uv_texel(m.uv.data(), 0.3f, 0.3f, 2, 1, ta.area.data()), 0);
}

TEST(GatherLookup, TriangleWithoutUvAreaFindsNoTexel) {
  Mesh m = half_texel_triangle();
  m.uv = {0.75f, 0.5f, 0.75f, 0.5f, 0.75f, 0.5f};  // all corners on one point of texel 1
  std::vector<double> area = {1.0, 0.0};            // texel 1 holds nothing
  EXPECT_EQ(covered_uv_texel(m.uv.data(), 0.2f, 0.3f, 2, 1, area.data()), -1);
  EXPECT_EQ(covered_uv_texel(m.uv.data(), NAN, 0.3f, 2, 1, area.data()), -1);
}

}  // namespace
}  // namespace plm

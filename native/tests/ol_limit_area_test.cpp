// OL area estimation on the subdivision limit surface (subdiv/limit_area.h):
// a cube cage's limit surface against a very fine uniform refinement, bins
// against the total, determinism, honest errors, and bakes of OL groups with
// a cage member (energy balance; furnace read through the limit areas).
#include "subdiv/limit_area.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <vector>

#include "demo_scenes.h"
#include "ol/octahedral.h"
#include "photonlm/photonlm.h"
#include "test_support.h"

namespace plm::subdiv {
namespace {

// Blender's default cube [-1, 1]^3, faces wound outward.
struct CubeCage {
  std::vector<float> p = {1, 1, 1, 1, 1, -1, 1, -1, 1, 1, -1, -1, -1, 1, 1, -1, 1, -1, -1, -1, 1, -1, -1, -1};
  std::vector<uint32_t> sizes = {4, 4, 4, 4, 4, 4};
  std::vector<uint32_t> idx = {0, 4, 6, 2, 3, 2, 6, 7, 7, 6, 4, 5, 5, 1, 3, 7, 1, 0, 2, 3, 5, 4, 0, 1};
  Cage cage(uint32_t level) const {
    Cage c;
    c.positions = p.data();
    c.vertex_count = 8;
    c.face_sizes = sizes.data();
    c.face_count = 6;
    c.face_indices = idx.data();
    c.level = level;
    return c;
  }
};

// A pentagonal prism with a crease: n-gons (several ptex faces) and sharp edges.
struct PrismCage {
  std::vector<float> p;
  std::vector<uint32_t> sizes = {5, 5, 4, 4, 4, 4, 4};
  std::vector<uint32_t> idx;
  std::vector<uint32_t> creases = {0, 1, 1, 2};
  std::vector<float> weights = {1.0f, 0.6f};
  PrismCage() {
    for (int z = 0; z < 2; ++z)
      for (int i = 0; i < 5; ++i)
        p.insert(p.end(), {float(std::cos(2 * M_PI * i / 5)), float(std::sin(2 * M_PI * i / 5)), float(z) * 1.5f});
    idx = {4, 3, 2, 1, 0, 5, 6, 7, 8, 9};  // bottom (down), top (up)
    for (uint32_t i = 0; i < 5; ++i) idx.insert(idx.end(), {i, (i + 1) % 5, 5 + (i + 1) % 5, 5 + i});
  }
  Cage cage(uint32_t level) const {
    Cage c;
    c.positions = p.data();
    c.vertex_count = 10;
    c.face_sizes = sizes.data();
    c.face_count = 7;
    c.face_indices = idx.data();
    c.crease_edges = creases.data();
    c.crease_weights = weights.data();
    c.crease_count = 2;
    c.level = level;
    return c;
  }
};

// Exact per-bin areas of the refined triangles.
std::vector<double> triangle_bins(const RefinedMesh& m, const ol::OctGrid& grid, double& total) {
  std::vector<double> area(grid.bins(), 0.0);
  total = 0.0;
  for (uint32_t t = 0; t < m.triangle_count(); ++t) {
    Vec3d q[3];
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = m.indices[3 * t + k];
      q[k] = Vec3d{m.positions[3 * v], m.positions[3 * v + 1], m.positions[3 * v + 2]};
    }
    const Vec3d n = cross(q[1] - q[0], q[2] - q[0]);
    const double len = length(n);
    if (!(len > 0.0)) continue;
    area[grid.bin(n * (1.0 / len))] += 0.5 * len;
    total += 0.5 * len;
  }
  return area;
}

void check_against_fine(const char* what, const Cage& coarse, const Cage& fine) {
  const ol::OctGrid grid(8);
  const auto t0 = std::chrono::steady_clock::now();
  const ol::AreaEstimate e = estimate_limit_area(what, coarse, grid, {20000, 7});
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  double fine_total = 0.0, coarse_total = 0.0;
  const std::vector<double> ref = triangle_bins(refine(what, fine), grid, fine_total);
  triangle_bins(refine(what, coarse), grid, coarse_total);
  std::printf("[ %s ] limit %.6f +- %.2g (%llu samples, %.1f ms), level-%u triangles %.6f, level-%u %.6f\n", what,
              e.total, e.total_error(), (unsigned long long)e.samples, ms, fine.level, fine_total, coarse.level,
              coarse_total);
  // The fine refinement's triangles are chords of the limit surface: a deficit of O(4^-level).
  const double fine_bias = 2e-4 * fine_total;
  EXPECT_NEAR(e.total, fine_total, 4.5 * e.total_error() + fine_bias) << what;
  EXPECT_LT(e.total_error(), 1e-3 * e.total) << what;
  // The limit surface has clearly more area than the coarse level's triangles.
  EXPECT_GT(e.total - coarse_total, 10.0 * e.total_error() + fine_bias) << what;
  double sum = 0.0, z2 = 0.0;
  int covered = 0;
  // A sliver of a bin that no sample hit reads 0 with 0 error: allow the area of ~5 samples.
  const double sliver = 5.0 * e.total / double(e.samples);
  for (size_t b = 0; b < grid.bins(); ++b) {
    sum += e.area[b];
    EXPECT_NEAR(e.area[b], ref[b], 4.5 * e.error(uint32_t(b)) + 1e-3 * ref[b] + sliver) << what << " bin " << b;
    if (ref[b] > 1e-3 * fine_total) {
      const double z = (e.area[b] - ref[b]) / std::sqrt(e.variance[b] + 1e-30);
      z2 += z * z;
      ++covered;
    }
  }
  EXPECT_NEAR(sum, e.total, 1e-12 * e.total) << what;
  ASSERT_GT(covered, 10) << what;
  std::printf("[ %s ] %d bins, mean z^2 %.3f\n", what, covered, z2 / covered);
  EXPECT_LT(z2 / covered, 2.0) << what;  // the collapsed-strata errors are not too small
}

TEST(OlLimitArea, CubeLimitSurfaceMatchesLevel7Triangles) {
  const CubeCage cube;
  check_against_fine("cube", cube.cage(1), cube.cage(7));
}

TEST(OlLimitArea, CreasedPrismMatchesLevel7Triangles) {
  const PrismCage prism;
  check_against_fine("prism", prism.cage(1), prism.cage(7));
}

TEST(OlLimitArea, SameSeedSameAreasOtherSeedOtherAreas) {
  const CubeCage cube;
  const ol::OctGrid grid(8);
  const ol::AreaEstimate a = estimate_limit_area("cube", cube.cage(2), grid, {5000, 3});
  const ol::AreaEstimate b = estimate_limit_area("cube", cube.cage(2), grid, {5000, 3});
  const ol::AreaEstimate c = estimate_limit_area("cube", cube.cage(2), grid, {5000, 4});
  EXPECT_EQ(a.area, b.area);
  EXPECT_EQ(a.variance, b.variance);
  EXPECT_NE(a.area, c.area);
  // Two seeds agree within their errors.
  EXPECT_NEAR(a.total, c.total, 4.5 * std::hypot(a.total_error(), c.total_error()));
}

// The reported total error is an upper bound of the real spread over seeds.
TEST(OlLimitArea, ErrorCoversTheSpreadOverSeeds) {
  const CubeCage cube;
  const ol::OctGrid grid(4);
  constexpr int kSeeds = 40;
  double mean = 0.0, sq = 0.0, reported = 0.0;
  for (int s = 0; s < kSeeds; ++s) {
    const ol::AreaEstimate e = estimate_limit_area("cube", cube.cage(1), grid, {2000, uint64_t(100 + s)});
    mean += e.total;
    sq += e.total * e.total;
    reported += e.total_variance;
  }
  mean /= kSeeds;
  const double spread = std::sqrt(std::fmax(0.0, (sq / kSeeds - mean * mean) * kSeeds / (kSeeds - 1)));
  const double err = std::sqrt(reported / kSeeds);
  std::printf("[ seeds ] total %.6f, spread %.3g, reported error %.3g\n", mean, spread, err);
  EXPECT_GT(spread, 0.0);
  EXPECT_LE(spread, 1.5 * err);
}

// docs/benchmarks/geometry.md: set-up time and area error against samples (run with
// --gtest_also_run_disabled_tests --gtest_filter=OlLimitArea.DISABLED_TimeAndErrorAgainstSamples).
TEST(OlLimitArea, DISABLED_TimeAndErrorAgainstSamples) {
  const CubeCage cube;
  // A bigger cage: the level-3 cube's 384 quads (triangle pairs 0-1-2, 0-2-3).
  const RefinedMesh l3 = refine("cube", cube.cage(3));
  std::vector<uint32_t> sizes(l3.triangle_count() / 2, 4), quads;
  for (uint32_t q = 0; q < l3.triangle_count() / 2; ++q)
    quads.insert(quads.end(), {l3.indices[6 * q], l3.indices[6 * q + 1], l3.indices[6 * q + 2], l3.indices[6 * q + 5]});
  Cage big;
  big.positions = l3.positions.data();
  big.vertex_count = l3.vertex_count();
  big.face_sizes = sizes.data();
  big.face_count = uint32_t(sizes.size());
  big.face_indices = quads.data();
  struct Case {
    const char* name;
    Cage cage;
    uint32_t fine_level;
  };
  Cage big5 = big;
  big5.level = 5;
  const Case cases[] = {{"cube cage (6 quads)", cube.cage(2), 7}, {"384-quad cage", big, 5}};
  const ol::OctGrid grid(16);
  std::printf("| cage | samples | drawn | set-up + sampling (ms) | total rel. error | reported | bins L1 rel. error |\n");
  for (const Case& c : cases) {
    Cage fine = c.fine_level == 7 ? cube.cage(7) : big5;
    double ref_total = 0.0, coarse_total = 0.0;
    const std::vector<double> ref = triangle_bins(refine(c.name, fine), grid, ref_total);
    auto t0 = std::chrono::steady_clock::now();
    const RefinedMesh coarse = refine(c.name, c.cage);
    const double refine_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    triangle_bins(coarse, grid, coarse_total);
    std::printf("| %s: level-%u refinement for reference | | | %.1f | %.2e (level-%u triangles) | | |\n", c.name,
                c.cage.level, refine_ms, coarse_total / ref_total - 1.0, c.cage.level);
    for (uint64_t n : {1000ull, 4000ull, 20000ull, 100000ull, 1000000ull}) {
      t0 = std::chrono::steady_clock::now();
      const ol::AreaEstimate e = estimate_limit_area(c.name, c.cage, grid, {n, 1});
      const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      double l1 = 0.0;
      for (size_t b = 0; b < grid.bins(); ++b) l1 += std::fabs(e.area[b] - ref[b]);
      std::printf("| %s | %llu | %llu | %.1f | %.2e | %.2e | %.2e |\n", c.name, (unsigned long long)n,
                  (unsigned long long)e.samples, ms, e.total / ref_total - 1.0, e.total_error() / ref_total,
                  l1 / ref_total);
    }
  }
}

// ---- bakes through the C API ----

using plm_demo::SceneBuilder;

uint32_t add_cage(SceneBuilder& b, const CubeCage& cube, uint32_t mat, uint32_t level, bool inward) {
  std::vector<uint32_t> idx = cube.idx;
  if (inward)
    for (size_t f = 0; f < 6; ++f) std::swap(idx[4 * f + 1], idx[4 * f + 3]);
  const std::vector<uint32_t> mats(6, mat);
  uint32_t mesh = 0;
  EXPECT_EQ(plm_scene_add_subdiv_mesh(b.scene, "cage", cube.p.data(), 8, cube.sizes.data(), 6, idx.data(), nullptr,
                                      mats.data(), nullptr, nullptr, 0, level, 0, 0, &mesh),
            PLM_OK)
      << plm_last_error();
  return mesh;
}

struct OlRead {
  std::vector<float> rgb, error, area;
  plm_ol_stats stats = plm_test::sized<plm_ol_stats>();
};

OlRead bake_ol(SceneBuilder& b, uint32_t mesh, uint32_t resolution, uint64_t photons, plm_test::BakeResult& r,
               bool limit_area = true) {
  uint32_t g = 0;
  EXPECT_EQ(plm_scene_add_ol_group(b.scene, "cage group", resolution, &g), PLM_OK) << plm_last_error();
  EXPECT_EQ(plm_scene_set_ol_group_limit_area(b.scene, g, limit_area ? 1 : 0), PLM_OK) << plm_last_error();
  EXPECT_EQ(plm_scene_set_mesh_ol_group(b.scene, mesh, g), PLM_OK) << plm_last_error();
  plm_bake_settings s;
  plm_bake_settings_default(&s);
  s.photon_count = photons;
  s.direct_samples = 16;
  OlRead o;
  EXPECT_TRUE(b.ok()) << b.error;
  EXPECT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r.r), PLM_OK) << plm_last_error();
  if (!r.r) return o;
  const float *rgb = nullptr, *err = nullptr, *area = nullptr, *hits = nullptr;
  uint32_t n = 0;
  EXPECT_EQ(plm_result_ol(r.r, g, &rgb, &err, &n), PLM_OK) << plm_last_error();
  EXPECT_EQ(plm_result_ol_bins(r.r, g, &area, &hits), PLM_OK) << plm_last_error();
  EXPECT_EQ(plm_result_ol_stats(r.r, g, &o.stats), PLM_OK) << plm_last_error();
  o.rgb.assign(rgb, rgb + 3 * size_t(n) * n);
  o.error.assign(err, err + size_t(n) * n);
  o.area.assign(area, area + size_t(n) * n);
  return o;
}

// A black cage around a point light: every photon ends on it, and the OL,
// read through the limit-surface areas, still holds exactly the light's power.
TEST(OlLimitArea, BlackCageAroundPointLightHoldsItsPower) {
  const CubeCage cube;
  SceneBuilder b;
  const uint32_t black = b.material("black", {0, 0, 0});
  const uint32_t mesh = add_cage(b, cube, black, 2, true);  // facing the light inside
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_POINT);
  l.power = 100.0f;
  l.radius = 0.0f;
  l.matrix[3] = 0.1f;
  l.matrix[7] = -0.2f;
  b.light(l, "lamp");
  plm_test::BakeResult r;
  const OlRead o = bake_ol(b, mesh, 8, 300000, r);
  ASSERT_TRUE(r.r);
  double sum = 0.0, area = 0.0;
  for (size_t k = 0; k < o.area.size(); ++k) {
    sum += (double(o.rgb[3 * k]) + o.rgb[3 * k + 1] + o.rgb[3 * k + 2]) / 3.0 * M_PI * o.area[k];
    area += o.area[k];
  }
  std::vector<uint32_t> inward = cube.idx;
  for (size_t f = 0; f < 6; ++f) std::swap(inward[4 * f + 1], inward[4 * f + 3]);
  Cage c = cube.cage(2);
  c.face_indices = inward.data();
  double tri_total = 0.0;
  const ol::OctGrid grid(8);
  triangle_bins(refine("cube", c), grid, tri_total);
  const ol::AreaEstimate e = estimate_limit_area("cube", c, grid, {kLimitAreaSamples, 1});
  std::printf("[ black cage ] recorded %.7f W of 100 W, orphan %.3g; OL area %.6f, limit %.6f +- %.2g, level-2 "
              "triangles %.6f\n", sum, o.stats.orphan_flux, area, e.total, e.total_error(), tri_total);
  EXPECT_NEAR(sum, 100.0, 1e-4 * 100.0);
  EXPECT_NEAR(o.stats.flux, 100.0, 1e-4 * 100.0);
  EXPECT_EQ(o.stats.orphan_flux, 0.0);
  // The OL's area is the limit surface's, not the traced triangles'.
  EXPECT_NEAR(area, e.total, 4.5 * e.total_error() + 1e-6 * area);
  EXPECT_GT(area - tri_total, 10.0 * e.total_error());
}

// An inward cage furnace (albedo rho, emission e): the traced triangles of
// area A_tri hold the exact e / (1 - rho); spread over the limit surface's
// larger area A_lim, each bin reads e / (1 - rho) * A_tri / A_lim (on average).
TEST(OlLimitArea, FurnaceCageReadsThroughTheLimitArea) {
  const CubeCage cube;
  const float rho = 0.5f;
  SceneBuilder b;
  const uint32_t m = b.material("furnace", {rho, rho, rho}, {1, 1, 1});
  const uint32_t mesh = add_cage(b, cube, m, 1, true);
  plm_test::BakeResult r;
  const OlRead o = bake_ol(b, mesh, 4, 1000000, r);
  ASSERT_TRUE(r.r);
  double flux = 0.0, area = 0.0;
  for (size_t k = 0; k < o.area.size(); ++k) {
    flux += (double(o.rgb[3 * k]) + o.rgb[3 * k + 1] + o.rgb[3 * k + 2]) / 3.0 * o.area[k];
    area += o.area[k];
  }
  std::vector<uint32_t> inward = cube.idx;
  for (size_t f = 0; f < 6; ++f) std::swap(inward[4 * f + 1], inward[4 * f + 3]);
  Cage c = cube.cage(1);
  c.face_indices = inward.data();
  double tri_total = 0.0;
  triangle_bins(refine("cube", c), ol::OctGrid(4), tri_total);
  const double exact = 1.0 / (1.0 - rho), expected = exact * tri_total / area;
  std::printf("[ furnace cage ] area-weighted mean %.5f, expected %.5f (exact on triangles %.5f, A_tri/A_lim %.5f)\n",
              flux / area, expected, exact, tri_total / area);
  EXPECT_NEAR(flux / area, expected, 0.01 * expected);
  EXPECT_GT(std::fabs(flux / area - exact), 0.02 * exact);  // the limit area is what the bake used

  // By default (limit_area off) the bins hold the traced triangles' areas: the exact furnace value.
  SceneBuilder b2;
  const uint32_t m2 = b2.material("furnace", {rho, rho, rho}, {1, 1, 1});
  const uint32_t mesh2 = add_cage(b2, cube, m2, 1, true);
  plm_test::BakeResult r2;
  const OlRead o2 = bake_ol(b2, mesh2, 4, 1000000, r2, false);
  ASSERT_TRUE(r2.r);
  double flux2 = 0.0, area2 = 0.0;
  for (size_t k = 0; k < o2.area.size(); ++k) {
    flux2 += (double(o2.rgb[3 * k]) + o2.rgb[3 * k + 1] + o2.rgb[3 * k + 2]) / 3.0 * o2.area[k];
    area2 += o2.area[k];
  }
  EXPECT_NEAR(area2, tri_total, 1e-6 * tri_total);
  EXPECT_NEAR(flux2 / area2, exact, 0.01 * exact);
}

}  // namespace
}  // namespace plm::subdiv

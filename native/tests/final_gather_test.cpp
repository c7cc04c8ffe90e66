// The final gather's estimate of its own noise (transport/gather/final_gather.h):
// the pair differences of its stratified rays, scaled by its calibration
// texels (gather_scale), against the spread of the gather over independent
// seeds; and the lookups' error statistics against their definitions.
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "accel/embree_scene.h"
#include "api/handles.h"
#include "api/settings.h"
#include "demo_scenes.h"
#include "test_support.h"
#include "transport/film/film.h"
#include "transport/gather/final_gather.h"
#include "transport/rays/tracing.h"

namespace plm {
namespace {

using plm_demo::SceneBuilder;

// The open scene's meshes with made-up radiosity to look up: the ground
// brighter along x, the box uniform; `error` the error every texel reports
// (local; none wide).
// A context with the Embree scene and the texel space, no lights: what the
// gather reads.
std::unique_ptr<BakeScene> gather_context(const Scene& scene, const plm_bake_settings& s) {
  auto ctx = std::make_unique<BakeScene>(scene, api::engine_settings(s, scene), 2);
  std::vector<std::string> warnings;
  ctx->arena.execute([&] { ctx->space = build_texel_space(scene, warnings); });
  ctx->accel = std::make_unique<EmbreeScene>(scene, 2);
  ctx->rtc = ctx->accel->handle();
  ctx->extent = length(ctx->accel->bounds_max() - ctx->accel->bounds_min());
  ctx->surfaces = surface_map(scene, ctx->space.views);
  return ctx;
}

struct GatherScene {
  SceneBuilder b;
  std::unique_ptr<BakeScene> ctx;
  std::vector<std::vector<float>> images, local, wide;
  std::vector<std::vector<Vec3>> albedo;
  std::vector<uint8_t> back_lit;

  explicit GatherScene(float error) {
    plm_test::open_scene(b);
    ctx = gather_context(b.scene->scene, plm_test::settings_with(0, 16));
    const TexelSpace& space = ctx->space;
    for (const MeshView& v : space.views) {
      const uint32_t w = v.mesh->lightmap_width, h = v.mesh->lightmap_height;
      std::vector<float> img(4 * size_t(w) * h, 0.0f);
      for (uint32_t t = 0; t < w * h; ++t)
        for (int c = 0; c < 3; ++c) img[4 * t + c] = &v == &space.views[0] ? 0.5f + float(t % w) / float(w) : 0.8f;
      images.push_back(img);
      local.emplace_back(size_t(w) * h, error);
      wide.emplace_back(size_t(w) * h, 0.0f);
      albedo.emplace_back(v.mesh->triangle_count(), Vec3{0.5f, 0.5f, 0.5f});
    }
    back_lit.assign(space.views.size(), 1);
  }

  GatherResult gather(uint32_t seed, uint32_t samples) const {
    ctx->settings.seed = seed;
    const FinalGather fg(*ctx);
    OpenShares open;
    return run_final_gather(*ctx, fg, {images, local, wide, albedo, back_lit.data()}, open, samples,
                            [] { return true; });
  }
};

// Stratified directions and points make neighbouring strata differ more
// than independent means do: the pairs alone overstate the variance of a
// texel's gather (2x-5x on the benchmark scenes); scaled by the calibration
// texels' replicates, the estimate matches the spread over 24 seeds.
TEST(FinalGather, CalibratedVarianceMatchesTheSpreadOverSeeds) {
  GatherScene g(0.0f);
  ASSERT_TRUE(g.b.ok()) << g.b.error;
  constexpr int kSeeds = 24;
  const size_t n = g.ctx->space.covered.size();
  std::vector<double> sum(n, 0.0), sum_sq(n, 0.0), estimated(n, 0.0), pairs(n, 0.0);
  double scale_sum = 0.0;
  for (int seed = 0; seed < kSeeds; ++seed) {
    const GatherResult r = g.gather(uint32_t(seed + 1), 16);
    ASSERT_EQ(r.sums.size(), n);
    scale_sum += r.scale;
    for (size_t k = 0; k < n; ++k) {
      const double m = r.sums[k].mean();
      sum[k] += m;
      sum_sq[k] += m * m;
      estimated[k] += r.sums[k].variance_of_mean(r.typical, 0.0, r.scale) / kSeeds;
      pairs[k] += r.sums[k].variance_of_mean(r.typical) / kSeeds;
    }
  }
  double spread = 0.0, est = 0.0, raw = 0.0;
  for (size_t k = 0; k < n; ++k) {
    spread += (sum_sq[k] - sum[k] * sum[k] / kSeeds) / (kSeeds - 1);
    est += estimated[k];
    raw += pairs[k];
  }
  std::printf("[ measured ] gather variance over %d seeds: calibrated estimate %.2fx, pairs alone %.2fx (scale %.3f)\n",
              kSeeds, est / spread, raw / spread, scale_sum / kSeeds);
  EXPECT_GT(est / spread, 0.75);
  EXPECT_LT(est / spread, 1.33);
  EXPECT_GT(raw / spread, 1.5);  // what the calibration corrects
}

// The lookups' error statistics (GatherInfo) against the spread of a texel's
// gather over noise added to what it looks up, its rays fixed: noise shared
// by all texels spreads as lookup_all, noise shared within the cells of a
// photon pool's reach (5 texels for filter radius 2) as lookup_cells, and
// independent noise per texel between lookup_rays and lookup_cells.
TEST(FinalGather, LookupErrorStatisticsBracketTheSpread) {
  constexpr float kError = 0.05f;
  GatherScene g(kError);
  ASSERT_TRUE(g.b.ok()) << g.b.error;
  const GatherResult base = g.gather(1, 16);
  const size_t n = g.ctx->space.covered.size();
  double all = 0.0, cells = 0.0, rays = 0.0;
  for (const GatherInfo& i : base.info) all += i.lookup_all, cells += i.lookup_cells, rays += i.lookup_rays;
  ASSERT_GT(rays, 0.0);
  EXPECT_LE(rays, cells);
  EXPECT_LT(cells, all);
  const std::vector<std::vector<float>> clean = g.images;
  enum Shared { kEverywhere, kCell, kTexel };
  for (const Shared shared : {kEverywhere, kCell, kTexel}) {
    std::mt19937 gen(7);
    std::normal_distribution<float> noise(0.0f, kError);
    constexpr int kTrials = 48;
    std::vector<double> sum(n, 0.0), sum_sq(n, 0.0);
    for (int trial = 0; trial < kTrials; ++trial) {
      const float offset = noise(gen);
      for (size_t i = 0; i < g.images.size(); ++i) {
        const uint32_t w = g.ctx->space.views[i].mesh->lightmap_width;
        std::vector<float> cell_noise(size_t(w / 5 + 1) * (g.images[i].size() / 4 / w / 5 + 1));
        for (float& c : cell_noise) c = noise(gen);
        for (size_t t = 0; 4 * t < g.images[i].size(); ++t) {
          const float e = shared == kEverywhere ? offset
                          : shared == kCell    ? cell_noise[(t / w / 5) * (w / 5 + 1) + t % w / 5]
                                               : noise(gen);
          for (int c = 0; c < 3; ++c) g.images[i][4 * t + c] = clean[i][4 * t + c] + e;
        }
      }
      const GatherResult r = g.gather(1, 16);
      for (size_t k = 0; k < n; ++k) {
        const double m = r.sums[k].mean();
        sum[k] += m;
        sum_sq[k] += m * m;
      }
    }
    double spread = 0.0;
    for (size_t k = 0; k < n; ++k) spread += (sum_sq[k] - sum[k] * sum[k] / kTrials) / (kTrials - 1);
    std::printf("[ measured ] lookups' noise shared %s: spread / all %.2f, / cells %.2f, / rays %.2f\n",
                shared == kEverywhere ? "everywhere" : shared == kCell ? "by cells" : "by no texels", spread / all,
                spread / cells, spread / rays);
    if (shared == kEverywhere) {
      EXPECT_NEAR(spread / all, 1.0, 0.3);
    } else if (shared == kCell) {
      EXPECT_NEAR(spread / cells, 1.0, 0.3);
    } else {
      EXPECT_GT(spread / rays, 0.7);
      EXPECT_LT(spread / cells, 1.3);
    }
  }
}

}  // namespace
}  // namespace plm

namespace plm {
namespace {

// The ground's closed area by open_share (sum over its texels of the closed
// share times the texel's area): under a box standing on it, 1 m^2.
double closed_ground_area(const SceneBuilder& b, bool with_contact, std::vector<uint8_t> back_lit, double* far_min) {
  const Scene& scene = b.scene->scene;
  const std::unique_ptr<BakeScene> ctx = gather_context(scene, plm_test::settings_with(0, 16));
  TexelSpace& space = ctx->space;
  if (with_contact) {
    ctx->contact = contact_candidates(ctx->rtc, scene, space.views, ctx->surfaces, 1e-6f * ctx->extent);
    for (size_t i = 0; i < space.views.size(); ++i)
      if (!ctx->contact[i].empty()) space.views[i].contact = ctx->contact[i].data();
  }
  const FinalGather fg(*ctx);
  const MeshView& ground = space.views[0];
  double closed = 0.0;
  *far_min = 1.0;
  for (uint32_t t = 0; t < ground.mesh->lightmap_width * ground.mesh->lightmap_height; ++t) {
    if (!(space.areas[0].area[t] > 0.0)) continue;
    const double open = fg.open_share(0, t, back_lit.data());
    closed += (1.0 - open) * space.areas[0].area[t];
    const uint32_t x = t % ground.mesh->lightmap_width, y = t / ground.mesh->lightmap_width;
    const double cx = -4.0 + 8.0 * (x + 0.5) / ground.mesh->lightmap_width;
    const double cy = -4.0 + 8.0 * (y + 0.5) / ground.mesh->lightmap_height;
    if (cx * cx + cy * cy > 1.5 * 1.5) *far_min = std::min(*far_min, open);
  }
  return closed;
}

// A texel partly under a box holds the mean over the whole texel, dark part
// included, while a gather ray lands on its lit part: open_share finds the
// dark part under a closed box (its bottom pressed on the ground: in
// contact) and under an open one (five faces: the back of a mesh no photon
// reached), and nothing elsewhere or where the box's backs are lit.
TEST(FinalGather, OpenShareFindsTheGroundUnderABox) {
  SceneBuilder closed_box;
  plm_test::open_scene(closed_box, true, false, 64);  // the ground (mesh 0) and a 1 x 1 m box, turned
  double far_min = 0.0;
  const double closed = closed_ground_area(closed_box, true, {1, 1}, &far_min);
  EXPECT_NEAR(closed, 1.0, 0.05);
  EXPECT_EQ(far_min, 1.0);

  SceneBuilder open_box;  // the same box without its bottom: five quads, each a mesh
  const uint32_t ground = open_box.material("ground", {0.35f, 0.42f, 0.30f});
  const uint32_t white = open_box.material("box", {0.8f, 0.8f, 0.8f});
  open_box.quad("ground", {-4, -4, 0}, {8, 0, 0}, {0, 8, 0}, ground, 64);
  open_box.quad("top", {-0.5f, -0.5f, 1.5f}, {1, 0, 0}, {0, 1, 0}, white, 8);
  open_box.quad("x+", {0.5f, -0.5f, 0}, {0, 1, 0}, {0, 0, 1.5f}, white, 8);
  open_box.quad("x-", {-0.5f, 0.5f, 0}, {0, -1, 0}, {0, 0, 1.5f}, white, 8);
  open_box.quad("y+", {0.5f, 0.5f, 0}, {-1, 0, 0}, {0, 0, 1.5f}, white, 8);
  open_box.quad("y-", {-0.5f, -0.5f, 0}, {1, 0, 0}, {0, 0, 1.5f}, white, 8);
  const double inside = closed_ground_area(open_box, true, {1, 0, 0, 0, 0, 0}, &far_min);
  EXPECT_NEAR(inside, 1.0, 0.05);
  EXPECT_EQ(far_min, 1.0);
  std::printf("[ measured ] ground closed under a 1 m^2 box: %.4f m^2 (bottom in contact), %.4f m^2 (no bottom)\n",
              closed, inside);
  // Backs that photons reached are a roof, not the inside of a box: open.
  EXPECT_EQ(closed_ground_area(open_box, true, {1, 1, 1, 1, 1, 1}, &far_min), 0.0);
}

}  // namespace
}  // namespace plm

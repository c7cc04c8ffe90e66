// Sharded bakes (transport/farm/shard.h, transport/farm/partial_file.h): the merge of N shards is
// the single-machine bake bit for bit, for any N; parts that do not belong
// together, or are damaged, are refused naming the part.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "demo_scenes.h"
#include "photonlm/photonlm.h"
#include "test_support.h"
#include "transport/film/film.h"
#include "transport/photons/photon_tracer.h"
#include "transport/farm/shard.h"
#include "transport/plan/scheduler.h"
#include "transport/farm/texel_ranges.h"
#include "transport/farm/partial_file.h"
#include "util/error.h"

namespace {

using plm_test::BakeResult;
using plm_test::Map;

struct TempDir {
  std::string path;
  TempDir() {
    path = (std::filesystem::temp_directory_path() / ("plm_shard_test_" + std::to_string(getpid()) + "_" +
                                                       std::to_string(counter()++)))
               .string();
    std::filesystem::create_directories(path);
  }
  ~TempDir() { std::filesystem::remove_all(path); }
  static int& counter() {
    static int n = 0;
    return n;
  }
};

plm_bake_settings small_settings(uint64_t photons) {
  plm_bake_settings s;
  plm_bake_settings_default(&s);
  s.photon_count = photons;
  s.direct_samples = 4;
  s.seed = 7;
  s.thread_count = 2;
  return s;
}

std::vector<std::string> bake_shards(plm_scene* scene, const plm_bake_settings& s, uint32_t n, const std::string& dir,
                                     const char* scene_label = "cornell") {
  std::vector<std::string> parts;
  for (uint32_t k = 0; k < n; ++k) {
    parts.push_back(dir + "/part-" + std::to_string(k) + "-of-" + std::to_string(n) + ".plmpart");
    EXPECT_EQ(plm_bake_shard(scene, &s, k, n, scene_label, parts.back().c_str(), nullptr, nullptr), PLM_OK)
        << plm_last_error();
  }
  return parts;
}

// Merges `parts`; returns the status and leaves the message in error.
plm_status merge(plm_scene* scene, const std::vector<std::string>& parts, BakeResult& out, std::string& error) {
  std::vector<const char*> p;
  for (const std::string& s : parts) p.push_back(s.c_str());
  const plm_status st = plm_bake_merge(scene, p.data(), uint32_t(p.size()), 2, nullptr, nullptr, &out.r);
  error = st == PLM_OK ? "" : plm_last_error();
  return st;
}

void expect_same_bits(const std::vector<float>& a, const std::vector<float>& b, const char* what, uint32_t mesh) {
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0) << what << " of mesh " << mesh;
}

void expect_identical(const BakeResult& one, const BakeResult& merged, uint32_t meshes) {
  for (uint32_t m = 0; m < meshes; ++m) {
    uint32_t w = 0, h = 0;
    if (plm_result_lightmap_size(one.r, m, &w, &h) != PLM_OK || w == 0) continue;
    const Map a = one.map(m), b = merged.map(m);
    expect_same_bits(a.rgb, b.rgb, "rgb", m);
    expect_same_bits(a.error, b.error, "error", m);
    expect_same_bits(a.hits, b.hits, "hits", m);
    expect_same_bits(a.coverage, b.coverage, "coverage", m);
  }
  plm_bake_stats x = plm_test::sized<plm_bake_stats>(), y = x;
  ASSERT_EQ(plm_result_stats(one.r, &x), PLM_OK);
  ASSERT_EQ(plm_result_stats(merged.r, &y), PLM_OK);
  EXPECT_EQ(x.photons_emitted, y.photons_emitted);
  EXPECT_EQ(x.photon_hits, y.photon_hits);
  EXPECT_EQ(x.rays_traced, y.rays_traced);
  EXPECT_EQ(x.paths_truncated, y.paths_truncated);
  EXPECT_EQ(x.direct_samples, y.direct_samples);
  EXPECT_EQ(std::memcmp(&x.error_estimate, &y.error_estimate, sizeof(double)), 0);
  EXPECT_EQ(std::memcmp(&x.error_p95, &y.error_p95, sizeof(double)), 0);
}

uint32_t mesh_count(const plm_demo::SceneBuilder& b) { return uint32_t(b.mesh_names.size()); }

}  // namespace

// Fluxes rounded to the quantum add up exactly: any order, any split into
// partial sums, gives the same bits (what makes shards merge exactly).
TEST(Shard, QuantizedSumsDoNotDependOnOrder) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> flux(0.0f, 1.0f), tiny(0.0f, 1e-6f);
  const uint64_t texels = 7;
  const plm::FluxQuantum q = plm::flux_quantum(1.0);
  std::vector<plm::BatchOutput> batches(40);
  for (auto& b : batches)
    for (int i = 0; i < 500; ++i) {
      const float f = (i % 3 == 0) ? tiny(rng) : flux(rng);
      b.hits.push_back({uint32_t(rng() % texels), f, f * 0.5f, f * 0.25f});
    }
  plm::Accumulators forward(texels, 1, false, q), backward(texels, 1, false, q), split(texels, 1, false, q),
      second(texels, 1, false, q);
  // A batch's hits added as the photon pass adds them (transport/film/photon_batches.h).
  auto merge = [](plm::Accumulators& a, const plm::BatchOutput& b) {
    a.add_totals(b.hits.size(), a.add_hits(b.hits.data(), b.hits.data() + b.hits.size(), false), false);
  };
  for (const auto& b : batches) merge(forward, b);
  for (size_t i = batches.size(); i-- > 0;) merge(backward, batches[i]);
  for (size_t i = 0; i < 13; ++i) merge(split, batches[i]);
  for (size_t i = 13; i < batches.size(); ++i) merge(second, batches[i]);
  split.add(second);
  for (const plm::Accumulators* a : {&backward, &split}) {
    EXPECT_EQ(std::memcmp(a->sum.data(), forward.sum.data(), forward.sum.size() * sizeof(double)), 0);
    EXPECT_EQ(std::memcmp(a->sum_sq.data(), forward.sum_sq.data(), forward.sum_sq.size() * sizeof(double)), 0);
    EXPECT_EQ(a->total_sq_q, forward.total_sq_q);
    EXPECT_EQ(a->hits, forward.hits);
  }
  // Plain double sums of the same hits do depend on the order (so the test can fail).
  double f = 0, r = 0;
  for (const auto& b : batches)
    for (const auto& h : b.hits) f += h.r;
  for (size_t i = batches.size(); i-- > 0;)
    for (size_t j = batches[i].hits.size(); j-- > 0;) r += batches[i].hits[j].r;
  EXPECT_NE(f, r);
  // The rounding is far below a hit: relative 1e-7 of the summed flux.
  double exact = 0;
  for (size_t t = 0; t < texels; ++t) exact += forward.sum[3 * t];
  EXPECT_NEAR(exact, f, 1e-7 * f);
}

TEST(Shard, BatchesOfShardsTileTheBake) {
  for (uint64_t batches : {1u, 5u, 16u, 17u, 100u})
    for (uint32_t n : {1u, 2u, 3u, 7u, 20u}) {
      uint64_t next = 0;
      for (uint32_t k = 0; k < n; ++k) {
        const auto [first, last] = plm::shard_batches(batches, k, n);
        EXPECT_EQ(first, next);
        EXPECT_LE(last - first, batches / n + 1);
        for (const auto& [b, e] : plm::shard_segments(first, last)) EXPECT_FALSE(b < 16 && e > 16);
        next = last;
      }
      EXPECT_EQ(next, batches);
    }
}

// A Cornell box (final gather on, 150 k photons: the gather's estimate after
// 16 batches falls inside a shard): 1, 2, 3 and 4 shards merge to the
// single-machine bake bit for bit.
TEST(Shard, MergeEqualsSingleBakeForAnyShardCount) {
  plm_demo::SceneBuilder b;
  plm_demo::build_cornell(b, 12);
  ASSERT_TRUE(b.ok()) << b.error;
  const plm_bake_settings s = small_settings(150000);
  BakeResult one;
  ASSERT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &one.r), PLM_OK) << plm_last_error();
  for (uint32_t n = 1; n <= 4; ++n) {
    SCOPED_TRACE("shards " + std::to_string(n));
    TempDir dir;
    plm_bake_settings shard_settings = s;
    shard_settings.thread_count = n;  // threads differ between machines too
    const auto parts = bake_shards(b.scene, shard_settings, n, dir.path);
    BakeResult merged;
    std::string error;
    ASSERT_EQ(merge(b.scene, parts, merged, error), PLM_OK) << error;
    expect_identical(one, merged, mesh_count(b));
  }
}

// Fewer batches than shards (some shards trace nothing), fewer than 16
// batches (the gather comes last), and photons that do not fill a batch.
TEST(Shard, FewPhotonsManyShards) {
  plm_demo::SceneBuilder b;
  plm_demo::build_cornell(b, 8);
  ASSERT_TRUE(b.ok()) << b.error;
  const plm_bake_settings s = small_settings(3 * 4096 + 100);
  BakeResult one;
  ASSERT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &one.r), PLM_OK) << plm_last_error();
  TempDir dir;
  const auto parts = bake_shards(b.scene, s, 6, dir.path);
  BakeResult merged;
  std::string error;
  ASSERT_EQ(merge(b.scene, parts, merged, error), PLM_OK) << error;
  expect_identical(one, merged, mesh_count(b));
}

// Glass (caustic photons have sums of their own) on the Cornell box's floor box.
TEST(Shard, CausticSumsMergeExactly) {
  plm_demo::SceneBuilder b;
  const uint32_t white = b.material("white", {0.7f, 0.7f, 0.7f});
  const uint32_t glass = b.material("glass", {0.0f, 0.0f, 0.0f});
  plm_lobe lobe;
  plm_lobe_default(&lobe, PLM_LOBE_GLASS);
  ASSERT_EQ(plm_scene_add_material_lobe(b.scene, glass, &lobe), PLM_OK) << plm_last_error();
  b.quad("floor", {-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, white, 16);
  b.box("glass block", {0, 0, 0.4f}, {0.4f, 0.4f, 0.2f}, 0.3f, glass, 0);
  plm_light light;
  plm_light_default(&light, PLM_LIGHT_POINT);
  light.power = 100;
  light.matrix[3] = 0.1f;
  light.matrix[11] = 1.2f;
  b.light(light, "lamp");
  ASSERT_TRUE(b.ok()) << b.error;
  const plm_bake_settings s = small_settings(100000);
  BakeResult one;
  ASSERT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &one.r), PLM_OK) << plm_last_error();
  TempDir dir;
  const auto parts = bake_shards(b.scene, s, 3, dir.path);
  BakeResult merged;
  std::string error;
  ASSERT_EQ(merge(b.scene, parts, merged, error), PLM_OK) << error;
  expect_identical(one, merged, mesh_count(b));
}

// Parts that do not belong together are refused, naming the part.
TEST(Shard, MergeRefusesPartsThatDoNotBelong) {
  plm_demo::SceneBuilder b;
  plm_demo::build_cornell(b, 6);
  ASSERT_TRUE(b.ok()) << b.error;
  plm_bake_settings s = small_settings(40000);
  s.direct_samples = 1;
  TempDir dir;
  const auto parts = bake_shards(b.scene, s, 3, dir.path);
  std::string error;
  {  // a shard missing
    BakeResult r;
    EXPECT_EQ(merge(b.scene, {parts[0], parts[2]}, r, error), PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(error.find("shard(s) 2 of 3 missing"), std::string::npos) << error;
  }
  {  // a shard twice
    BakeResult r;
    EXPECT_EQ(merge(b.scene, {parts[0], parts[1], parts[2], parts[1]}, r, error), PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(error.find(parts[1] + ": shard 2 of 3 is also " + parts[1]), std::string::npos) << error;
  }
  {  // another seed
    TempDir other;
    plm_bake_settings t = s;
    t.seed = 8;
    const auto odd = bake_shards(b.scene, t, 3, other.path);
    BakeResult r;
    EXPECT_EQ(merge(b.scene, {parts[0], odd[1], parts[2]}, r, error), PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(error.find(odd[1] + ": does not belong with " + parts[0] + ": its seed 8 against 7"),
              std::string::npos)
        << error;
  }
  {  // another scene given to the merge
    plm_demo::SceneBuilder c;
    plm_demo::build_cornell(c, 7);
    BakeResult r;
    EXPECT_EQ(merge(c.scene, parts, r, error), PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(error.find("another scene"), std::string::npos) << error;
  }
  {  // a damaged payload byte, then a truncated file
    const std::string bad = dir.path + "/bad.plmpart";
    std::filesystem::copy_file(parts[1], bad);
    plm_test::flip_byte(bad, 2000);
    BakeResult r;
    EXPECT_EQ(merge(b.scene, {parts[0], bad, parts[2]}, r, error), PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(error.find(bad + ": the part file's sums are damaged (checksum)"), std::string::npos) << error;
    std::filesystem::resize_file(bad, std::filesystem::file_size(parts[1]) - 10);
    BakeResult r2;
    EXPECT_EQ(merge(b.scene, {parts[0], bad, parts[2]}, r2, error), PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(error.find(bad + ": the part file holds"), std::string::npos) << error;
    std::filesystem::resize_file(bad, 100);
    BakeResult r3;
    EXPECT_EQ(merge(b.scene, {parts[0], bad, parts[2]}, r3, error), PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(error.find(bad + ": too short for a part file"), std::string::npos) << error;
  }
  {  // not a part file at all
    const std::string text = dir.path + "/text.plmpart";
    std::ofstream(text) << std::string(600, 'x');
    BakeResult r;
    EXPECT_EQ(merge(b.scene, {text}, r, error), PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(error.find(text + ": not a photonlm part file"), std::string::npos) << error;
  }
  // No temporary files are left next to the parts.
  for (const auto& e : std::filesystem::directory_iterator(dir.path))
    EXPECT_EQ(e.path().string().find(".tmp-"), std::string::npos) << e.path();
}

// What cannot be split is refused up front with the reason.
TEST(Shard, ShardRefusesWhatCannotBeSplit) {
  plm_demo::SceneBuilder b;
  plm_demo::build_cornell(b, 6);
  ASSERT_TRUE(b.ok()) << b.error;
  TempDir dir;
  const std::string part = dir.path + "/p.plmpart";
  plm_bake_settings s = small_settings(40000);
  s.target_error = 0.05;
  EXPECT_EQ(plm_bake_shard(b.scene, &s, 0, 2, nullptr, part.c_str(), nullptr, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("target error"), std::string::npos) << plm_last_error();
  s = small_settings(40000);
  s.time_budget = 3;
  EXPECT_EQ(plm_bake_shard(b.scene, &s, 0, 2, nullptr, part.c_str(), nullptr, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("time budget"), std::string::npos) << plm_last_error();
  s = small_settings(40000);
  EXPECT_EQ(plm_bake_shard(b.scene, &s, 2, 2, nullptr, part.c_str(), nullptr, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_bake_shard(b.scene, &s, 0, 2, nullptr, (dir.path + "/no/such/folder/p").c_str(), nullptr, nullptr),
            PLM_ERROR_IO);
  EXPECT_NE(std::string(plm_last_error()).find("no/such/folder/p"), std::string::npos) << plm_last_error();
  uint32_t group = 0;
  ASSERT_EQ(plm_scene_add_ol_group(b.scene, "props", 0, &group), PLM_OK) << plm_last_error();
  EXPECT_EQ(plm_bake_shard(b.scene, &s, 0, 2, nullptr, part.c_str(), nullptr, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("OL groups"), std::string::npos) << plm_last_error();
  EXPECT_FALSE(std::filesystem::exists(part));
}

// A sum past 2^53 quanta is no longer exact: the merge says so.
TEST(Shard, SumsPastTheExactRangeAreReported) {
  const plm::FluxQuantum q = plm::flux_quantum(100.0);
  plm::Accumulators acc(4, 1, false, q);
  EXPECT_EQ(plm::inexact_sums(acc), "");
  acc.sum[5] = std::ldexp(1.0, 52) * q.q;  // still exact
  EXPECT_EQ(plm::inexact_sums(acc), "");
  acc.sum[5] = std::ldexp(1.0, 53) * q.q;
  acc.sum_sq[2] = std::ldexp(1.0, 54) * q.q2;
  EXPECT_NE(plm::inexact_sums(acc).find("2 photon sums passed 2^53 flux quanta"), std::string::npos)
      << plm::inexact_sums(acc);
}

// ---- Texel ranges (transport/farm/texel_ranges.h): the direct pass and the final
// gather split by ranges of covered texels.
namespace {

std::vector<std::string> bake_ranges(plm_scene* scene, const plm_bake_settings& s, uint32_t stage, uint32_t n,
                                     const std::vector<std::string>& inputs, const std::string& dir) {
  std::vector<const char*> in;
  for (const std::string& p : inputs) in.push_back(p.c_str());
  std::vector<std::string> parts;
  for (uint32_t k = 0; k < n; ++k) {
    parts.push_back(dir + (stage == PLM_TEXELS_DIRECT ? "/direct-" : "/gather-") + std::to_string(k) + "-of-" +
                    std::to_string(n) + ".plmpart");
    EXPECT_EQ(plm_bake_texels(scene, &s, stage, k, n, in.data(), uint32_t(in.size()), "cornell", parts.back().c_str(),
                              nullptr, nullptr),
              PLM_OK)
        << plm_last_error();
  }
  return parts;
}

std::vector<std::string> joined(std::initializer_list<std::vector<std::string>> lists) {
  std::vector<std::string> out;
  for (const auto& l : lists) out.insert(out.end(), l.begin(), l.end());
  return out;
}

}  // namespace

TEST(TexelRanges, RangesTileTheCoveredTexels) {
  for (size_t covered : {0u, 1u, 5u, 1000u, 1001u})
    for (uint32_t n : {1u, 2u, 3u, 7u}) {
      size_t next = 0;
      for (uint32_t k = 0; k < n; ++k) {
        const plm::CoveredSlice r = plm::texel_range(covered, k, n);
        EXPECT_EQ(r.begin, next);
        EXPECT_LE(r.size(), covered / n + 1);
        EXPECT_GE(r.size(), covered / n);
        next = r.end;
      }
      EXPECT_EQ(next, covered);
    }
}

// A Cornell box with the final gather: 1, 2 and 3 texel ranges (direct pass
// and gather), over 2 or 3 photon shards, merge to the single-machine bake
// bit for bit; so do direct parts alone (the merge gathers) and gather parts
// alone (the merge runs the direct pass). direct_samples 4: one round (the
// phantom sample comes before the calibration's extra samples); 1: a second
// round for every texel.
TEST(TexelRanges, MergeEqualsSingleBakeForAnyRangeCount) {
  plm_demo::SceneBuilder b;
  plm_demo::build_cornell(b, 12);
  ASSERT_TRUE(b.ok()) << b.error;
  for (uint32_t direct_samples : {4u, 1u}) {
    plm_bake_settings s = small_settings(150000);
    s.direct_samples = direct_samples;
    BakeResult one;
    ASSERT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &one.r), PLM_OK) << plm_last_error();
    for (uint32_t n = 1; n <= 3; ++n) {
      SCOPED_TRACE("direct samples " + std::to_string(direct_samples) + ", ranges " + std::to_string(n));
      TempDir dir;
      plm_bake_settings machine = s;
      machine.thread_count = n;  // threads differ between machines too
      const auto photons = bake_shards(b.scene, machine, n == 3 ? 3 : 2, dir.path);
      const auto direct = bake_ranges(b.scene, machine, PLM_TEXELS_DIRECT, n, {}, dir.path);
      const plm::PartHeader h = plm::read_part_header(direct[0]);
      EXPECT_EQ(h.direct_rounds, direct_samples == 1 ? 2u : 1u);
      EXPECT_GT(h.calibration_count, 0u);
      const auto gather = bake_ranges(b.scene, machine, PLM_TEXELS_GATHER, n, joined({photons, direct}), dir.path);
      EXPECT_TRUE(plm::read_part_header(gather[0]).gathered);
      BakeResult merged;
      std::string error;
      ASSERT_EQ(merge(b.scene, joined({gather, direct, photons}), merged, error), PLM_OK) << error;
      expect_identical(one, merged, mesh_count(b));
      if (n != 2) continue;
      BakeResult direct_only, gather_only;
      ASSERT_EQ(merge(b.scene, joined({photons, direct}), direct_only, error), PLM_OK) << error;
      expect_identical(one, direct_only, mesh_count(b));
      ASSERT_EQ(merge(b.scene, joined({photons, gather}), gather_only, error), PLM_OK) << error;
      expect_identical(one, gather_only, mesh_count(b));
    }
  }
}

// An open sunlit scene whose ground's sky light is pooled over neighbouring
// texels (transport/direct/direct_pool.h): the ranges' parts carry the samples'
// world part, and the merge pools across the ranges' borders as one machine
// does, bit for bit.
TEST(TexelRanges, SkyLightPooledAcrossRangesAsOnOneMachine) {
  plm_demo::SceneBuilder b;
  plm_test::open_scene(b);
  ASSERT_TRUE(b.ok()) << b.error;
  plm_bake_settings s = small_settings(65536);
  s.direct_samples = 16;
  BakeResult one;
  ASSERT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &one.r), PLM_OK) << plm_last_error();
  TempDir dir;
  const auto photons = bake_shards(b.scene, s, 2, dir.path);
  const auto direct = bake_ranges(b.scene, s, PLM_TEXELS_DIRECT, 3, {}, dir.path);
  BakeResult merged;
  std::string error;
  ASSERT_EQ(merge(b.scene, joined({photons, direct}), merged, error), PLM_OK) << error;
  expect_identical(one, merged, mesh_count(b));
}

// A CSG ball in the Cornell box: its sub-texels are covered texels of the
// last ranges, and there is no final gather (CSG solids): gather parts hold
// no texels, and the merge is still the single bake.
TEST(TexelRanges, CsgSubTexelsAndNoGather) {
  plm_demo::SceneBuilder b;
  plm_demo::build_cornell(b, 8);
  const uint32_t grey = b.material("ball grey", {0.5f, 0.5f, 0.5f});
  plm_csg_primitive ball = plm_test::sized<plm_csg_primitive>();  // radius 0.2 at (0.4, 0.5, 0.25), beside the boxes
  ball.shape = PLM_CSG_SPHERE;
  ball.material = grey;
  const double m[12] = {0.2, 0, 0, 0.4, 0, 0.2, 0, 0.5, 0, 0, 0.2, 0.25};
  for (int i = 0; i < 12; ++i) ball.matrix[i] = m[i];
  const plm_csg_node leaf = {sizeof(plm_csg_node), PLM_CSG_LEAF, 0, 0};
  uint32_t solid = 0;
  ASSERT_EQ(plm_scene_add_csg(b.scene, "ball", &ball, 1, &leaf, 1, nullptr, 0, 0, &solid), PLM_OK) << plm_last_error();
  // Carrier: a 16 x 8 latitude-longitude sphere around it.
  const double centre[3] = {0.4, 0.5, 0.25};
  const uint32_t carrier = plm_test::add_latlong_sphere(b.scene, "ball mesh", centre, 0.2, 16, 8, grey);
  ASSERT_EQ(plm_scene_set_csg_carrier(b.scene, solid, carrier), PLM_OK) << plm_last_error();
  ASSERT_TRUE(b.ok()) << b.error;
  const plm_bake_settings s = small_settings(60000);
  BakeResult one;
  ASSERT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &one.r), PLM_OK) << plm_last_error();
  TempDir dir;
  const auto photons = bake_shards(b.scene, s, 2, dir.path);
  const auto direct = bake_ranges(b.scene, s, PLM_TEXELS_DIRECT, 3, {}, dir.path);
  const auto gather = bake_ranges(b.scene, s, PLM_TEXELS_GATHER, 2, joined({photons, direct}), dir.path);
  EXPECT_FALSE(plm::read_part_header(gather[1]).gathered);
  EXPECT_EQ(std::filesystem::file_size(gather[1]), plm::kPartHeaderBytes);
  BakeResult merged;
  std::string error;
  ASSERT_EQ(merge(b.scene, joined({photons, direct, gather}), merged, error), PLM_OK) << error;
  expect_identical(one, merged, carrier + 1);  // the carrier's lightmap (the ball's sub-texels) too
  uint32_t w = 0, h = 0;
  ASSERT_EQ(plm_result_lightmap_size(one.r, carrier, &w, &h), PLM_OK);
  EXPECT_EQ(w, 16u);
}

// Texel parts that do not belong are refused, naming the part or the range.
TEST(TexelRanges, MergeRefusesRangesThatDoNotBelong) {
  plm_demo::SceneBuilder b;
  plm_demo::build_cornell(b, 6);
  ASSERT_TRUE(b.ok()) << b.error;
  const plm_bake_settings s = small_settings(40000);
  TempDir dir;
  const auto photons = bake_shards(b.scene, s, 2, dir.path);
  const auto direct = bake_ranges(b.scene, s, PLM_TEXELS_DIRECT, 3, {}, dir.path);
  const auto gather = bake_ranges(b.scene, s, PLM_TEXELS_GATHER, 3, joined({photons, direct}), dir.path);
  std::string error;
  {  // a direct range missing
    BakeResult r;
    EXPECT_EQ(merge(b.scene, joined({photons, {direct[0], direct[2]}, gather}), r, error), PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(error.find("direct range(s) 2 of 3 missing"), std::string::npos) << error;
  }
  {  // a gather range twice
    BakeResult r;
    EXPECT_EQ(merge(b.scene, joined({photons, direct, gather, {gather[1]}}), r, error), PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(error.find(gather[1] + ": gather range 2 of 3 is also " + gather[1]), std::string::npos) << error;
  }
  {  // direct parts of two range counts
    TempDir other;
    const auto halves = bake_ranges(b.scene, s, PLM_TEXELS_DIRECT, 2, {}, other.path);
    BakeResult r;
    EXPECT_EQ(merge(b.scene, joined({photons, {direct[0], halves[1], direct[2]}, gather}), r, error),
              PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(error.find(halves[1] + ": does not belong with " + direct[0] + ": its range count 2 against 3"),
              std::string::npos)
        << error;
  }
  {  // a direct range of another seed
    TempDir other;
    plm_bake_settings t = s;
    t.seed = 8;
    const auto odd = bake_ranges(b.scene, t, PLM_TEXELS_DIRECT, 3, {}, other.path);
    BakeResult r;
    EXPECT_EQ(merge(b.scene, joined({photons, {direct[0], odd[1], direct[2]}}), r, error), PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(error.find(odd[1] + ": does not belong with " + photons[0] + ": its seed 8 against 7"),
              std::string::npos)
        << error;
  }
  {  // gathers made over direct light of another target
    TempDir other;
    plm_bake_settings t = s;
    t.target_error = 0.05;
    const auto targeted = bake_ranges(b.scene, t, PLM_TEXELS_DIRECT, 3, {}, other.path);
    BakeResult r;
    EXPECT_EQ(merge(b.scene, joined({photons, targeted, gather}), r, error), PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(error.find(gather[0] + ": its gather looked up direct light baked to the target error 0"),
              std::string::npos)
        << error;
  }
  {  // a damaged direct part
    const std::string bad = dir.path + "/bad.plmpart";
    std::filesystem::copy_file(direct[1], bad);
    plm_test::flip_byte(bad, 600);
    BakeResult r;
    EXPECT_EQ(merge(b.scene, joined({photons, {direct[0], bad, direct[2]}}), r, error), PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(error.find(bad + ": the part file's sums are damaged (checksum)"), std::string::npos) << error;
  }
  {  // texel parts without photon parts; a direct range given parts
    BakeResult r;
    EXPECT_EQ(merge(b.scene, joined({direct, gather}), r, error), PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(error.find("no photon parts"), std::string::npos) << error;
    const char* in[] = {photons[0].c_str()};
    EXPECT_EQ(plm_bake_texels(b.scene, &s, PLM_TEXELS_DIRECT, 0, 2, in, 1, nullptr,
                              (dir.path + "/d.plmpart").c_str(), nullptr, nullptr),
              PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(std::string(plm_last_error()).find("reads no parts"), std::string::npos) << plm_last_error();
    EXPECT_EQ(plm_bake_texels(b.scene, &s, PLM_TEXELS_GATHER, 3, 3, nullptr, 0, nullptr,
                              (dir.path + "/g.plmpart").c_str(), nullptr, nullptr),
              PLM_ERROR_INVALID_ARGUMENT);
  }
}

// Direct ranges under a target (the rule in docs/design/sharding.md, "A target
// across texel ranges"): each range's rounds aim at the target relative to the
// whole's mean with the whole's phantom sample, so the merged direct light
// meets the direct pass's share of the target, measured against a bake with
// 1024 direct samples a texel (the same photons: the images then differ by the
// direct light's error), and the error the merge reports is honest. A room
// whose last range (a box on the floor, mostly in shadow) is far darker than
// the rest: with its own mean and phantom sample that range would stop early.
TEST(TexelRanges, DirectRangesMeetTheTargetTogether) {
  plm_demo::SceneBuilder b;
  const uint32_t white = b.material("white", {0.75f, 0.75f, 0.75f});
  const uint32_t res = 12;
  b.quad("floor", {0, 0, 0}, {4, 0, 0}, {0, 4, 0}, white, res);
  b.quad("ceiling", {0, 0, 3}, {0, 4, 0}, {4, 0, 0}, white, res);
  b.quad("wall_x0", {0, 0, 0}, {0, 4, 0}, {0, 0, 3}, white, res);
  b.quad("wall_x1", {4, 0, 0}, {0, 0, 3}, {0, 4, 0}, white, res);
  b.quad("wall_y0", {0, 0, 0}, {0, 0, 3}, {4, 0, 0}, white, res);
  b.quad("wall_y1", {0, 4, 0}, {4, 0, 0}, {0, 0, 3}, white, res);
  b.quad("box_x0", {1.5f, 1.5f, 0}, {0, 0, 1}, {0, 1, 0}, white, 2 * res);
  b.quad("box_x1", {2.5f, 1.5f, 0}, {0, 1, 0}, {0, 0, 1}, white, 2 * res);
  b.quad("box_y0", {1.5f, 1.5f, 0}, {1, 0, 0}, {0, 0, 1}, white, 2 * res);
  plm_light light;
  plm_light_default(&light, PLM_LIGHT_POINT);
  light.power = 800;
  light.matrix[3] = 2.0f;
  light.matrix[7] = 3.6f;
  light.matrix[11] = 2.7f;
  b.light(light, "lamp");
  ASSERT_TRUE(b.ok()) << b.error;
  const double target = 0.03;
  plm_bake_settings s = small_settings(150000);
  s.direct_samples = 16;
  plm_bake_settings fine = s;
  fine.direct_samples = 1024;
  BakeResult reference;
  ASSERT_EQ(plm_bake(b.scene, &fine, nullptr, nullptr, &reference.r), PLM_OK) << plm_last_error();
  TempDir dir;
  const auto photons = bake_shards(b.scene, s, 2, dir.path);
  plm_bake_settings targeted = s;
  targeted.target_error = target;
  const auto direct = bake_ranges(b.scene, targeted, PLM_TEXELS_DIRECT, 3, {}, dir.path);
  BakeResult merged;
  std::string error;
  ASSERT_EQ(merge(b.scene, joined({photons, direct}), merged, error), PLM_OK) << error;
  double sq = 0.0, sum = 0.0;
  size_t n = 0;
  for (uint32_t m = 0; m < mesh_count(b); ++m) {
    uint32_t w = 0, h = 0;
    if (plm_result_lightmap_size(reference.r, m, &w, &h) != PLM_OK || w == 0) continue;
    const Map a = merged.map(m), r = reference.map(m);
    for (size_t t = 0; t < size_t(w) * h; ++t) {
      if (r.coverage[t] <= 0.0f) continue;
      const double va = (a.rgb[3 * t] + a.rgb[3 * t + 1] + a.rgb[3 * t + 2]) / 3.0;
      const double vr = (r.rgb[3 * t] + r.rgb[3 * t + 1] + r.rgb[3 * t + 2]) / 3.0;
      sq += (va - vr) * (va - vr);
      sum += vr;
      ++n;
    }
  }
  ASSERT_GT(n, 0u);
  const double measured = std::sqrt(sq / double(n)) / (sum / double(n));
  plm_bake_stats stats = plm_test::sized<plm_bake_stats>(), single_stats = stats;
  ASSERT_EQ(plm_result_stats(merged.r, &stats), PLM_OK);
  BakeResult single;
  ASSERT_EQ(plm_bake(b.scene, &targeted, nullptr, nullptr, &single.r), PLM_OK) << plm_last_error();
  ASSERT_EQ(plm_result_stats(single.r, &single_stats), PLM_OK);
  std::printf("direct ranges under a %.0f %% target: measured %.2f %%, reported direct part %.2f %%, %llu samples; "
              "one machine: reported %.2f %%, %llu samples\n",
              100 * target, 100 * measured, 100 * stats.error_direct, (unsigned long long)stats.direct_samples,
              100 * single_stats.error_direct, (unsigned long long)single_stats.direct_samples);
  // The direct pass's share of the target, as one machine's rounds aim at it
  // (the ranges' own means and phantom samples give 2.11 % here).
  EXPECT_LT(stats.error_direct, plm::DirectSchedule::kDirectShareOfTarget * target);
  EXPECT_LT(measured, plm::DirectSchedule::kDirectShareOfTarget * target);
  EXPECT_LT(measured, 2.0 * stats.error_direct);  // the report does not understate it
  // About the samples one machine takes for that target.
  EXPECT_LT(double(stats.direct_samples), 1.5 * double(single_stats.direct_samples));
}

// A range's gather reads only the shards that hold the batches its estimate
// looks up (the first 16 of 37 here: shards 1 and 2 of 3); the merge reads
// them all. A damaged third shard passes the gather and stops the merge.
TEST(TexelRanges, GatherReadsOnlyTheFirstBatchesShards) {
  plm_demo::SceneBuilder b;
  plm_demo::build_cornell(b, 6);
  ASSERT_TRUE(b.ok()) << b.error;
  const plm_bake_settings s = small_settings(150000);
  TempDir dir;
  const auto photons = bake_shards(b.scene, s, 3, dir.path);
  plm_test::flip_byte(photons[2], 1000);
  const auto gather = bake_ranges(b.scene, s, PLM_TEXELS_GATHER, 2, photons, dir.path);
  BakeResult r;
  std::string error;
  EXPECT_EQ(merge(b.scene, joined({photons, gather}), r, error), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(error.find(photons[2] + ": the part file's sums are damaged (checksum)"), std::string::npos) << error;
}

// Texel parts whose checksums are right but whose values no bake writes (a
// part made by hand) are refused naming the part and the texel, before a NaN
// or negative distance reaches the estimate's integer conversions.
TEST(TexelRanges, PartsWithValuesNoBakeWritesAreRefused) {
  TempDir dir;
  plm::PartHeader h;
  h.engine_version = plm_version();
  h.shard_index = 1;
  h.shard_count = 2;
  h.layout.covered = 8;
  h.range_begin = 5;
  h.range_end = 7;
  h.gathered = true;
  auto refused = [&](auto write, auto read, const std::string& what) {
    const std::string path = dir.path + "/forged.plmpart";
    write(path);
    try {
      read(path);
      ADD_FAILURE() << "accepted a part with " << what;
    } catch (const plm::Error& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(path + ": " + what + " of covered texel 6 out of range"), std::string::npos) << message;
    }
  };
  plm::GatherResult g;
  g.sums.resize(2);
  g.info.resize(2);
  plm::GatherResult read_g;
  auto write_g = [&](const std::string& p) { plm::write_gather_part(p, h, g); };
  auto read_gather = [&](const std::string& p) { plm::read_gather_part(p, read_g); };
  const std::string ok = dir.path + "/ok.plmpart";
  write_g(ok);
  EXPECT_NO_THROW(plm::read_gather_part(ok, read_g));  // infinite hit distances: nothing hit
  g.info[1].hit_distance = -1.0f;
  refused(write_g, read_gather, "the gather's hit distance");
  g.info[1].hit_distance = std::nanf("");
  refused(write_g, read_gather, "the gather's hit distance");
  g.info[1].hit_distance = 2.0f;
  g.info[1].lookup_cells = -1.0;
  refused(write_g, read_gather, "the gather's error terms");
  g.info[1].lookup_cells = 0.0;
  g.sums[1].rgb[2] = std::numeric_limits<double>::infinity();
  refused(write_g, read_gather, "the gather sums");

  plm::DirectResult d;
  d.sums.resize(2);
  plm::DirectResult read_d;
  auto write_d = [&](const std::string& p) { plm::write_direct_part(p, h, d); };
  auto read_direct = [&](const std::string& p) { plm::read_direct_part(p, read_d); };
  d.sums[1].sky_rays = 4;
  d.sums[1].sky_blocked = 2;
  d.sums[1].sky_inv_distance = 3.0f;
  write_d(ok);
  EXPECT_NO_THROW(plm::read_direct_part(ok, read_d));
  d.sums[1].sky_inv_distance = -3.0f;
  refused(write_d, read_direct, "the sky's blocked rays or their distances");
  d.sums[1].sky_inv_distance = 3.0f;
  d.sums[1].sky_blocked = 5;
  refused(write_d, read_direct, "the sky's blocked rays or their distances");
  d.sums[1].sky_blocked = 2;
  d.sums[1].pair_sq = -1.0;
  refused(write_d, read_direct, "the direct sums");
}

// Directional lightmaps across machines: every SH band of every lightmap bit
// for bit as one machine gives it; parts of a plain bake do not merge into a
// directional one.
TEST(TexelRanges, DirectionalLightmapsMergeExactly) {
  plm_demo::SceneBuilder b;
  plm_test::open_scene(b, true, true, 16);
  ASSERT_TRUE(b.ok()) << b.error;
  plm_bake_settings s = small_settings(100000);
  s.directional = 1;
  BakeResult one;
  ASSERT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &one.r), PLM_OK) << plm_last_error();
  TempDir dir;
  const auto photons = bake_shards(b.scene, s, 2, dir.path, "open");
  const auto direct = bake_ranges(b.scene, s, PLM_TEXELS_DIRECT, 2, {}, dir.path);
  const auto gather = bake_ranges(b.scene, s, PLM_TEXELS_GATHER, 2, joined({photons, direct}), dir.path);
  EXPECT_TRUE(plm::read_part_header(photons[0]).layout.split.directional);
  EXPECT_TRUE(plm::read_part_header(direct[0]).settings.directional);
  BakeResult merged;
  std::string error;
  ASSERT_EQ(merge(b.scene, joined({gather, direct, photons}), merged, error), PLM_OK) << error;
  expect_identical(one, merged, mesh_count(b));
  ASSERT_EQ(plm_result_directional(merged.r), 1u);
  for (uint32_t m = 0; m < mesh_count(b); ++m) {
    uint32_t w = 0, h = 0;
    ASSERT_EQ(plm_result_lightmap_size(one.r, m, &w, &h), PLM_OK);
    for (uint32_t band = 0; band < 4; ++band) {
      std::vector<float> a(3 * size_t(w) * h), c = a;
      ASSERT_EQ(plm_result_copy_lightmap_sh(one.r, m, band, a.data()), PLM_OK);
      ASSERT_EQ(plm_result_copy_lightmap_sh(merged.r, m, band, c.data()), PLM_OK);
      expect_same_bits(a, c, "SH band", m);
    }
  }
  // A plain bake's photon parts with directional direct and gather parts: refused.
  plm_bake_settings plain = s;
  plain.directional = 0;
  TempDir other_dir;
  const auto plain_photons = bake_shards(b.scene, plain, 2, other_dir.path, "open");
  BakeResult mixed;
  EXPECT_NE(merge(b.scene, joined({gather, direct, plain_photons}), mixed, error), PLM_OK);
  EXPECT_NE(error.find("directional"), std::string::npos) << error;
}

// Light groups across machines: shards, direct and gather ranges and the merge
// give every layer of every lightmap bit for bit as one machine does.
TEST(TexelRanges, LightGroupLayersMergeExactly) {
  plm_demo::SceneBuilder b;
  plm_test::open_scene(b, true, true, 16);
  ASSERT_TRUE(b.ok()) << b.error;
  uint32_t day = 0;
  ASSERT_EQ(plm_scene_add_light_group(b.scene, "day", &day), PLM_OK);
  ASSERT_EQ(plm_scene_set_light_group(b.scene, 0, day), PLM_OK);  // the sun; the sky stays in the default group
  plm_bake_settings s = small_settings(100000);
  BakeResult one;
  ASSERT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &one.r), PLM_OK) << plm_last_error();
  ASSERT_EQ(plm_result_layer_count(one.r), 2u);
  TempDir dir;
  const auto photons = bake_shards(b.scene, s, 2, dir.path, "open");
  const auto direct = bake_ranges(b.scene, s, PLM_TEXELS_DIRECT, 2, {}, dir.path);
  const auto gather = bake_ranges(b.scene, s, PLM_TEXELS_GATHER, 2, joined({photons, direct}), dir.path);
  EXPECT_EQ(plm::read_part_header(photons[0]).layout.split.layers, 2u);
  BakeResult merged;
  std::string error;
  ASSERT_EQ(merge(b.scene, joined({gather, direct, photons}), merged, error), PLM_OK) << error;
  expect_identical(one, merged, mesh_count(b));
  ASSERT_EQ(plm_result_layer_count(merged.r), 2u);
  for (uint32_t m = 0; m < mesh_count(b); ++m) {
    uint32_t w = 0, h = 0;
    ASSERT_EQ(plm_result_lightmap_size(one.r, m, &w, &h), PLM_OK);
    for (uint32_t l = 0; l < 2; ++l) {
      std::vector<float> a(3 * size_t(w) * h), ae(size_t(w) * h), c = a, ce = ae;
      ASSERT_EQ(plm_result_copy_lightmap_layer(one.r, m, l, a.data(), ae.data()), PLM_OK);
      ASSERT_EQ(plm_result_copy_lightmap_layer(merged.r, m, l, c.data(), ce.data()), PLM_OK);
      expect_same_bits(a, c, "layer rgb", m);
      expect_same_bits(ae, ce, "layer error", m);
    }
  }
  // A scene whose groups changed since the shards were baked is another scene.
  ASSERT_EQ(plm_scene_set_light_group(b.scene, 0, 0), PLM_OK);
  BakeResult other;
  EXPECT_EQ(merge(b.scene, joined({gather, direct, photons}), other, error), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(error.find("another scene"), std::string::npos) << error;
}

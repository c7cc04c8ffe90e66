// Live previews (plm_bake_with_preview): what they show against analytic
// answers, that they never change the result, and their error handling.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "demo_scenes.h"
#include "test_support.h"

namespace {

using plm_demo::SceneBuilder;
using plm_test::BakeResult;
using plm_test::Map;

// What a preview callback saw: per call the photon count and, per mesh, the
// lightmap it copied (empty where the mesh has no preview).
struct Seen {
  std::vector<uint32_t> meshes;                    // which meshes to copy
  std::vector<std::pair<uint32_t, uint32_t>> size;  // their (width, height)
  std::vector<uint64_t> photons;
  std::vector<std::vector<std::vector<float>>> maps;  // per call, per mesh in `meshes`
  int cancel_after = -1;                              // return 0 on this call (-1: never)
  std::vector<plm_status> statuses;
};

int record(void* user, const plm_preview* p) {
  Seen& s = *static_cast<Seen*>(user);
  uint64_t photons = 0;
  s.statuses.push_back(plm_preview_photons(p, &photons));
  s.photons.push_back(photons);
  s.maps.emplace_back();
  for (size_t k = 0; k < s.meshes.size(); ++k) {
    std::vector<float> rgb(3 * size_t(s.size[k].first) * s.size[k].second, -1.0f);
    uint32_t w = 0, h = 0;
    s.statuses.push_back(plm_preview_lightmap_size(p, s.meshes[k], &w, &h));
    if (w != s.size[k].first || h != s.size[k].second) s.statuses.push_back(PLM_ERROR_INTERNAL);  // wrong size
    int written = -1;
    s.statuses.push_back(plm_preview_copy_lightmap(p, s.meshes[k], rgb.data(), &written));
    if (written != 1) rgb.clear();
    s.maps.back().push_back(std::move(rgb));
  }
  return int(s.photons.size()) - 1 == s.cancel_after ? 0 : 1;
}

plm_bake_settings quick(uint64_t photons, double target = 0.0) {
  plm_bake_settings s = plm_test::settings_with(photons, 16);
  s.thread_count = 2;
  s.seed = 7;
  s.target_error = target;
  return s;
}

void expect_same(const Map& a, const Map& b, uint32_t mesh) {
  ASSERT_EQ(a.rgb.size(), b.rgb.size());
  EXPECT_EQ(std::memcmp(a.rgb.data(), b.rgb.data(), 4 * a.rgb.size()), 0) << "rgb of mesh " << mesh;
  EXPECT_EQ(std::memcmp(a.error.data(), b.error.data(), 4 * a.error.size()), 0) << "error of mesh " << mesh;
  EXPECT_EQ(std::memcmp(a.hits.data(), b.hits.data(), 4 * a.hits.size()), 0) << "hits of mesh " << mesh;
}

std::string file_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

// The furnace (every texel exactly e / (1 - rho), its direct part e): the
// previews of the direct pass show e, later ones approach e / (1 - rho).
TEST(LivePreview, FurnaceShowsDirectThenFullLight) {
  SceneBuilder b;
  plm_demo::build_furnace(b, 0.5f, 1.0f, 16);
  ASSERT_TRUE(b.ok()) << b.error;
  Seen seen;
  seen.meshes = {0};
  seen.size = {{48, 32}};
  const plm_bake_settings s = quick(600000);
  BakeResult r;
  ASSERT_EQ(plm_bake_with_preview(b.scene, &s, nullptr, record, 1e-9, &seen, &r.r), PLM_OK) << plm_last_error();
  for (plm_status st : seen.statuses) EXPECT_EQ(st, PLM_OK);
  const Map final_map = r.map(0);
  ASSERT_EQ(final_map.w, 48u);
  ASSERT_GE(seen.photons.size(), 3u) << "previews after the direct pass and during the photon pass";
  EXPECT_EQ(seen.photons[0], 0u);
  // After the direct pass's round(s) (no photons yet), more photons each time.
  for (size_t c = 1; c < seen.photons.size(); ++c) {
    if (seen.photons[c] > 0) {
      EXPECT_GT(seen.photons[c], seen.photons[c - 1]);
    }
  }
  EXPECT_LE(seen.photons.back(), s.photon_count);
  for (size_t c = 0; c < seen.photons.size(); ++c) {
    const std::vector<float>& rgb = seen.maps[c][0];
    ASSERT_EQ(rgb.size(), final_map.rgb.size());
    double sum = 0.0, n = 0.0;
    bool finite = true;
    for (size_t t = 0; t < final_map.coverage.size(); ++t) {
      for (int ch = 0; ch < 3; ++ch) finite = finite && std::isfinite(rgb[3 * t + ch]) && rgb[3 * t + ch] >= 0.0f;
      if (final_map.coverage[t] <= 0.0f) continue;
      sum += (double(rgb[3 * t]) + rgb[3 * t + 1] + rgb[3 * t + 2]) / 3.0;
      n += 1.0;
    }
    EXPECT_TRUE(finite) << "preview " << c;
    const double mean = sum / n;
    if (seen.photons[c] == 0) {
      EXPECT_NEAR(mean, 1.0, 0.02) << "direct light alone";
    } else if (seen.photons[c] >= 100000) {
      EXPECT_NEAR(mean, 2.0, 0.06) << "preview at " << seen.photons[c];
    }
  }
  // Dilated like the final image: no texel is left at the -1 the buffer held.
  for (float v : seen.maps.back()[0]) ASSERT_GE(v, 0.0f);
}

// Previews at every check point, copying every lightmap, change nothing:
// the lightmaps, statistics and EXR files equal those of plm_bake, without a
// target (the gather after 16 batches) and with one (checks at batch counts).
TEST(LivePreview, ResultIsBitIdentical) {
  for (double target : {0.0, 0.03}) {
    SceneBuilder b;
    plm_demo::build_cornell(b, 16);
    ASSERT_TRUE(b.ok()) << b.error;
    const plm_bake_settings s = quick(300000, target);
    BakeResult plain, live;
    ASSERT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &plain.r), PLM_OK) << plm_last_error();
    Seen seen;
    for (uint32_t m = 0; m < b.mesh_names.size(); ++m) {
      uint32_t w = 0, h = 0;
      ASSERT_EQ(plm_result_lightmap_size(plain.r, m, &w, &h), PLM_OK);
      seen.meshes.push_back(m);
      seen.size.push_back({w, h});
    }
    ASSERT_EQ(plm_bake_with_preview(b.scene, &s, nullptr, record, 1e-9, &seen, &live.r), PLM_OK) << plm_last_error();
    EXPECT_GE(seen.photons.size(), 3u);
    const plm_bake_stats a = plain.stats(), c = live.stats();
    EXPECT_EQ(a.photons_emitted, c.photons_emitted);
    EXPECT_EQ(a.photon_hits, c.photon_hits);
    EXPECT_EQ(a.error_estimate, c.error_estimate);
    for (uint32_t m = 0; m < b.mesh_names.size(); ++m) {
      expect_same(plain.map(m), live.map(m), m);
      const std::string pa = "/tmp/plm_live_plain_" + std::to_string(getpid()) + ".exr";
      const std::string pb = "/tmp/plm_live_live_" + std::to_string(getpid()) + ".exr";
      ASSERT_EQ(plm_result_write_exr(plain.r, m, pa.c_str()), PLM_OK);
      ASSERT_EQ(plm_result_write_exr(live.r, m, pb.c_str()), PLM_OK);
      const std::string fa = file_bytes(pa), fb = file_bytes(pb);
      EXPECT_FALSE(fa.empty());
      EXPECT_TRUE(fa == fb) << "EXR of mesh " << m << " (target " << target << ")";
      std::remove(pa.c_str());
      std::remove(pb.c_str());
    }
  }
}

TEST(LivePreview, CallbackCancels) {
  SceneBuilder b;
  plm_demo::build_cornell(b, 8);
  ASSERT_TRUE(b.ok()) << b.error;
  Seen seen;
  seen.cancel_after = 1;
  const plm_bake_settings s = quick(2000000);
  plm_result* r = reinterpret_cast<plm_result*>(&seen);
  EXPECT_EQ(plm_bake_with_preview(b.scene, &s, nullptr, record, 1e-9, &seen, &r), PLM_ERROR_CANCELLED);
  EXPECT_EQ(r, nullptr);
  EXPECT_EQ(seen.photons.size(), 2u);
  EXPECT_LT(seen.photons.back(), s.photon_count);
}

// An interval of 0 or no callback: no previews.
TEST(LivePreview, OffWithoutIntervalOrCallback) {
  SceneBuilder b;
  plm_demo::build_cornell(b, 8);
  ASSERT_TRUE(b.ok()) << b.error;
  Seen seen;
  const plm_bake_settings s = quick(100000);
  BakeResult r1, r2;
  ASSERT_EQ(plm_bake_with_preview(b.scene, &s, nullptr, record, 0.0, &seen, &r1.r), PLM_OK) << plm_last_error();
  ASSERT_EQ(plm_bake_with_preview(b.scene, &s, nullptr, nullptr, 1.0, &seen, &r2.r), PLM_OK) << plm_last_error();
  EXPECT_TRUE(seen.photons.empty());
}

// A mesh in an OL group has no preview (written 0, buffer untouched); bad
// arguments get errors naming them; the bake goes on.
TEST(LivePreview, HardCases) {
  SceneBuilder b;
  plm_demo::build_cornell(b, 8);
  ASSERT_TRUE(b.ok()) << b.error;
  uint32_t g = 0;
  ASSERT_EQ(plm_scene_add_ol_group(b.scene, "walls", 0, &g), PLM_OK) << plm_last_error();
  ASSERT_EQ(plm_scene_set_mesh_ol_group(b.scene, 1, g), PLM_OK) << plm_last_error();
  const plm_bake_settings s = quick(100000);
  BakeResult r;
  for (double bad : {-1.0, double(NAN), double(INFINITY)}) {
    EXPECT_EQ(plm_bake_with_preview(b.scene, &s, nullptr, record, bad, nullptr, &r.r), PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(std::string(plm_last_error()).find("preview_interval"), std::string::npos) << plm_last_error();
  }
  struct Probe {
    int calls = 0;
    int ol_written = -1;
    float ol_first = 0.0f;
    plm_status null_rgb = PLM_OK, out_of_range = PLM_OK, null_out = PLM_OK, null_handle = PLM_OK;
    std::string range_message;
  } probe;
  auto fn = [](void* user, const plm_preview* p) -> int {
    Probe& q = *static_cast<Probe*>(user);
    ++q.calls;
    std::vector<float> rgb(3 * 8 * 8, 5.0f);
    q.null_rgb = plm_preview_copy_lightmap(p, 0, nullptr, nullptr);
    q.out_of_range = plm_preview_copy_lightmap(p, 99, rgb.data(), nullptr);
    q.range_message = plm_last_error();
    q.null_out = plm_preview_photons(p, nullptr);
    q.null_handle = plm_preview_copy_lightmap(nullptr, 0, rgb.data(), nullptr);
    q.ol_written = 7;
    EXPECT_EQ(plm_preview_copy_lightmap(p, 1, rgb.data(), &q.ol_written), PLM_OK) << plm_last_error();
    q.ol_first = rgb[0];
    return 1;
  };
  ASSERT_EQ(plm_bake_with_preview(b.scene, &s, nullptr, fn, 1e-9, &probe, &r.r), PLM_OK) << plm_last_error();
  EXPECT_GE(probe.calls, 1);
  EXPECT_EQ(probe.null_rgb, PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(probe.out_of_range, PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(probe.range_message.find("mesh id 99 is out of range"), std::string::npos) << probe.range_message;
  EXPECT_EQ(probe.null_out, PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(probe.null_handle, PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(probe.ol_written, 0);
  EXPECT_EQ(probe.ol_first, 5.0f);
}

}  // namespace

// Light groups (docs/design/light-groups.md): one bake's layers add up to
// the lightmap, the lightmap is the bake without groups bit for bit, and each
// layer is a bake of its group's lights alone within its error.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "../tools/demo_scenes.h"
#include "io/scene_file.h"
#include "photonlm/photonlm.h"
#include "test_support.h"

namespace {

using plm_test::BakeResult;
using plm_test::Map;

struct Layer {
  std::vector<float> rgb, error;
};

Layer layer(const BakeResult& r, uint32_t mesh, uint32_t l) {
  uint32_t w = 0, h = 0;
  EXPECT_EQ(plm_result_lightmap_size(r.r, mesh, &w, &h), PLM_OK);
  Layer out;
  out.rgb.resize(3 * size_t(w) * h);
  out.error.resize(size_t(w) * h);
  EXPECT_EQ(plm_result_copy_lightmap_layer(r.r, mesh, l, out.rgb.data(), out.error.data()), PLM_OK) << plm_last_error();
  return out;
}

// Coverage-weighted mean RGB (averaged) of covered texels of an image, and
// the RMS of its per-texel errors there.
struct Mean {
  double value = 0.0, rms_error = 0.0;
  size_t texels = 0;
};
Mean mean_of(const std::vector<float>& rgb, const std::vector<float>& error, const std::vector<float>& coverage) {
  Mean m;
  double cover = 0.0, var = 0.0;
  for (size_t t = 0; t < coverage.size(); ++t) {
    if (!(coverage[t] > 0.0f)) continue;
    m.value += coverage[t] * (double(rgb[3 * t]) + rgb[3 * t + 1] + rgb[3 * t + 2]) / 3.0;
    cover += coverage[t];
    var += double(error[t]) * error[t];
    ++m.texels;
  }
  m.value /= cover;
  m.rms_error = std::sqrt(var / double(m.texels));
  return m;
}

// The open scene (ground and box under a sun and a sky) with the sun (light
// 0) and the world in groups as asked; a default-group lamp where `lamp`.
void grouped_open_scene(plm_demo::SceneBuilder& b, bool sun, bool sky, bool groups, bool lamp = false) {
  plm_test::open_scene(b, sun, sky, 24);
  if (lamp) {
    plm_light l;
    plm_light_default(&l, PLM_LIGHT_POINT);
    l.power = 300.0f;
    l.matrix[3] = 1.5f, l.matrix[7] = -1.0f, l.matrix[11] = 2.0f;
    b.light(l, "lamp");
  }
  if (!groups) return;
  uint32_t g_sun = 0, g_sky = 0;
  ASSERT_EQ(plm_scene_add_light_group(b.scene, "sun", &g_sun), PLM_OK) << plm_last_error();
  ASSERT_EQ(plm_scene_add_light_group(b.scene, "sky", &g_sky), PLM_OK) << plm_last_error();
  EXPECT_EQ(g_sun, 1u);
  EXPECT_EQ(g_sky, 2u);
  if (sun) {
    ASSERT_EQ(plm_scene_set_light_group(b.scene, 0, g_sun), PLM_OK) << plm_last_error();
  }
  ASSERT_EQ(plm_scene_set_world_light_group(b.scene, g_sky), PLM_OK) << plm_last_error();
}

TEST(LightGroups, LayersAddUpToTheLightmapWhichIsTheBakeWithoutGroups) {
  const plm_bake_settings s = plm_test::settings_with(200000, 16);
  BakeResult plain, grouped;
  {
    plm_demo::SceneBuilder b;
    grouped_open_scene(b, true, true, false, true);
    plm_test::bake(b, s, plain);
  }
  {
    plm_demo::SceneBuilder b;
    grouped_open_scene(b, true, true, true, true);
    plm_test::bake(b, s, grouped);
  }
  EXPECT_EQ(plm_result_layer_count(plain.r), 0u);
  ASSERT_EQ(plm_result_layer_count(grouped.r), 3u);
  EXPECT_STREQ(plm_result_layer_name(grouped.r, 0), "default");  // the lamp
  EXPECT_STREQ(plm_result_layer_name(grouped.r, 1), "sun");
  EXPECT_STREQ(plm_result_layer_name(grouped.r, 2), "sky");
  EXPECT_EQ(plm_result_layer_name(grouped.r, 3), nullptr);
  for (uint32_t mesh = 0; mesh < 2; ++mesh) {
    const Map a = plain.map(mesh), g = grouped.map(mesh);
    ASSERT_EQ(a.rgb.size(), g.rgb.size());
    for (size_t i = 0; i < a.rgb.size(); ++i) ASSERT_EQ(a.rgb[i], g.rgb[i]) << "mesh " << mesh << " float " << i;
    const Layer l0 = layer(grouped, mesh, 0), l1 = layer(grouped, mesh, 1), l2 = layer(grouped, mesh, 2);
    double worst = 0.0;
    for (size_t i = 0; i < g.rgb.size(); ++i) {
      const double sum = double(l0.rgb[i]) + l1.rgb[i] + l2.rgb[i];
      worst = std::max(worst, std::fabs(sum - g.rgb[i]) / std::max(1e-3, double(g.rgb[i])));
      // No layer below 0 beyond rounding (a texel's indirect part is its value less its direct light).
      ASSERT_GE(std::min({l0.rgb[i], l1.rgb[i], l2.rgb[i]}), -1e-6f) << "mesh " << mesh << " float " << i;
    }
    EXPECT_LT(worst, 1e-4) << "mesh " << mesh;
    // Each layer's error is finite, and positive where the layer has light.
    for (size_t t = 0; t < g.error.size(); ++t) {
      if (!(g.coverage[t] > 0.0f)) continue;
      for (const Layer* l : {&l0, &l1, &l2}) {
        ASSERT_TRUE(std::isfinite(l->error[t])) << "mesh " << mesh << " texel " << t;
        if (l->rgb[3 * t] + l->rgb[3 * t + 1] + l->rgb[3 * t + 2] > 1e-4f) {
          ASSERT_GT(l->error[t], 0.0f) << "mesh " << mesh << " texel " << t;
        }
      }
    }
  }
  double e = -1.0;
  ASSERT_EQ(plm_result_layer_error(grouped.r, 1, &e), PLM_OK);
  EXPECT_GT(e, 0.0);
  EXPECT_LT(e, 0.2);
  EXPECT_EQ(plm_result_layer_error(grouped.r, 3, &e), PLM_ERROR_INVALID_ARGUMENT);
}

// Each layer against a bake of its group's lights alone: per mesh, the means
// within 3 x their estimated errors (the layer's and the lone bake's RMS
// texel errors over the texel count's square root, doubled for the pooling's
// correlation) plus 1 %.
TEST(LightGroups, EachLayerIsABakeOfItsLightsAlone) {
  plm_bake_settings s = plm_test::settings_with(0, 0);
  s.target_error = 0.02f;
  s.seed = 3;
  BakeResult grouped, sun_alone, sky_alone;
  {
    plm_demo::SceneBuilder b;
    grouped_open_scene(b, true, true, true);
    plm_test::bake(b, s, grouped);
  }
  {
    plm_demo::SceneBuilder b;
    grouped_open_scene(b, true, false, false);
    plm_test::bake(b, s, sun_alone);
  }
  {
    plm_demo::SceneBuilder b;
    grouped_open_scene(b, false, true, false);
    plm_test::bake(b, s, sky_alone);
  }
  ASSERT_EQ(plm_result_layer_count(grouped.r), 2u);  // no default group: every light is in one
  const BakeResult* alone[2] = {&sun_alone, &sky_alone};
  for (uint32_t l = 0; l < 2; ++l) {
    for (uint32_t mesh = 0; mesh < 2; ++mesh) {
      const Map whole = grouped.map(mesh), lone = alone[l]->map(mesh);
      const Layer part = layer(grouped, mesh, l);
      const Mean a = mean_of(part.rgb, part.error, whole.coverage), b = mean_of(lone.rgb, lone.error, lone.coverage);
      const double sigma = 2.0 * std::hypot(a.rms_error, b.rms_error) / std::sqrt(double(a.texels));
      EXPECT_NEAR(a.value, b.value, 3.0 * sigma + 0.01 * b.value)
          << plm_result_layer_name(grouped.r, l) << " on mesh " << mesh;
    }
  }
}

// A mesh's emission in a group of its own (its triangles are emitters, also
// found by the direct pass's cosine rays), beside the Cornell box's area light.
TEST(LightGroups, EmissiveMeshesTakeTheirMeshsGroup) {
  const plm_bake_settings s = plm_test::settings_with(400000, 16);
  BakeResult grouped, panel_alone;
  auto build = [](plm_demo::SceneBuilder& b, bool lamp, bool groups) {
    plm_demo::build_cornell(b, 8, lamp ? 200.0f : 0.0f);
    const uint32_t glow = b.material("glow", {0.0f, 0.0f, 0.0f}, {2.0f, 1.5f, 1.0f});
    const uint32_t panel = b.quad("panel", {-0.99f, -0.3f, 0.6f}, {0, 0.6f, 0}, {0, 0, 0.6f}, glow, 0);
    if (!groups) return;
    uint32_t g = 0;
    ASSERT_EQ(plm_scene_add_light_group(b.scene, "panel", &g), PLM_OK);
    ASSERT_EQ(plm_scene_set_mesh_light_group(b.scene, panel, g), PLM_OK) << plm_last_error();
  };
  {
    plm_demo::SceneBuilder b;
    build(b, true, true);
    plm_test::bake(b, s, grouped);
  }
  {
    plm_demo::SceneBuilder b;
    build(b, false, false);
    plm_test::bake(b, s, panel_alone);
  }
  ASSERT_EQ(plm_result_layer_count(grouped.r), 2u);
  EXPECT_STREQ(plm_result_layer_name(grouped.r, 1), "panel");
  for (uint32_t mesh = 0; mesh < 5; ++mesh) {  // floor, ceiling, back and side walls
    const Map whole = grouped.map(mesh), lone = panel_alone.map(mesh);
    const Layer part = layer(grouped, mesh, 1);
    const Mean a = mean_of(part.rgb, part.error, whole.coverage), b = mean_of(lone.rgb, lone.error, lone.coverage);
    const double sigma = 2.0 * std::hypot(a.rms_error, b.rms_error) / std::sqrt(double(a.texels));
    EXPECT_NEAR(a.value, b.value, 3.0 * sigma + 0.02 * b.value) << "mesh " << mesh;
  }
}

TEST(LightGroups, BadGroupsAreRefusedNamingWhatIsWrong) {
  plm_demo::SceneBuilder b;
  grouped_open_scene(b, true, true, false);
  uint32_t id = 0;
  auto refused = [&](plm_status status, const char* needle) {
    EXPECT_EQ(status, PLM_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(std::string(plm_last_error()).find(needle), std::string::npos) << plm_last_error();
  };
  refused(plm_scene_add_light_group(b.scene, "", &id), "must not be empty");
  refused(plm_scene_add_light_group(b.scene, "default", &id), "default group's name");
  refused(plm_scene_add_light_group(b.scene, "day light", &id), "holds ' '");
  ASSERT_EQ(plm_scene_add_light_group(b.scene, "day", &id), PLM_OK);
  refused(plm_scene_add_light_group(b.scene, "day", &id), "exists");
  refused(plm_scene_set_light_group(b.scene, 0, 2), "light group 2 does not exist");
  refused(plm_scene_set_light_group(b.scene, 7, 1), "light 7 does not exist");
  refused(plm_scene_set_mesh_light_group(b.scene, 9, 1), "mesh 9 does not exist");
  refused(plm_scene_set_world_light_group(b.scene, 5), "world: light group 5");
  // Scenes with OL groups refuse light groups.
  const plm_bake_settings s = plm_test::settings_with(20000, 4);
  uint32_t ol = 0;
  ASSERT_EQ(plm_scene_add_ol_group(b.scene, "ol", 0, &ol), PLM_OK);
  plm_result* r = nullptr;
  EXPECT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r), PLM_ERROR_INVALID_SCENE);
  EXPECT_NE(std::string(plm_last_error()).find("orientation-lightmap groups"), std::string::npos) << plm_last_error();
  EXPECT_EQ(r, nullptr);
}

TEST(LightGroups, SceneFilesNameTheGroups) {
  const char* text = R"({
    "light_groups": ["warm", "cool"],
    "materials": [{"name": "grey", "albedo": [0.5, 0.5, 0.5]}],
    "meshes": [{"name": "floor", "positions": [-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0], "indices": [0, 1, 2, 0, 2, 3],
                "lightmap_uv": [0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1], "lightmap_resolution": 8, "material": "grey"}],
    "lights": [{"type": "POINT", "power": 100, "location": [0, 0, 1], "group": "warm"},
               {"type": "POINT", "power": 50, "location": [0.5, 0, 1], "group": "cool"}],
    "world": {"radiance": [0.1, 0.1, 0.1]},
    "settings": {"photon_count": 20000, "direct_samples": 4}
  })";
  plm::SceneFile file;
  std::string error;
  ASSERT_TRUE(plm::parse_scene_file_text(text, {}, file, error)) << error;
  plm_result* r = nullptr;
  ASSERT_EQ(plm_bake(file.scene, &file.settings, nullptr, nullptr, &r), PLM_OK) << plm_last_error();
  ASSERT_EQ(plm_result_layer_count(r), 3u);
  EXPECT_STREQ(plm_result_layer_name(r, 0), "default");  // the world
  EXPECT_STREQ(plm_result_layer_name(r, 1), "warm");
  EXPECT_STREQ(plm_result_layer_name(r, 2), "cool");
  plm_result_release(r);

  std::string bad = text;
  bad.replace(bad.find("\"group\": \"cool\""), 15, "\"group\": \"cold\"");
  plm::SceneFile bad_file;
  EXPECT_FALSE(plm::parse_scene_file_text(bad, {}, bad_file, error));
  EXPECT_NE(error.find("scene.lights[1].group"), std::string::npos) << error;
  EXPECT_NE(error.find("cold"), std::string::npos) << error;
}

}  // namespace

// Image textures (scene/texture.h) through the scene file and the C API: a
// furnace box whose albedo texture is one colour c bakes to E / (1 - c) per
// channel, and malformed texture fields are refused with their JSON path; the
// bilinear lookup's conventions (pixel centres, periodic wrap, v = 0 at the
// bottom row, 8-bit sRGB decoded after filtering) on a small image; the final
// gather takes the texture's albedo where its rays land.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include "demo_scenes.h"
#include "io/scene_file.h"
#include "scene/texture.h"
#include "test_support.h"

namespace {

std::string temp_dir() {
  static const std::string dir = [] {
    std::string d = testing::TempDir() + "photonlm_texture_" + std::to_string(getpid());
    ::mkdir(d.c_str(), 0700);
    return d;
  }();
  return dir;
}

// A w x h binary PPM of one colour.
void write_ppm(const std::string& path, int w, int h, unsigned char r, unsigned char g, unsigned char b) {
  std::ofstream f(path, std::ios::binary);
  f << "P6\n" << w << " " << h << "\n255\n";
  for (int i = 0; i < w * h; ++i) f << r << g << b;
  ASSERT_TRUE(f.good()) << path;
}

std::string parse(const std::string& text, plm::SceneFile& out) {
  plm::SceneFileOptions options;
  options.base_dir = temp_dir();
  std::string error;
  if (!plm::parse_scene_file_text(text, options, out, error)) return error.empty() ? "(empty error)" : error;
  return "";
}

constexpr const char* kQuadUv = "[0,0, 1,0, 1,1, 0,0, 1,1, 0,1]";

std::string quad_mesh(const char* name, const float o[3], const float eu[3], const float ev[3], int res) {
  auto p = [&](float s, float t) {
    std::string r;
    for (int c = 0; c < 3; ++c) r += (c ? "," : "") + std::to_string(o[c] + s * eu[c] + t * ev[c]);
    return r;
  };
  return std::string("{\"name\": \"") + name + "\", \"material\": 0, \"positions\": [" + p(0, 0) + "," + p(1, 0) +
         "," + p(0, 1) + "," + p(1, 1) + "], \"indices\": [0,1,3, 0,3,2], \"lightmap_uv\": " + kQuadUv +
         ", \"texture_uv\": " + kQuadUv + ", \"lightmap_resolution\": " + std::to_string(res) + "}";
}

// A closed cube of six inward-facing quads, emission 1, albedo texture `texture`.
std::string furnace_file(const std::string& texture) {
  const float faces[6][3][3] = {
      {{-1, -1, -1}, {2, 0, 0}, {0, 2, 0}}, {{-1, -1, 1}, {0, 2, 0}, {2, 0, 0}},
      {{-1, -1, -1}, {0, 2, 0}, {0, 0, 2}}, {{1, -1, -1}, {0, 0, 2}, {0, 2, 0}},
      {{-1, -1, -1}, {0, 0, 2}, {2, 0, 0}}, {{-1, 1, -1}, {2, 0, 0}, {0, 0, 2}}};
  std::string meshes;
  for (int f = 0; f < 6; ++f)
    meshes += (f ? ",\n" : "") +
              quad_mesh(("face" + std::to_string(f)).c_str(), faces[f][0], faces[f][1], faces[f][2], 6);
  return "{\"version\": 1,\n\"materials\": [{\"name\": \"furnace\", \"albedo\": 1, \"emission\": [1, 1, 1], "
         "\"albedo_texture\": " + texture + "}],\n\"meshes\": [" + meshes +
         "],\n\"settings\": {\"photon_count\": 1000000, \"seed\": 3}}";
}

}  // namespace

TEST(Texture, SceneFileFurnaceWithConstantTexture) {
  write_ppm(temp_dir() + "/flat.ppm", 8, 8, 102, 153, 51);  // linear 0.4, 0.6, 0.2
  plm::SceneFile f;
  ASSERT_EQ(parse(furnace_file(R"({"path": "flat.ppm", "colorspace": "linear"})"), f), "");
  plm_test::BakeResult r;
  ASSERT_EQ(plm_bake(f.scene, &f.settings, nullptr, nullptr, &r.r), PLM_OK) << plm_last_error();
  const double c[3] = {0.4, 0.6, 0.2};
  double sum[3] = {0, 0, 0};
  int n = 0;
  for (const plm::SceneFileMesh& m : f.meshes) {
    const plm_test::Map lm = r.map(m.id);
    for (size_t t = 0; t < lm.coverage.size(); ++t) {
      if (lm.coverage[t] < 0.999f) continue;
      for (int k = 0; k < 3; ++k) sum[k] += lm.rgb[3 * t + size_t(k)];
      ++n;
    }
  }
  ASSERT_EQ(n, 6 * 36);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(sum[k] / n, 1.0 / (1.0 - c[k]), 0.015 / (1.0 - c[k])) << "channel " << k;
  EXPECT_EQ(plm_result_warning_count(r.r), 0u);
}

// The final gather in a textured scene takes the albedo where each ray lands:
// the open sunlit scene with its ground half bright (0.9), half dark (0.05),
// the box standing across the line, so its walls see one half or the other.
// The gather lowers the box's error at a given photon count and stays
// unbiased; with the ground's mean albedo its walls would be off by the
// difference. Reference: without the gather (max_bounces 63 turns it off) at
// 32x the photons and 256 direct samples.
TEST(Texture, GatherTakesTheAlbedoWhereItsRaysLand) {
  const std::string path = temp_dir() + "/halves.ppm";
  {
    std::ofstream f(path, std::ios::binary);
    f << "P6\n64 1\n255\n";
    for (int x = 0; x < 64; ++x) {
      const unsigned char c = x < 32 ? 230 : 13;
      f << c << c << c;
    }
    ASSERT_TRUE(f.good());
  }
  auto scene = [&](plm_demo::SceneBuilder& b) {  // plm_test::open_scene with the texture as the ground's albedo
    const uint32_t ground = b.material("ground", {1.0f, 1.0f, 1.0f}), white = b.material("box", {0.8f, 0.8f, 0.8f});
    b.quad("ground", {-4, -4, 0}, {8, 0, 0}, {0, 8, 0}, ground, 32);
    b.box("box", {0, 0, 0.75f}, {1.0f, 1.0f, 1.5f}, 0.35f, white, 8);
    b.light(plm_test::tilted_sun(4.0f, float(M_PI / 4.0)), "sun");
    const float sky[3] = {0.3f, 0.4f, 0.6f};
    ASSERT_EQ(plm_scene_set_world(b.scene, sky), PLM_OK);
    ASSERT_EQ(plm_scene_set_material_texture(b.scene, ground, PLM_TEXTURE_ALBEDO, path.c_str(),
                                             PLM_TEXTURE_COLOR_LINEAR), PLM_OK);
    const float uv[12] = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};  // the ground's two triangles (SceneBuilder::quad)
    ASSERT_EQ(plm_scene_set_mesh_texture_uv(b.scene, 0, uv), PLM_OK);
  };
  plm_demo::SceneBuilder gb, pb, rb;
  scene(gb), scene(pb), scene(rb);
  plm_bake_settings s;
  plm_bake_settings_default(&s);
  s.photon_count = 32768, s.direct_samples = 256, s.filter_radius = 2;
  plm_test::BakeResult gather, photons, ref;
  plm_test::bake(gb, s, gather);
  s.max_bounces = 63;
  plm_test::bake(pb, s, photons);
  s.photon_count = 128 * 32768, s.direct_samples = 1024, s.seed = 7;
  plm_test::bake(rb, s, ref);
  const plm_test::Map g = gather.map(1), p = photons.map(1), r = ref.map(1);  // the box
  double sq_g = 0, sq_p = 0, sum_g = 0, sum_ref = 0, n = 0;
  for (size_t t = 0; t < r.coverage.size(); ++t) {
    if (r.coverage[t] < 0.999f) continue;
    sq_g += (g.value(t) - r.value(t)) * (g.value(t) - r.value(t));
    sq_p += (p.value(t) - r.value(t)) * (p.value(t) - r.value(t));
    sum_g += g.value(t), sum_ref += r.value(t), n += 1;
  }
  const double mean = sum_ref / n, err_g = std::sqrt(sq_g / n) / mean, err_p = std::sqrt(sq_p / n) / mean;
  std::printf("[ measured ] box on a ground of two halves, 32768 photons: gather %.2f %%, photons only %.2f %%, "
              "mean gather / reference %.4f\n", 100 * err_g, 100 * err_p, sum_g / sum_ref);
  EXPECT_LT(err_g, 0.9 * err_p);
  EXPECT_NEAR(sum_g / sum_ref, 1.0, 0.01);
}

TEST(Texture, SceneFileErrorsNameTheJsonPath) {
  write_ppm(temp_dir() + "/one.ppm", 2, 2, 10, 20, 30);
  const std::string tri =
      R"("positions": [0,0,0, 1,0,0, 0,1,0], "indices": [0,1,2])";
  struct Case {
    std::string text, error;
  } cases[] = {
      {R"({"materials": [{"albedo_texture": 5}]})",
       "scene.materials[0].albedo_texture: expected a file name or an object {\"path\", \"colorspace\"}, got 5"},
      {R"({"materials": [{"albedo_texture": {"path": "one.ppm", "gamma": 2}}]})",
       "scene.materials[0].albedo_texture.gamma: unknown field (allowed: path, colorspace)"},
      {R"({"materials": [{"emission_texture": {"path": "one.ppm", "colorspace": "aces"}}]})",
       "scene.materials[0].emission_texture.colorspace: \"aces\" is not one of auto, linear, srgb"},
      {R"({"materials": [{"albedo_texture": ""}]})", "scene.materials[0].albedo_texture: empty file name"},
      {R"({"meshes": [{)" + tri + R"(, "texture_uv": [0,0, 1,0]}]})",
       "scene.meshes[0].texture_uv: expected 2 numbers (u, v) per triangle corner: 6 for 1 triangles, got 4"},
      {R"({"meshes": [{)" + tri + R"(, "texture_uv": [0,0, 1,0, 0,"x"]}]})",
       "scene.meshes[0].texture_uv[5]: expected a number, got \"x\""},
  };
  for (const Case& c : cases) {
    plm::SceneFile f;
    EXPECT_EQ(parse(c.text, f), c.error) << c.text;
  }
  // A missing file: the JSON path, the material and the file.
  plm::SceneFile f;
  const std::string error = parse(R"({"materials": [{"name": "brick", "albedo_texture": "missing.png"}]})", f);
  EXPECT_NE(error.find("scene.materials[0].albedo_texture"), std::string::npos) << error;
  EXPECT_NE(error.find("material 'brick' (0)"), std::string::npos) << error;
  EXPECT_NE(error.find("missing.png"), std::string::npos) << error;
  // No file access (the fuzzer's mode).
  plm::SceneFileOptions no_files;
  no_files.allow_file_access = false;
  std::string e2;
  plm::SceneFile g;
  EXPECT_FALSE(plm::parse_scene_file_text(R"({"materials": [{"albedo_texture": "one.ppm"}]})", no_files, g, e2));
  EXPECT_EQ(e2, "scene.materials[0].albedo_texture: file access is disabled");
}

TEST(Texture, CApiRejectsBadArguments) {
  plm_scene* s = nullptr;
  ASSERT_EQ(plm_scene_create(&s), PLM_OK);
  const float a[3] = {0.5f, 0.5f, 0.5f}, e[3] = {0, 0, 0};
  uint32_t mat = 0;
  ASSERT_EQ(plm_scene_add_material(s, "m", a, e, &mat), PLM_OK);
  EXPECT_EQ(plm_scene_set_material_texture(s, 3, PLM_TEXTURE_ALBEDO, "x.png", 0), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_scene_set_material_texture(s, mat, 9, "x.png", 0), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("texture slot 9"), std::string::npos) << plm_last_error();
  EXPECT_EQ(plm_scene_set_material_texture(s, mat, PLM_TEXTURE_ALBEDO, "x.png", 7), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_scene_set_material_texture(s, mat, PLM_TEXTURE_ALBEDO, "/nonexistent/x.png", 0), PLM_ERROR_IO);
  EXPECT_NE(std::string(plm_last_error()).find("material 'm' (0)"), std::string::npos) << plm_last_error();
  EXPECT_EQ(plm_scene_set_material_texture(s, mat, PLM_TEXTURE_ALBEDO, nullptr, 0), PLM_OK);  // removes
  EXPECT_EQ(plm_scene_set_mesh_texture_uv(s, 0, nullptr), PLM_ERROR_INVALID_ARGUMENT);  // no mesh 0
  EXPECT_EQ(plm_scene_set_mesh_texture_uv(nullptr, 0, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  plm_scene_release(s);
}

TEST(Texture, BilinearLookupConventions) {
  // 4 x 2 pixels, row 0 = the image's top row; pixel (x, y) = (x + 10 y, 1, y).
  plm::TextureSet::Texture t;
  t.width = 4;
  t.height = 2;
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 4; ++x) t.rgb.insert(t.rgb.end(), {float(x + 10 * y), 1.0f, float(y)});
  t.mean = {7.0f, 1.0f, 0.5f};
  auto at = [&](float u, float v) { return plm::TextureSet::sample(t, u, v); };
  // Pixel centres ((x + 0.5) / 4, v) give the pixel itself; v = 0.75 is the top row, 0.25 the bottom one.
  for (int x = 0; x < 4; ++x) {
    EXPECT_FLOAT_EQ(at((float(x) + 0.5f) / 4.0f, 0.75f).x, float(x)) << x;
    EXPECT_FLOAT_EQ(at((float(x) + 0.5f) / 4.0f, 0.25f).x, float(x + 10)) << x;
    EXPECT_FLOAT_EQ(at((float(x) + 0.5f) / 4.0f, 0.25f).z, 1.0f) << x;
  }
  // Between centres: linear in u and v.
  EXPECT_FLOAT_EQ(at(0.25f, 0.75f).x, 0.5f);
  EXPECT_FLOAT_EQ(at(0.5f, 0.5f).x, 6.5f);  // 0.25 x (1 + 2 + 11 + 12)
  // Periodic: u = 0 lies halfway between the last column and the first, v = 0 (and 1) between
  // the bottom row and the top one; whole periods change nothing.
  EXPECT_FLOAT_EQ(at(0.0f, 0.75f).x, 1.5f);
  EXPECT_FLOAT_EQ(at(1.0f, 0.75f).x, 1.5f);
  EXPECT_FLOAT_EQ(at(0.125f, 0.0f).x, 5.0f);
  EXPECT_FLOAT_EQ(at(0.125f, 1.0f).x, 5.0f);
  EXPECT_FLOAT_EQ(at(0.375f - 3.0f, 0.25f + 7.0f).x, 11.0f);
  EXPECT_FLOAT_EQ(at(0.375f + 1024.0f, 0.25f - 4096.0f).x, 11.0f);
  // Far out and non-finite coordinates: a pixel value or the mean, never out of bounds.
  const plm::Vec3 far = at(3e30f, -1e25f);
  EXPECT_TRUE(far.x >= 0.0f && far.x <= 13.0f) << far.x;
  EXPECT_FLOAT_EQ(at(std::nanf(""), 0.5f).x, 7.0f);
  EXPECT_FLOAT_EQ(at(0.5f, INFINITY).x, 7.0f);

  // 8-bit sRGB images are filtered encoded and decoded after the lookup: halfway between
  // encoded 0 and 1 is encoded 0.5, i.e. linear 0.214, not the 0.5 of decoding first.
  plm::TextureSet::Texture e;
  e.width = 2;
  e.height = 1;
  e.rgb = {0, 0, 0, 1, 1, 1};
  e.decode_after = true;
  EXPECT_NEAR(plm::TextureSet::sample(e, 0.5f, 0.5f).x, 0.21404f, 1e-5f);
  EXPECT_NEAR(plm::TextureSet::sample(e, 0.75f, 0.5f).x, 1.0f, 1e-6f);
}

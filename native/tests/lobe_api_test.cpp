// Specular lobes through the C API (photonlm.h "Specular lobes"): defaults
// per type, and every bad input refused with a message naming the material,
// the lobe and the field.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "api/handles.h"
#include "io/scene_file.h"
#include "photonlm/photonlm.h"

namespace {

struct SceneHandle {
  plm_scene* s = nullptr;
  SceneHandle() { EXPECT_EQ(plm_scene_create(&s), PLM_OK); }
  ~SceneHandle() { plm_scene_release(s); }
};

uint32_t material(plm_scene* s, const char* name, float albedo) {
  const float a[3] = {albedo, albedo, albedo}, e[3] = {0, 0, 0};
  uint32_t id = 0;
  EXPECT_EQ(plm_scene_add_material(s, name, a, e, &id), PLM_OK) << plm_last_error();
  return id;
}

// The error of adding `lobe` to a fresh material 'glass' of albedo `albedo` ("" if accepted).
std::string add_error(const plm_lobe& lobe, float albedo = 0.0f) {
  SceneHandle h;
  const uint32_t m = material(h.s, "glass", albedo);
  const plm_status st = plm_scene_add_material_lobe(h.s, m, &lobe);
  if (st == PLM_OK) return "";
  EXPECT_EQ(st, PLM_ERROR_INVALID_ARGUMENT);
  return plm_last_error();
}

plm_lobe lobe_of(plm_lobe_type type) {
  plm_lobe l;
  plm_lobe_default(&l, type);
  return l;
}

TEST(Lobes, DefaultsAreBlendersPerType) {
  const plm_lobe glass = lobe_of(PLM_LOBE_GLASS), refraction = lobe_of(PLM_LOBE_REFRACTION);
  const plm_lobe fresnel = lobe_of(PLM_LOBE_FRESNEL), glossy = lobe_of(PLM_LOBE_GLOSSY);
  EXPECT_EQ(glass.type, PLM_LOBE_GLASS);
  EXPECT_FLOAT_EQ(glass.ior, 1.45f);
  EXPECT_FLOAT_EQ(refraction.ior, 1.45f);
  EXPECT_FLOAT_EQ(fresnel.ior, 1.5f);
  for (const plm_lobe& l : {glass, refraction, fresnel, glossy}) {
    EXPECT_EQ(l.color[0], 1.0f);
    EXPECT_EQ(l.color[2], 1.0f);
    EXPECT_EQ(l.weight, 1.0f);
    EXPECT_EQ(l.roughness, 0.0f);
    EXPECT_EQ(l.abbe, 0.0f);
  }
  plm_lobe_default(nullptr, PLM_LOBE_GLASS);  // NULL is ignored
}

TEST(Lobes, AreStoredInOrder) {
  SceneHandle h;
  const uint32_t m = material(h.s, "metal", 0.2f);
  plm_lobe a = lobe_of(PLM_LOBE_FRESNEL);
  a.color[0] = 0.9f, a.color[1] = 0.6f, a.color[2] = 0.2f;
  a.roughness = 0.3f;
  plm_lobe b = lobe_of(PLM_LOBE_GLASS);
  b.abbe = 40.0f;
  b.weight = 0.5f;
  ASSERT_EQ(plm_scene_add_material_lobe(h.s, m, &a), PLM_OK) << plm_last_error();
  ASSERT_EQ(plm_scene_add_material_lobe(h.s, m, &b), PLM_OK) << plm_last_error();
  const auto& lobes = h.s->scene.materials[m].lobes;
  ASSERT_EQ(lobes.size(), 2u);
  EXPECT_EQ(lobes[0].type, PLM_LOBE_FRESNEL);
  EXPECT_EQ(lobes[0].color.y, 0.6f);
  EXPECT_EQ(lobes[0].roughness, 0.3f);
  EXPECT_EQ(lobes[1].type, PLM_LOBE_GLASS);
  EXPECT_EQ(lobes[1].abbe, 40.0f);
  EXPECT_EQ(lobes[1].weight, 0.5f);
  EXPECT_TRUE(h.s->scene.has_lobes());
}

TEST(Lobes, NullArgumentsAndBadMaterialAreRefused) {
  SceneHandle h;
  const plm_lobe l = lobe_of(PLM_LOBE_GLOSSY);
  EXPECT_EQ(plm_scene_add_material_lobe(nullptr, 0, &l), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("scene must not be NULL"), std::string::npos);
  const uint32_t m = material(h.s, "x", 0.5f);
  EXPECT_EQ(plm_scene_add_material_lobe(h.s, m, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("lobe must not be NULL"), std::string::npos);
  EXPECT_EQ(plm_scene_add_material_lobe(h.s, 7, &l), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("material id 7 is out of range"), std::string::npos);
}

struct BadLobe {
  const char* what;
  plm_lobe lobe;
  float albedo;
  const char* message;
};

std::ostream& operator<<(std::ostream& os, const BadLobe& b) { return os << b.what; }

plm_lobe with(plm_lobe_type type, void (*edit)(plm_lobe&)) {
  plm_lobe l = lobe_of(type);
  edit(l);
  return l;
}

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

const BadLobe kBad[] = {
    {"unknown type", with(PLM_LOBE_GLASS, [](plm_lobe& l) { l.type = 9; }), 0.0f,
     "material 'glass': lobe 0 has the unknown type 9"},
    {"colour above 1", with(PLM_LOBE_GLASS, [](plm_lobe& l) { l.color[1] = 1.5f; }), 0.0f,
     "material 'glass': lobe 0 (glass): color[1] = 1.5 is not in [0, 1]"},
    {"negative colour", with(PLM_LOBE_GLOSSY, [](plm_lobe& l) { l.color[0] = -0.1f; }), 0.0f,
     "lobe 0 (glossy): color[0] = -0.1 is not in [0, 1]"},
    {"NaN colour", with(PLM_LOBE_GLOSSY, [](plm_lobe& l) { l.color[2] = kNaN; }), 0.0f,
     "lobe 0 (glossy): color[2] = nan is not in [0, 1]"},
    {"NaN weight", with(PLM_LOBE_FRESNEL, [](plm_lobe& l) { l.weight = kNaN; }), 0.0f,
     "lobe 0 (fresnel): weight nan is not in [0, 1]"},
    {"roughness above 1", with(PLM_LOBE_GLOSSY, [](plm_lobe& l) { l.roughness = 2.0f; }), 0.0f,
     "lobe 0 (glossy): roughness 2 is not in [0, 1]"},
    {"zero ior", with(PLM_LOBE_GLASS, [](plm_lobe& l) { l.ior = 0.0f; }), 0.0f,
     "lobe 0 (glass): ior 0 must be > 0 and finite"},
    {"negative ior", with(PLM_LOBE_REFRACTION, [](plm_lobe& l) { l.ior = -1.5f; }), 0.0f,
     "lobe 0 (refraction): ior -1.5 must be > 0"},
    {"infinite ior", with(PLM_LOBE_FRESNEL, [](plm_lobe& l) { l.ior = kInf; }), 0.0f,
     "lobe 0 (fresnel): ior inf must be > 0 and finite"},
    {"NaN ior on a glossy lobe", with(PLM_LOBE_GLOSSY, [](plm_lobe& l) { l.ior = kNaN; }), 0.0f,
     "lobe 0 (glossy): ior nan"},
    {"negative abbe", with(PLM_LOBE_GLASS, [](plm_lobe& l) { l.abbe = -3.0f; }), 0.0f,
     "lobe 0 (glass): abbe -3 must be >= 0"},
    {"abbe on a mirror", with(PLM_LOBE_FRESNEL, [](plm_lobe& l) { l.abbe = 40.0f; }), 0.0f,
     "lobe 0 (fresnel): abbe 40 is for glass and refraction lobes only"},
    {"diffuse + glass above 1", with(PLM_LOBE_GLASS, [](plm_lobe& l) { l.color[0] = 0.5f; }), 0.6f,
     "lobe 0 (glass): the diffuse albedo plus weight x color of the lobes is 1.1 in channel 0, above 1"},
    {"transparent above 1 by weight", with(PLM_LOBE_TRANSPARENT, [](plm_lobe& l) { l.weight = 0.5f; }), 0.6f,
     "lobe 0 (transparent): the diffuse albedo plus weight x color"},
};

class LobesRefused : public testing::TestWithParam<BadLobe> {};

TEST_P(LobesRefused, NamingMaterialLobeAndField) {
  const BadLobe& b = GetParam();
  const std::string e = add_error(b.lobe, b.albedo);
  EXPECT_NE(e.find(b.message), std::string::npos) << e;
}

INSTANTIATE_TEST_SUITE_P(Lobes, LobesRefused, testing::ValuesIn(kBad));

TEST(Lobes, FresnelLayersDoNotCountAgainstTheDiffuseBudget) {
  plm_lobe coat = lobe_of(PLM_LOBE_FRESNEL);
  coat.color[0] = coat.color[1] = coat.color[2] = 0.04f;
  EXPECT_EQ(add_error(coat, 1.0f), "");
  plm_lobe half = lobe_of(PLM_LOBE_GLASS);
  half.weight = 0.5f;
  EXPECT_EQ(add_error(half, 0.5f), "");  // exactly 1: allowed
}

TEST(Lobes, TheBudgetSumsEveryLobe) {
  SceneHandle h;
  const uint32_t m = material(h.s, "mix", 0.4f);
  plm_lobe a = lobe_of(PLM_LOBE_GLOSSY);
  a.weight = 0.3f;
  ASSERT_EQ(plm_scene_add_material_lobe(h.s, m, &a), PLM_OK) << plm_last_error();
  plm_lobe b = lobe_of(PLM_LOBE_TRANSPARENT);
  b.weight = 0.4f;
  EXPECT_EQ(plm_scene_add_material_lobe(h.s, m, &b), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("lobe 1 (transparent)"), std::string::npos) << plm_last_error();
  b.weight = 0.3f;
  EXPECT_EQ(plm_scene_add_material_lobe(h.s, m, &b), PLM_OK) << plm_last_error();
}

TEST(Lobes, AtMostEightAMaterial) {
  SceneHandle h;
  const uint32_t m = material(h.s, "layers", 0.0f);
  plm_lobe l = lobe_of(PLM_LOBE_FRESNEL);
  for (int i = 0; i < 8; ++i) ASSERT_EQ(plm_scene_add_material_lobe(h.s, m, &l), PLM_OK) << plm_last_error();
  EXPECT_EQ(plm_scene_add_material_lobe(h.s, m, &l), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("material 'layers': has 8 lobes already"), std::string::npos)
      << plm_last_error();
}

TEST(Lobes, UnnamedMaterialsAreNamedByIndex) {
  SceneHandle h;
  material(h.s, nullptr, 0.5f);
  const uint32_t m = material(h.s, nullptr, 0.5f);
  plm_lobe l = lobe_of(PLM_LOBE_GLASS);
  l.ior = 0.0f;
  EXPECT_EQ(plm_scene_add_material_lobe(h.s, m, &l), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("material '#1': lobe 0 (glass): ior 0"), std::string::npos)
      << plm_last_error();
}

TEST(Lobes, SceneFilesGiveThemWithDefaults) {
  plm::SceneFileOptions options;
  options.allow_file_access = false;
  plm::SceneFile f;
  std::string error;
  ASSERT_TRUE(plm::parse_scene_file_text(
      R"({"materials": [{"name": "pane", "albedo": 0, "lobes": [
            {"type": "glass", "color": [0.9, 1, 0.9]},
            {"type": "fresnel", "color": 0.04, "weight": 0.25, "roughness": 0.1, "ior": 1.6}]},
          {"name": "prism", "albedo": 0, "lobes": [{"type": "refraction", "ior": 1.52, "abbe": 58.5}]}]})",
      options, f, error))
      << error;
  const auto& mats = f.scene->scene.materials;
  ASSERT_EQ(mats.size(), 2u);
  ASSERT_EQ(mats[0].lobes.size(), 2u);
  EXPECT_EQ(mats[0].lobes[0].type, PLM_LOBE_GLASS);
  EXPECT_FLOAT_EQ(mats[0].lobes[0].ior, 1.45f);
  EXPECT_FLOAT_EQ(mats[0].lobes[0].color.x, 0.9f);
  EXPECT_EQ(mats[0].lobes[0].weight, 1.0f);
  EXPECT_EQ(mats[0].lobes[1].type, PLM_LOBE_FRESNEL);
  EXPECT_FLOAT_EQ(mats[0].lobes[1].color.y, 0.04f);
  EXPECT_FLOAT_EQ(mats[0].lobes[1].weight, 0.25f);
  EXPECT_FLOAT_EQ(mats[0].lobes[1].roughness, 0.1f);
  EXPECT_FLOAT_EQ(mats[0].lobes[1].ior, 1.6f);
  ASSERT_EQ(mats[1].lobes.size(), 1u);
  EXPECT_FLOAT_EQ(mats[1].lobes[0].abbe, 58.5f);
}

}  // namespace

// The C API's caller-allocated structs carry their size (photonlm.h "Struct
// sizes"): the current size is taken, unknown sizes are refused naming the
// struct, and an older (shorter) stats struct is written only as far as its size.
#include <gtest/gtest.h>

#include <cstddef>
#include <cstring>
#include <string>
#include <vector>

#include "demo_scenes.h"
#include "test_support.h"

namespace {

using plm_demo::SceneBuilder;

// A small baked scene: a quad under a point light.
struct Baked {
  SceneBuilder b;
  plm_test::BakeResult r;
  Baked() {
    const uint32_t grey = b.material("grey", {0.5f, 0.5f, 0.5f});
    b.quad("floor", {-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, grey, 8);
    plm_light l;
    plm_light_default(&l, PLM_LIGHT_POINT);
    l.matrix[11] = 1.0f;
    b.light(l, "lamp");
    plm_test::bake(b, plm_test::settings_with(20000, 4), r);
  }
};

// The status of a call refused for its struct_size, with the message checked.
void expect_refused(plm_status s, const char* function, const char* name, uint32_t size, size_t current) {
  EXPECT_EQ(s, PLM_ERROR_STRUCT_SIZE) << plm_last_error();
  const std::string m = plm_last_error();
  EXPECT_NE(m.find(function), std::string::npos) << m;
  EXPECT_NE(m.find(name), std::string::npos) << m;
  EXPECT_NE(m.find("struct_size " + std::to_string(size)), std::string::npos) << m;
  EXPECT_NE(m.find("current " + std::to_string(current)), std::string::npos) << m;
}

TEST(StructSize, DefaultsSetTheCurrentSize) {
  plm_bake_settings s;
  plm_bake_settings_default(&s);
  EXPECT_EQ(s.struct_size, sizeof s);
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_SUN);
  EXPECT_EQ(l.struct_size, sizeof l);
  plm_lobe lobe;
  plm_lobe_default(&lobe, PLM_LOBE_GLASS);
  EXPECT_EQ(lobe.struct_size, sizeof lobe);
  plm_lsystem_settings ls;
  plm_lsystem_settings_default(&ls);
  EXPECT_EQ(ls.struct_size, sizeof ls);
}

TEST(StructSize, CurrentStatsSizeIsAcceptedAndKept) {
  Baked k;
  plm_bake_stats st = plm_test::sized<plm_bake_stats>();
  ASSERT_EQ(plm_result_stats(k.r.r, &st), PLM_OK) << plm_last_error();
  EXPECT_EQ(st.struct_size, sizeof st);
  EXPECT_GT(st.photons_emitted, 0u);
  EXPECT_GT(st.memory_estimate, 0u);
}

TEST(StructSize, WrongStatsSizesAreRefusedNamingTheStruct) {
  Baked k;
  for (uint32_t size : {0u, 1u, 4u, uint32_t(sizeof(plm_bake_stats) - 8), uint32_t(sizeof(plm_bake_stats) + 8),
                        0xdeadbeefu}) {
    plm_bake_stats st = plm_test::sized<plm_bake_stats>();
    st.struct_size = size;
    st.photons_emitted = 12345;
    expect_refused(plm_result_stats(k.r.r, &st), "plm_result_stats", "plm_bake_stats", size, sizeof st);
    EXPECT_EQ(st.photons_emitted, 12345u) << "a refused struct is not written";
    EXPECT_EQ(st.struct_size, size);
  }
  plm_ol_stats os = plm_test::sized<plm_ol_stats>();
  os.struct_size = 0;
  EXPECT_EQ(plm_result_ol_stats(k.r.r, 0, &os), PLM_ERROR_INVALID_ARGUMENT)
      << "no OL group: the group is checked first";
}

// plm_bake_stats as a header before error_above and memory_estimate declared it.
struct OlderStats {
  uint32_t struct_size;
  uint64_t photons_emitted, photon_hits, rays_traced, paths_truncated;
  double emitted_power, seconds_setup, seconds_trace, seconds_total;
  uint64_t direct_samples;
  double seconds_direct, error_estimate, error_direct, error_median, error_p95;
};

TEST(StructSize, OlderStatsAreWrittenOnlyUpToTheirSize) {
  static_assert(sizeof(OlderStats) == offsetof(plm_bake_stats, error_above), "the older layout is a prefix");
  Baked k;
  plm_bake_stats current = plm_test::sized<plm_bake_stats>();
  ASSERT_EQ(plm_result_stats(k.r.r, &current), PLM_OK) << plm_last_error();
  // The older struct followed by guard bytes that must stay as they are.
  std::vector<unsigned char> buf(sizeof(OlderStats) + 64, 0xA5);
  const uint32_t size = sizeof(OlderStats);
  std::memcpy(buf.data(), &size, sizeof size);
  ASSERT_EQ(plm_result_stats(k.r.r, reinterpret_cast<plm_bake_stats*>(buf.data())), PLM_OK) << plm_last_error();
  for (size_t i = sizeof(OlderStats); i < buf.size(); ++i) ASSERT_EQ(buf[i], 0xA5) << "byte " << i << " written";
  OlderStats old;
  std::memcpy(&old, buf.data(), sizeof old);
  EXPECT_EQ(old.struct_size, size);
  EXPECT_EQ(old.photons_emitted, current.photons_emitted);
  EXPECT_EQ(old.rays_traced, current.rays_traced);
  EXPECT_EQ(old.seconds_total, current.seconds_total);
  EXPECT_EQ(old.error_estimate, current.error_estimate);
  EXPECT_EQ(old.error_p95, current.error_p95);
}

TEST(StructSize, OlderSettingsBakeAsTheDefaultsOfTheRest) {
  // Settings up to filter_radius: texel_value and sampler take their defaults.
  Baked k;
  plm_bake_settings s = plm_test::settings_with(20000, 4);
  plm_bake_settings older = s;
  older.struct_size = offsetof(plm_bake_settings, texel_value);
  older.texel_value = PLM_TEXEL_AREA;  // past the older size: not read
  older.sampler = 77;
  plm_test::BakeResult a, b;
  plm_test::bake(k.b, s, a);
  plm_test::bake(k.b, older, b);
  EXPECT_EQ(a.map(0).rgb, b.map(0).rgb);
}

TEST(StructSize, WrongSettingsSizesAreRefused) {
  Baked k;
  plm_bake_settings s = plm_test::settings_with(1000, 1);
  for (uint32_t size : {0u, uint32_t(sizeof s - 4), uint32_t(sizeof s + 4), 0xffffffffu}) {
    s.struct_size = size;
    plm_result* r = nullptr;
    expect_refused(plm_bake(k.b.scene, &s, nullptr, nullptr, &r), "plm_bake", "plm_bake_settings", size, sizeof s);
    EXPECT_EQ(r, nullptr);
    expect_refused(plm_bake_shard(k.b.scene, &s, 0, 1, nullptr, "/nonexistent/part", nullptr, nullptr),
                   "plm_bake_shard", "plm_bake_settings", size, sizeof s);
  }
  plm_lsystem_settings ls;
  plm_lsystem_settings_default(&ls);
  ls.struct_size = 3;
  uint32_t id = 0;
  expect_refused(plm_scene_add_lsystem(k.b.scene, "weed", "axiom: F\n", &ls, &id), "plm_scene_add_lsystem",
                 "plm_lsystem_settings", 3, sizeof ls);
}

TEST(StructSize, LightsLobesAndCsgArraysAreChecked) {
  SceneBuilder b;
  const uint32_t glass = b.material("glass", {0.0f, 0.0f, 0.0f});
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_POINT);
  l.struct_size = 0;
  expect_refused(plm_scene_add_light(b.scene, "lamp", &l, nullptr), "plm_scene_add_light", "plm_light", 0, sizeof l);
  l.struct_size = sizeof l;
  EXPECT_EQ(plm_scene_add_light(b.scene, "lamp", &l, nullptr), PLM_OK) << plm_last_error();

  plm_lobe lobe;
  plm_lobe_default(&lobe, PLM_LOBE_GLASS);
  lobe.struct_size = sizeof lobe + 4;
  expect_refused(plm_scene_add_material_lobe(b.scene, glass, &lobe), "plm_scene_add_material_lobe", "plm_lobe",
                 sizeof lobe + 4, sizeof lobe);
  // The layout before weight: the weight is the default's, 1, whatever follows.
  lobe.struct_size = offsetof(plm_lobe, weight);
  lobe.weight = -5.0f;  // past the size: not read (it would be refused)
  EXPECT_EQ(plm_scene_add_material_lobe(b.scene, glass, &lobe), PLM_OK) << plm_last_error();

  plm_csg_primitive p = plm_test::sized<plm_csg_primitive>();
  p.matrix[0] = p.matrix[5] = p.matrix[10] = 1.0;
  plm_csg_node nodes[2] = {{sizeof(plm_csg_node), PLM_CSG_UNION, 0, 1},
                           {sizeof(plm_csg_node), PLM_CSG_LEAF, 0, 0}};
  const uint32_t child = 1;
  nodes[1].struct_size = 8;
  EXPECT_EQ(plm_scene_add_csg(b.scene, "ball", &p, 1, nodes, 2, &child, 1, 0, nullptr), PLM_ERROR_STRUCT_SIZE);
  EXPECT_NE(std::string(plm_last_error()).find("nodes[1]"), std::string::npos) << plm_last_error();
  nodes[1].struct_size = sizeof(plm_csg_node);
  p.struct_size = 0;
  expect_refused(plm_scene_add_csg(b.scene, "ball", &p, 1, nodes, 2, &child, 1, 0, nullptr), "plm_scene_add_csg",
                 "plm_csg_primitive", 0, sizeof p);
  p.struct_size = sizeof p;
  EXPECT_EQ(plm_scene_add_csg(b.scene, "ball", &p, 1, nodes, 2, &child, 1, 0, nullptr), PLM_OK) << plm_last_error();
}

TEST(StructSize, PartInfoWritesTheCallersSettingsSize) {
  Baked k;
  const std::string part = ::testing::TempDir() + "/struct_size.part";
  plm_bake_settings s = plm_test::settings_with(8192, 1);
  ASSERT_EQ(plm_bake_shard(k.b.scene, &s, 0, 1, nullptr, part.c_str(), nullptr, nullptr), PLM_OK) << plm_last_error();
  plm_bake_settings out;
  std::memset(&out, 0xA5, sizeof out);
  out.struct_size = offsetof(plm_bake_settings, texel_value);
  ASSERT_EQ(plm_part_info(part.c_str(), &out, nullptr, nullptr, nullptr, 0), PLM_OK) << plm_last_error();
  EXPECT_EQ(out.struct_size, offsetof(plm_bake_settings, texel_value));
  EXPECT_EQ(out.photon_count, 8192u);
  EXPECT_EQ(out.direct_samples, 1u);
  EXPECT_EQ(out.texel_value, 0xA5A5A5A5u) << "past the caller's size: untouched";
  out.struct_size = 0;
  expect_refused(plm_part_info(part.c_str(), &out, nullptr, nullptr, nullptr, 0), "plm_part_info",
                 "plm_bake_settings", 0, sizeof out);
  std::remove(part.c_str());
}

}  // namespace

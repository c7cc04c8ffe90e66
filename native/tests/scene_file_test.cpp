// The JSON scene file (docs/scene-file.md): a furnace file bakes to its
// analytic answer, an OBJ mesh equals the same mesh inline bit for bit, and
// every malformed input is refused with the JSON path of the offending value.
#include "io/scene_file.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "test_support.h"

namespace {

// A private folder for the OBJ files of these tests.
std::string temp_dir() {
  static const std::string dir = [] {
    std::string d = testing::TempDir() + "photonlm_scene_file_" + std::to_string(getpid());
    ::mkdir(d.c_str(), 0700);
    return d;
  }();
  return dir;
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
  ASSERT_TRUE(f.good()) << path;
}

// Parses text with OBJ paths relative to temp_dir(); error "" on success.
std::string parse(const std::string& text, plm::SceneFile& out, const plm::SceneFileLimits& limits = {}) {
  plm::SceneFileOptions options;
  options.limits = limits;
  options.base_dir = temp_dir();
  std::string error;
  if (!plm::parse_scene_file_text(text, options, out, error)) return error.empty() ? "(empty error)" : error;
  return "";
}

// A quad o + s*eu + t*ev (front side along eu x ev) as an inline mesh object.
std::string quad_mesh(const char* name, const float o[3], const float eu[3], const float ev[3], int res) {
  auto p = [&](float s, float t) {
    std::string r;
    for (int c = 0; c < 3; ++c) r += (c ? "," : "") + std::to_string(o[c] + s * eu[c] + t * ev[c]);
    return r;
  };
  return std::string("{\"name\": \"") + name + "\", \"positions\": [" + p(0, 0) + "," + p(1, 0) + "," + p(0, 1) +
         "," + p(1, 1) + "], \"indices\": [0,1,3, 0,3,2], \"lightmap_uv\": [0,0, 1,0, 1,1, 0,0, 1,1, 0,1]," +
         " \"lightmap_resolution\": " + std::to_string(res) + "}";
}

// A closed cube [-1, 1]^3 of six inward-facing quads, albedo rho, emission 1.
std::string furnace_file(float rho, int res, uint64_t photons) {
  const float faces[6][3][3] = {
      {{-1, -1, -1}, {2, 0, 0}, {0, 2, 0}}, {{-1, -1, 1}, {0, 2, 0}, {2, 0, 0}},
      {{-1, -1, -1}, {0, 2, 0}, {0, 0, 2}}, {{1, -1, -1}, {0, 0, 2}, {0, 2, 0}},
      {{-1, -1, -1}, {0, 0, 2}, {2, 0, 0}}, {{-1, 1, -1}, {2, 0, 0}, {0, 0, 2}}};
  std::string meshes;
  for (int f = 0; f < 6; ++f)
    meshes += (f ? ",\n" : "") + quad_mesh(("face" + std::to_string(f)).c_str(), faces[f][0], faces[f][1], faces[f][2], res);
  return "{\"version\": 1,\n\"materials\": [{\"name\": \"furnace\", \"albedo\": " + std::to_string(rho) +
         ", \"emission\": [1, 1, 1]}],\n\"meshes\": [" + meshes + "],\n\"settings\": {\"photon_count\": " +
         std::to_string(photons) + ", \"seed\": 7, \"texel_value\": \"AREA\", \"sampler\": \"DEFAULT\"}}";
}

plm_status bake(const plm::SceneFile& f, plm_test::BakeResult& r) {
  return plm_bake(f.scene, &f.settings, nullptr, nullptr, &r.r);
}

}  // namespace

// The Cornell box as the add-on exports it (docs/bench_vs_cycles.py), at
// 1 %: after the gathers most of the error is the gather's, which more
// photons lower (each texel weighs photons and gather by variance). The
// photon pass once stopped at its first check (65,536 photons, 1.1 %
// estimated, the target not reached) when it took the gather's part as out
// of its reach; with the gather's noise calibrated the first check can meet
// the target (0.91-0.98 % estimated, 1.01-1.15 % measured in the benchmark's
// copy of this scene), and the bake must end at the target either way.
TEST(SceneFile, TargetReachedWhereTheGatherHoldsMostOfTheError) {
  plm::SceneFile f;
  std::string error;
  ASSERT_TRUE(plm::read_scene_file(PLM_TEST_DATA_DIR "/cornell_blender.json", {}, f, error)) << error;
  EXPECT_EQ(f.settings.target_error, 0.01);
  plm_test::BakeResult r;
  ASSERT_EQ(bake(f, r), PLM_OK) << plm_last_error();
  const plm_bake_stats st = r.stats();
  EXPECT_LE(st.error_estimate, f.settings.target_error);
  EXPECT_GE(st.photons_emitted, 16u * 4096);
  EXPECT_EQ(r.warning("not reached"), "");
}

TEST(SceneFile, FurnaceBakesToEmissionOverOneMinusAlbedo) {
  plm::SceneFile f;
  ASSERT_EQ(parse(furnace_file(0.5f, 8, 1000000), f), "");
  ASSERT_EQ(f.meshes.size(), 6u);
  EXPECT_EQ(f.settings.photon_count, 1000000u);
  EXPECT_EQ(f.settings.seed, 7u);
  EXPECT_EQ(f.settings.texel_value, uint32_t(PLM_TEXEL_AREA));
  plm_test::BakeResult r;
  ASSERT_EQ(bake(f, r), PLM_OK) << plm_last_error();
  const double exact = 1.0 / (1.0 - 0.5);
  double sum = 0, z2 = 0;
  int n = 0;
  for (const plm::SceneFileMesh& m : f.meshes) {
    const plm_test::Map lm = r.map(m.id);
    ASSERT_EQ(lm.w, 8u);
    for (size_t t = 0; t < lm.coverage.size(); ++t) {
      if (lm.coverage[t] < 0.999f) continue;
      sum += lm.value(t);
      const double z = (lm.value(t) - exact) / lm.error[t];
      z2 += z * z;
      ++n;
    }
  }
  ASSERT_EQ(n, 6 * 64);
  EXPECT_NEAR(sum / n, exact, 0.01 * exact);
  // Texels scatter around the exact value as their reported errors say.
  EXPECT_GT(z2 / n, 0.3);
  EXPECT_LT(z2 / n, 2.0);
}

TEST(SceneFile, ObjMeshEqualsInlineMeshBitForBit) {
  // A floor of two quads (one of them written as a polygon with negative indices) under a point
  // light, and a red wall chosen by usemtl; the same geometry inline, fan-triangulated by hand.
  write_text(temp_dir() + "/floor.obj",
             "# floor\r\nmtllib ignored.mtl\no floor\n"
             "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
             "vt 0 0\nvt 0.5 0\nvt 0.5 1\nvt 0 1\nvt 1 0\nvt 1 1\n"
             "vn 0 0 1\n"
             "s off\n"
             "f 1/1/1 2/2/1 3/3/1 4/4/1\n"
             "v 1 -1 0\nv 1 -1 2\nv 1 1 2\nv 1 1 0\n"
             "usemtl red\n"
             "f -4/2 -3/5 -2/6 -1/3\n");
  const std::string common =
      R"("materials": [{"name": "grey", "albedo": 0.6}, {"name": "red", "albedo": [0.8, 0.1, 0.1]}],
         "lights": [{"type": "POINT", "power": 200, "location": [0, 0, 1.5]}],
         "settings": {"photon_count": 30000, "seed": 11, "thread_count": 3, "direct_samples": 4})";
  const std::string obj_file =
      "{" + common + R"(, "meshes": [{"name": "floor", "obj": "floor.obj", "material": "grey", "lightmap_resolution": [16, 8]}]})";
  const std::string inline_file = "{" + common + R"(, "meshes": [{"name": "floor",
      "positions": [-1,-1,0, 1,-1,0, 1,1,0, -1,1,0, 1,-1,0, 1,-1,2, 1,1,2, 1,1,0],
      "indices": [0,1,2, 0,2,3, 4,5,6, 4,6,7],
      "lightmap_uv": [0,0, 0.5,0, 0.5,1,  0,0, 0.5,1, 0,1,  0.5,0, 1,0, 1,1,  0.5,0, 1,1, 0.5,1],
      "materials": ["grey", "grey", 1, "red"], "lightmap_resolution": [16, 8]}]})";
  plm::SceneFile a, b;
  ASSERT_EQ(parse(obj_file, a), "");
  ASSERT_EQ(parse(inline_file, b), "");
  plm_test::BakeResult ra, rb;
  ASSERT_EQ(bake(a, ra), PLM_OK) << plm_last_error();
  ASSERT_EQ(bake(b, rb), PLM_OK) << plm_last_error();
  const plm_test::Map ma = ra.map(0), mb = rb.map(0);
  ASSERT_EQ(ma.rgb.size(), size_t(16 * 8 * 3));
  ASSERT_EQ(ma.rgb.size(), mb.rgb.size());
  EXPECT_EQ(std::memcmp(ma.rgb.data(), mb.rgb.data(), ma.rgb.size() * sizeof(float)), 0);
  EXPECT_EQ(std::memcmp(ma.error.data(), mb.error.data(), ma.error.size() * sizeof(float)), 0);
  double lit = 0;
  for (float v : ma.rgb) lit += v;
  EXPECT_GT(lit, 0.0);
}

TEST(SceneFile, OlGroupsCsgAndWorldAreRead) {
  const std::string text = R"({
    "materials": [{"name": "white"}],
    "ol_groups": [{"name": "props", "resolution": 8}],
    "world": {"radiance": [0.1, 0.2, 0.3]},
    "meshes": [
      {"name": "carrier", "positions": [-1,-1,0, 1,-1,0, 1,1,0, -1,1,0], "indices": [0,1,2, 0,2,3],
       "lightmap_uv": [0,0, 1,0, 1,1, 0,0, 1,1, 0,1], "lightmap_resolution": 4},
      {"name": "prop", "positions": [0,0,0, 1,0,0, 0,1,0], "indices": [0,1,2], "ol_group": "props"}],
    "csg": [{"name": "ball", "primitives": [{"shape": "SPHERE", "material": "white",
             "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0]}],
             "nodes": [{"op": "LEAF", "first": 0}], "carrier": "carrier"}],
    "settings": {"max_bounces": 3, "dilation": 2, "filter_radius": 1, "time_budget": 1.5,
                 "target_error": 0.05, "sampler": "SOBOL"}})";
  plm::SceneFile f;
  ASSERT_EQ(parse(text, f), "");
  ASSERT_EQ(f.ol_groups.size(), 1u);
  EXPECT_EQ(f.meshes[1].ol_group, 0);
  EXPECT_EQ(f.settings.max_bounces, 3u);
  EXPECT_EQ(f.settings.sampler, uint32_t(PLM_SAMPLER_SOBOL));
  EXPECT_DOUBLE_EQ(f.settings.time_budget, 1.5);
}

struct Malformed {
  const char* text;
  const char* path;     // the error starts with "path: "
  const char* message;  // and contains this
};

std::ostream& operator<<(std::ostream& os, const Malformed& m) { return os << m.text; }

class SceneFileMalformed : public testing::TestWithParam<Malformed> {};

#define QUAD R"({"positions": [0,0,0, 1,0,0, 0,1,0], "indices": [0,1,2]})"
#define UVQ R"("positions": [0,0,0, 1,0,0, 0,1,0], "indices": [0,1,2], "lightmap_uv": [0,0, 1,0, 0,1])"

const Malformed kMalformed[] = {
    {"[]", "scene", "expected an object, got an array"},
    {R"({"meshes": 3})", "scene.meshes", "expected an array, got 3"},
    {R"({"mesh": []})", "scene.mesh", "unknown field (allowed: version, settings"},
    {R"({"version": 2})", "scene.version", "this reader knows version 1, got 2"},
    {R"({"materials": [{"albedo": "abc"}]})", "scene.materials[0].albedo", "expected [r, g, b] or a number, got \"abc\""},
    {R"({"materials": [{"albedo": [0.5, "NaN", 0.5]}]})", "scene.materials[0].albedo[1]", "expected a number, got \"NaN\""},
    {R"({"materials": [{"emission": [1, 1]}]})", "scene.materials[0].emission", "expected 3 numbers [r, g, b], got 2"},
    {R"({"materials": [{"albedo": 1.5}]})", "scene.materials[0]", "albedo"},
    {R"({"materials": [{"colour": 1}]})", "scene.materials[0].colour", "unknown field"},
    {R"({"materials": [{"name": 7}]})", "scene.materials[0].name", "expected a string, got 7"},
    {R"({"materials": [{"lobes": {}}]})", "scene.materials[0].lobes", "expected an array, got an object"},
    {R"({"materials": [{"lobes": [{"color": 1}]}]})", "scene.materials[0].lobes[0]", "missing field \"type\""},
    {R"({"materials": [{"lobes": [{"type": "chrome"}]}]})", "scene.materials[0].lobes[0].type",
     "\"chrome\" is not one of glossy, fresnel, glass, refraction, transparent"},
    {R"({"materials": [{"lobes": [{"type": "glass", "eta": 1.5}]}]})", "scene.materials[0].lobes[0].eta",
     "unknown field (allowed: type, color, weight, roughness, ior, abbe)"},
    {R"({"materials": [{"name": "g", "albedo": 0, "lobes": [{"type": "glass", "ior": 0}]}]})",
     "scene.materials[0].lobes[0]", "material 'g': lobe 0 (glass): ior 0 must be > 0"},
    {R"({"materials": [{"albedo": 0.5, "lobes": [{"type": "glossy", "color": 0.6}]}]})",
     "scene.materials[0].lobes[0]", "above 1"},
    {R"({"materials": [{"lobes": [{"type": "glossy", "roughness": "rough"}]}]})",
     "scene.materials[0].lobes[0].roughness", "expected a number, got \"rough\""},
    {R"({"materials": [{"lobes": [{"type":"fresnel"},{"type":"fresnel"},{"type":"fresnel"},{"type":"fresnel"},{"type":"fresnel"},{"type":"fresnel"},{"type":"fresnel"},{"type":"fresnel"},{"type":"fresnel"}]}]})",
     "scene.materials[0].lobes", "9 lobes exceed the limit of 8"},
    {R"({"meshes": [)" QUAD "," QUAD R"(, {"positions": [0,0,0, 1,0,0, 0,"abc",0], "indices": [0,1,2]}]})",
     "scene.meshes[2].positions[7]", "expected a number, got \"abc\""},
    {R"({"meshes": [{"indices": [0,1,2]}]})", "scene.meshes[0]", "missing field \"positions\""},
    {R"({"meshes": [{"positions": [0,0,0, 1,0,0, 0,1], "indices": [0,1,2]}]})", "scene.meshes[0].positions",
     "expected 3 numbers per vertex, got 8 numbers"},
    {R"({"meshes": [{"positions": [0,0,0, 1,0,0, 0,1,0], "indices": [0,1,9]}]})", "scene.meshes[0].indices[2]",
     "vertex index 9 is out of range (the mesh has 3 vertices)"},
    {R"({"meshes": [{"positions": [0,0,0, 1,0,0, 0,1,0], "indices": [-1,1,2]}]})", "scene.meshes[0].indices[0]",
     "expected an integer >= 0, got -1"},
    {R"({"meshes": [{"positions": [0,0,0, 1,0,0, 0,1,0], "indices": [0,1.5,2]}]})", "scene.meshes[0].indices[1]",
     "expected an integer, got 1.5"},
    {R"({"meshes": [{"positions": [0,0,0, 1,0,0, 0,1,0], "indices": [0,1,2], "lightmap_uv": [0,0, 1,0], "lightmap_resolution": 4}]})",
     "scene.meshes[0].lightmap_uv", "expected 2 numbers (u, v) per triangle corner: 6 for 1 triangles, got 4"},
    {R"({"meshes": [{)" UVQ R"(}], "x": 1})", "scene.x", "unknown field"},
    {R"({"meshes": [{)" UVQ R"(}]})", "scene.meshes[0].lightmap_uv", "given, but the mesh has no lightmap"},
    {R"({"meshes": [{)" UVQ R"(, "lightmap_resolution": 100000}]})", "scene.meshes[0].lightmap_resolution",
     "100000 exceeds the limit of 16384"},
    {R"({"meshes": [{)" UVQ R"(, "lightmap_resolution": [8]}]})", "scene.meshes[0].lightmap_resolution",
     "expected N or [width, height], got an array of 1"},
    {R"({"materials": [{}], "meshes": [{"positions": [0,0,0, 1,0,0, 0,1,0], "indices": [0,1,2], "materials": [0, 0]}]})",
     "scene.meshes[0].materials", "expected one material per triangle: 1, got 2"},
    {R"({"materials": [{"name": "grey"}], "meshes": [{"positions": [0,0,0, 1,0,0, 0,1,0], "indices": [0,1,2], "material": "gold"}]})",
     "scene.meshes[0].material", "\"gold\" is not the name of one of scene.materials"},
    {R"({"materials": [{}], "meshes": [{"positions": [0,0,0, 1,0,0, 0,1,0], "indices": [0,1,2], "material": 5}]})",
     "scene.meshes[0].material", "index 5 is out of range (scene.materials has 1)"},
    {R"({"meshes": [{"positions": [0,0,0, 1,0,0, 0,1,1e39], "indices": [0,1,2]}]})", "scene.meshes[0].positions[8]",
     "out of the range of a 32-bit float"},
    {R"({"meshes": [{"positions": [0,0,0, 1,0,0, 0,1,0], "indices": [0,1,2], "ol_group": "x"}]})",
     "scene.meshes[0].ol_group", "\"x\" is not the name of one of scene.ol_groups"},
    {R"({"lights": [{"type": "LASER"}]})", "scene.lights[0].type",
     "\"LASER\" is not one of POINT, SPOT, SUN, AREA_RECT, AREA_DISK"},
    {R"({"lights": [{"power": 10}]})", "scene.lights[0]", "missing field \"type\""},
    {R"({"lights": [{"type": "SUN", "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0]}]})", "scene.lights[0].matrix",
     "expected 16 numbers, got 15"},
    {R"({"lights": [{"type": "POINT", "power": -5}]})", "scene.lights[0]", "power"},
    {R"({"lights": [{"type": "POINT", "matrix": [1], "location": [0,0,0]}]})", "scene.lights[0].location",
     "give either \"matrix\" or \"location\", not both"},
    {R"({"world": {"radiance": -1}})", "scene.world", "radiance"},
    {R"({"world": [1, 1, 1]})", "scene.world", "expected an object, got an array"},
    {R"({"world": {"map": "missing_sky.hdr"}})", "scene.world.map", "missing_sky.hdr"},
    {R"({"world": {"map": "sky.hdr", "radiance": 1}})", "scene.world.radiance", "give either"},
    {R"({"world": {"rotation": [1,0,0, 0,1,0, 0,0,1]}})", "scene.world.rotation", "only with \"map\""},
    {R"({"world": {"map": "sky.hdr", "rotation": [1, 0]}})", "scene.world.rotation", "expected 9 numbers, got 2"},
    {R"({"world": {"map": ""}})", "scene.world.map", "empty file name"},
    {R"({"settings": {"texel_value": "PIXEL"}})", "scene.settings.texel_value", "\"PIXEL\" is not one of CYCLES, AREA"},
    {R"({"settings": {"sampler": 2}})", "scene.settings.sampler", "expected a string, got 2"},
    {R"({"settings": {"seed": 5000000000}})", "scene.settings.seed", "5000000000 exceeds the limit of 4294967295"},
    {R"({"settings": {"photon_count": 1e30}})", "scene.settings.photon_count", "exceeds the limit of 1099511627776"},
    {R"({"settings": {"target_error": -0.1}})", "scene.settings.target_error", "must be >= 0, got -0.1"},
    {R"({"settings": {"photons": 100}})", "scene.settings.photons", "unknown field"},
    {R"({"csg": [{"primitives": [{"shape": "BLOB"}], "nodes": [{"op": "LEAF", "first": 0}]}]})",
     "scene.csg[0].primitives[0].shape", "\"BLOB\" is not one of SPHERE, BOX"},
    {R"({"csg": [{"primitives": [{"shape": "BOX"}], "nodes": [{"op": "UNION", "first": 0}]}]})", "scene.csg[0].nodes[0]",
     "missing field \"count\""},
    {R"({"csg": [{"primitives": [{"shape": "BOX"}], "nodes": [{"op": "LEAF", "first": 3}]}]})", "scene.csg[0]", "3"},
    {R"({"meshes": [)" QUAD R"(], "csg": [{"primitives": [{"shape": "BOX"}], "nodes": [{"op": "LEAF", "first": 0}], "carrier": 0}]})",
     "scene.csg[0].carrier", "has no lightmap"},
    {R"({"meshes": [{"obj": "missing.obj"}]})", "scene.meshes[0].obj", "missing.obj: cannot open"},
    {R"({"meshes": [{"obj": "bad_v.obj"}]})", "scene.meshes[0].obj", "bad_v.obj:3: v needs 3 coordinates"},
    {R"({"meshes": [{"obj": "bad_f.obj"}]})", "scene.meshes[0].obj", "bad_f.obj:4: vertex index 7 is out of range (3 so far)"},
    {R"({"meshes": [{"obj": "bad_num.obj"}]})", "scene.meshes[0].obj", "bad_num.obj:2: \"1.0.0\" is not a number"},
    {R"({"meshes": [{"obj": "bad_f.obj", "lightmap_resolution": 4}]})", "scene.meshes[0].obj",
     "bad_f.obj:4: face corner 1 has no texture coordinate (vt)"},
    {R"({"meshes": [{"obj": "bad_mtl.obj"}]})", "scene.meshes[0].obj",
     "bad_mtl.obj:4: usemtl \"gold\": the scene has no material of that name"},
    {R"({"meshes": [{"obj": "bad_v.obj", "indices": [0,1,2]}]})", "scene.meshes[0].indices",
     "not allowed together with \"obj\""},
    {"{\"meshes\": [\n{\"positions\": [1, 2,, 3]}]}", "", "JSON syntax: parse error at line 2"},
    {R"({"meshes": [{"positions": [1e999]}]})", "", "JSON syntax: number overflow"},
};

TEST_P(SceneFileMalformed, NamesTheJsonPath) {
  const Malformed& m = GetParam();
  write_text(temp_dir() + "/bad_v.obj", "v 0 0 0\nv 1 0 0\nv 0 1\nf 1 2 3\n");
  write_text(temp_dir() + "/bad_f.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n");
  write_text(temp_dir() + "/bad_num.obj", "v 0 0 0\nv 1.0.0 0 0\n");
  write_text(temp_dir() + "/bad_mtl.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl gold\nf 1 2 3\n");
  plm::SceneFile f;
  const std::string error = parse(m.text, f);
  ASSERT_NE(error, "") << "accepted";
  EXPECT_EQ(error.rfind(std::string(m.path) + (*m.path ? ": " : ""), 0), 0u) << error;
  EXPECT_NE(error.find(m.message), std::string::npos) << error;
}

INSTANTIATE_TEST_SUITE_P(SceneFile, SceneFileMalformed, testing::ValuesIn(kMalformed));

TEST(SceneFile, LimitsOnCountsAndSizes) {
  plm::SceneFileLimits limits;
  limits.max_items = 2;
  limits.max_vertices = 4;
  limits.max_triangles = 1;
  plm::SceneFile f;
  EXPECT_EQ(parse(R"({"materials": [{}, {}, {}]})", f, limits), "scene.materials: 3 materials exceed the limit of 2");
  EXPECT_EQ(parse(R"({"meshes": [{"positions": [0,0,0, 1,0,0, 0,1,0, 1,1,0, 2,2,2], "indices": [0,1,2]}]})", f, limits),
            "scene.meshes[0].positions: 15 numbers exceed the limit of 12");
  EXPECT_EQ(parse(R"({"meshes": [{"positions": [0,0,0, 1,0,0, 0,1,0], "indices": [0,1,2, 0,2,1]}]})", f, limits),
            "scene.meshes[0].indices: 6 indices exceed the limit of 3");
  write_text(temp_dir() + "/big.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3 4\n");
  EXPECT_NE(parse(R"({"meshes": [{"obj": "big.obj"}]})", f, limits).find("big.obj:5: more than 1 triangles"),
            std::string::npos);
  limits = {};
  limits.max_file_bytes = 10;
  EXPECT_EQ(parse(R"({"materials": []})", f, limits), "the scene file is larger than the limit of 10 bytes");
  limits = {};
  EXPECT_NE(parse(std::string(100, '[') + std::string(100, ']'), f, limits).find("nesting deeper than 64"),
            std::string::npos);
}

TEST(SceneFile, FileErrorsNameTheFile) {
  plm::SceneFile f;
  std::string error;
  EXPECT_FALSE(plm::read_scene_file(temp_dir() + "/nowhere.json", {}, f, error));
  EXPECT_NE(error.find("nowhere.json: cannot open"), std::string::npos) << error;
  write_text(temp_dir() + "/broken.json", R"({"lights": [{"type": "LASER"}]})");
  EXPECT_FALSE(plm::read_scene_file(temp_dir() + "/broken.json", {}, f, error));
  EXPECT_EQ(error, temp_dir() + "/broken.json: scene.lights[0].type: \"LASER\" is not one of POINT, SPOT, SUN, "
                                "AREA_RECT, AREA_DISK, PORTAL");
  // OBJ paths are relative to the scene file's folder.
  write_text(temp_dir() + "/tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  write_text(temp_dir() + "/tri.json", R"({"meshes": [{"obj": "tri.obj"}]})");
  EXPECT_TRUE(plm::read_scene_file(temp_dir() + "/tri.json", {}, f, error)) << error;
  // The fuzzer's mode: no file is opened.
  plm::SceneFileOptions no_files;
  no_files.allow_file_access = false;
  no_files.base_dir = temp_dir();
  EXPECT_FALSE(plm::parse_scene_file_text(R"({"meshes": [{"obj": "tri.obj"}]})", no_files, f, error));
  EXPECT_EQ(error, "scene.meshes[0].obj: file access is disabled");
}

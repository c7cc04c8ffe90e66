// glTF mesh references in the scene file (docs/scene-file.md): a .gltf (external buffer) and
// the same .glb bake bit for bit like the same mesh written inline (node transforms applied by
// the test's own arithmetic, v flipped, every index type, the lightmap UV from TEXCOORD_1);
// quaternion rotations, mirroring nodes and node/mesh selection give the expected geometry;
// malformed files are refused naming the JSON path and the glTF object.
#include "io/gltf_mesh.h"
#include "io/scene_file.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sys/stat.h>
#include <unistd.h>

#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "test_support.h"

namespace {

using json = nlohmann::json;

std::string temp_dir() {
  static const std::string dir = [] {
    std::string d = testing::TempDir() + "photonlm_gltf_" + std::to_string(getpid());
    ::mkdir(d.c_str(), 0700);
    return d;
  }();
  return dir;
}

void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream f(path, std::ios::binary);
  f << bytes;
  ASSERT_TRUE(f.good()) << path;
}

// Builds glTF accessors over one binary buffer.
struct GltfBuilder {
  std::string bin;
  json doc = {{"asset", {{"version", "2.0"}}}, {"bufferViews", json::array()}, {"accessors", json::array()}};

  int add(const void* data, size_t bytes, int component, const char* type, size_t count) {
    while (bin.size() % 4) bin.push_back('\0');
    doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes}});
    bin.append(static_cast<const char*>(data), bytes);
    doc["accessors"].push_back({{"bufferView", doc["bufferViews"].size() - 1},
                                {"componentType", component}, {"type", type}, {"count", count}});
    return int(doc["accessors"].size() - 1);
  }
  int floats(const std::vector<float>& v, const char* type, int per) {
    return add(v.data(), v.size() * 4, 5126, type, v.size() / size_t(per));
  }
  template <typename T>
  int indices(const std::vector<T>& v) {
    const int component = sizeof(T) == 1 ? 5121 : sizeof(T) == 2 ? 5123 : 5125;
    return add(v.data(), v.size() * sizeof(T), component, "SCALAR", v.size());
  }
  // Writes name.gltf (+ name.bin) and name.glb into temp_dir().
  void write(const std::string& name) {
    while (bin.size() % 4) bin.push_back('\0');
    json d = doc;
    d["buffers"] = {{{"uri", name + ".bin"}, {"byteLength", bin.size()}}};
    write_bytes(temp_dir() + "/" + name + ".bin", bin);
    write_bytes(temp_dir() + "/" + name + ".gltf", d.dump(1));
    d["buffers"] = {{{"byteLength", bin.size()}}};
    std::string js = d.dump();
    while (js.size() % 4) js.push_back(' ');
    auto u32 = [](uint32_t x) { return std::string(reinterpret_cast<const char*>(&x), 4); };
    const std::string glb = "glTF" + u32(2) + u32(uint32_t(12 + 8 + js.size() + 8 + bin.size())) +
                            u32(uint32_t(js.size())) + "JSON" + js + u32(uint32_t(bin.size())) + "BIN" +
                            std::string(1, '\0') + bin;
    write_bytes(temp_dir() + "/" + name + ".glb", glb);
  }
};

// Local geometry: a floor quad (mesh 0) and a wall of two triangles in two primitives plus a
// non-indexed triangle (mesh 1). TEXCOORD_0 is junk, TEXCOORD_1 the lightmap UV (glTF's v down).
const std::vector<float> kFloorPos = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
const std::vector<uint16_t> kFloorIdx = {0, 1, 2, 0, 2, 3};
const std::vector<float> kFloorUv = {0, 1, 0.5f, 1, 0.5f, 0.5f, 0, 0.5f};
const std::vector<float> kWallPos = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
const std::vector<uint8_t> kWallIdxA = {0, 1, 2};
const std::vector<uint32_t> kWallIdxB = {0, 2, 3};
const std::vector<float> kWallUv = {0.5f, 1, 1, 1, 1, 0.5f, 0.5f, 0.5f};
const std::vector<float> kTriPos = {0, 0, 0.25f, 0.5f, 0, 0.25f, 0, 0.5f, 0.25f};
const std::vector<float> kTriUv = {0, 0.5f, 0.25f, 0.5f, 0, 0.25f};

// Node transforms, applied here by the test's own arithmetic to build the inline mesh:
// root translates by (0, 0, 0.5); floor scales by (2, 2, 1) and moves by (-1, -1, 0); the wall's
// matrix turns local y into z (column-major) and moves it to x = 1.
void floor_to_world(const float* p, float* q) { q[0] = 2 * p[0] - 1, q[1] = 2 * p[1] - 1, q[2] = p[2] + 0.5f; }
void wall_to_world(const float* p, float* q) { q[0] = p[0] * 0 + 1, q[1] = p[0] * 2 - 1, q[2] = p[1] * 2 + 0.5f; }
// The wall matrix: x' = 1, y' = 2 x - 1, z' = 2 y (+ root's 0.5): columns (0,2,0), (0,0,2), (1,0,0)*0...
// glTF needs an invertible matrix: x' = 1 + 0.5 z (z is 0 on the wall), written column-major.
const std::vector<double> kWallMatrix = {0, 2, 0, 0, 0, 0, 2, 0, 0.5, 0, 0, 0, 1, -1, 0, 1};

GltfBuilder two_meshes() {
  GltfBuilder b;
  const int fp = b.floats(kFloorPos, "VEC3", 3), fi = b.indices(kFloorIdx), fu = b.floats(kFloorUv, "VEC2", 2);
  const int wp = b.floats(kWallPos, "VEC3", 3), wa = b.indices(kWallIdxA), wb = b.indices(kWallIdxB),
            wu = b.floats(kWallUv, "VEC2", 2);
  const int tp = b.floats(kTriPos, "VEC3", 3), tu = b.floats(kTriUv, "VEC2", 2);
  b.doc["meshes"] = {
      {{"name", "floor"},
       {"primitives", {{{"attributes", {{"POSITION", fp}, {"TEXCOORD_0", fu}, {"TEXCOORD_1", fu}}}, {"indices", fi}}}}},
      {{"name", "wall"},
       {"primitives",
        {{{"attributes", {{"POSITION", wp}, {"TEXCOORD_1", wu}}}, {"indices", wa}, {"mode", 4}},
         {{"attributes", {{"POSITION", wp}, {"TEXCOORD_1", wu}}}, {"indices", wb}},
         {{"attributes", {{"POSITION", tp}, {"TEXCOORD_1", tu}}}}}}}};
  b.doc["nodes"] = {{{"name", "root"}, {"translation", {0, 0, 0.5}}, {"children", {1, 2}}},
                    {{"name", "floor node"}, {"mesh", 0}, {"scale", {2, 2, 1}}, {"translation", {-1, -1, 0}}},
                    {{"name", "wall node"}, {"mesh", 1}, {"matrix", kWallMatrix}}};
  b.doc["scenes"] = {{{"nodes", {0}}}};
  b.doc["scene"] = 0;
  return b;
}

// The same geometry inline: positions transformed here, v flipped, corners in file order.
std::string inline_mesh() {
  std::vector<float> pos, uv;
  std::vector<uint32_t> idx;
  auto add = [&](const std::vector<float>& p, const std::vector<float>& u, const std::vector<uint32_t>& ix,
                 void (*xf)(const float*, float*)) {
    const uint32_t base = uint32_t(pos.size() / 3);
    for (size_t v = 0; v < p.size() / 3; ++v) {
      float q[3];
      xf(&p[3 * v], q);
      pos.insert(pos.end(), q, q + 3);
    }
    for (uint32_t i : ix) {
      idx.push_back(base + i);
      uv.push_back(u[2 * i]);
      uv.push_back(1.0f - u[2 * i + 1]);
    }
  };
  add(kFloorPos, kFloorUv, {0, 1, 2, 0, 2, 3}, floor_to_world);
  add(kWallPos, kWallUv, {0, 1, 2}, wall_to_world);
  add(kWallPos, kWallUv, {0, 2, 3}, wall_to_world);
  add(kTriPos, kTriUv, {0, 1, 2}, [](const float* p, float* q) {
    q[0] = 1 + 0.5f * p[2], q[1] = 2 * p[0] - 1, q[2] = 2 * p[1] + 0.5f;
  });
  return json{{"positions", pos}, {"indices", idx}, {"lightmap_uv", uv}}.dump();
}

std::string parse(const std::string& text, plm::SceneFile& out) {
  plm::SceneFileOptions options;
  options.base_dir = temp_dir();
  std::string error;
  if (!plm::parse_scene_file_text(text, options, out, error)) return error.empty() ? "(empty error)" : error;
  return "";
}

const char* kCommon = R"("materials": [{"name": "grey", "albedo": 0.6}],
  "lights": [{"type": "POINT", "power": 300, "location": [0.2, 0.1, 1.6]}],
  "settings": {"photon_count": 30000, "seed": 5, "direct_samples": 4})";

plm_test::Map bake_first(const std::string& text) {
  plm::SceneFile f;
  const std::string err = parse(text, f);
  EXPECT_EQ(err, "");
  plm_test::BakeResult r;
  EXPECT_EQ(plm_bake(f.scene, &f.settings, nullptr, nullptr, &r.r), PLM_OK) << plm_last_error();
  return r.map(0);
}

}  // namespace

TEST(SceneFileGltf, GltfAndGlbEqualTheInlineMeshBitForBit) {
  two_meshes().write("room");
  const std::string mesh_tail = R"(, "material": "grey", "lightmap_resolution": [16, 8]})";
  const plm_test::Map in = bake_first(std::string("{") + kCommon + R"(, "meshes": [{"name": "m", )" +
                                      inline_mesh().substr(1, inline_mesh().size() - 2) + mesh_tail + "]}");
  double lit = 0;
  for (float v : in.rgb) lit += v;
  EXPECT_GT(lit, 0.0);
  for (const char* file : {"room.gltf", "room.glb"}) {
    SCOPED_TRACE(file);
    const plm_test::Map g = bake_first(std::string("{") + kCommon + R"(, "meshes": [{"name": "m", "gltf": ")" + file +
                                       R"(", "gltf_texcoord": 1)" + mesh_tail + "]}");
    ASSERT_EQ(g.rgb.size(), in.rgb.size());
    EXPECT_EQ(std::memcmp(g.rgb.data(), in.rgb.data(), g.rgb.size() * sizeof(float)), 0);
    EXPECT_EQ(std::memcmp(g.coverage.data(), in.coverage.data(), g.coverage.size() * sizeof(float)), 0);
  }
}

TEST(SceneFileGltf, SelectionsRotationsAndMirrors) {
  GltfBuilder b = two_meshes();
  // Node 3: a quaternion turn of 90 degrees about z and a mirror in x, holding the floor mesh.
  const double h = std::sqrt(0.5);
  b.doc["nodes"].push_back({{"name", "mirror"}, {"mesh", 0}, {"rotation", {0, 0, h, h}}, {"scale", {-1, 1, 1}}});
  b.doc["scenes"][0]["nodes"].push_back(3);
  b.write("select");
  const std::string file = temp_dir() + "/select.gltf";
  plm::GltfLimits lim{1u << 30, 1u << 24, 1u << 24, 64};
  std::string error;
  plm::GltfMeshData d;

  plm::GltfSelection mesh;  // mesh 'floor' alone: local coordinates, indices as in the file
  mesh.kind = plm::GltfSelection::kMesh;
  mesh.name = "floor";
  ASSERT_TRUE(plm::read_gltf_mesh(file, mesh, 0, true, lim, d, error)) << error;
  EXPECT_EQ(d.positions, kFloorPos);
  EXPECT_EQ(d.indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));
  ASSERT_EQ(d.uv.size(), 12u);
  EXPECT_EQ(d.uv[3], 1.0f - kFloorUv[3]);

  plm::GltfSelection node;  // node 2 ('wall node'): its parent's translation applies
  node.kind = plm::GltfSelection::kNode;
  node.index = 2;
  ASSERT_TRUE(plm::read_gltf_mesh(file, node, 1, true, lim, d, error)) << error;
  ASSERT_EQ(d.positions.size(), 3u * 11);
  const float expect_v2[3] = {1, 1, 2.5f};  // local (1, 1, 0)
  for (int c = 0; c < 3; ++c) EXPECT_EQ(d.positions[6 + c], expect_v2[c]);

  node.index = 3;  // rotate (x, y) -> (-y, x) after mirroring x -> -x: (x, y) -> (-y, -x)
  ASSERT_TRUE(plm::read_gltf_mesh(file, node, 0, false, lim, d, error)) << error;
  ASSERT_EQ(d.positions.size(), 12u);
  for (size_t v = 0; v < 4; ++v) {
    EXPECT_NEAR(d.positions[3 * v + 0], -kFloorPos[3 * v + 1], 1e-6);
    EXPECT_NEAR(d.positions[3 * v + 1], -kFloorPos[3 * v + 0], 1e-6);
  }
  EXPECT_TRUE(d.uv.empty());
  // A mirror reverses the winding; the reader undoes it so the front stays up (+z).
  for (size_t t = 0; t < d.indices.size(); t += 3) {
    const float* a = &d.positions[3 * d.indices[t]];
    const float* p = &d.positions[3 * d.indices[t + 1]];
    const float* q = &d.positions[3 * d.indices[t + 2]];
    const double nz = double(p[0] - a[0]) * (q[1] - a[1]) - double(p[1] - a[1]) * (q[0] - a[0]);
    EXPECT_GT(nz, 0.0) << "triangle " << t / 3;
  }
}

struct GltfBad {
  const char* label;
  std::function<void(json&)> edit;  // applied to the glTF document
  const char* mesh_fields;          // extra scene-file fields of the mesh
  const char* expected;             // substring of the error
};

void PrintTo(const GltfBad& c, std::ostream* os) { *os << c.label; }

class SceneFileGltfMalformed : public testing::TestWithParam<GltfBad> {};

TEST_P(SceneFileGltfMalformed, NamesTheFieldAndTheGltfObject) {
  const GltfBad& c = GetParam();
  GltfBuilder b = two_meshes();
  if (c.edit) c.edit(b.doc);
  b.write("bad");
  plm::SceneFile f;
  std::string fields = c.mesh_fields;
  if (fields.find("gltf_texcoord") == std::string::npos) fields += R"("gltf_texcoord": 1, )";
  const std::string err = parse(std::string("{") + kCommon + R"(, "meshes": [{"gltf": "bad.gltf", )" + fields +
                                    R"("lightmap_resolution": 8}]})",
                                f);
  EXPECT_NE(err.find(c.expected), std::string::npos) << "error: " << err;
  const bool field_path = err.rfind("scene.meshes[0].", 0) == 0;
  EXPECT_TRUE(field_path) << "error: " << err;
}

INSTANTIATE_TEST_SUITE_P(
    Cases, SceneFileGltfMalformed,
    testing::Values(
        GltfBad{"lines", [](json& d) { d["meshes"][1]["primitives"][1]["mode"] = 1; }, "",
                "mesh 1 'wall' primitive 1: mode 1 (LINES) is not supported: only triangles"},
        GltfBad{"strip", [](json& d) { d["meshes"][0]["primitives"][0]["mode"] = 5; }, "",
                "mode 5 (TRIANGLE_STRIP) is not supported"},
        GltfBad{"no lightmap uv", nullptr, R"("gltf_texcoord": 2, )",
                "mesh 0 'floor' primitive 0: has no TEXCOORD_2 attribute"},
        GltfBad{"past the view", [](json& d) { d["accessors"][0]["count"] = 5; }, "",
                "accessor 0 (mesh 0 'floor' primitive 0 POSITION): 5 elements from byte 0 run past the end of bufferView 0"},
        GltfBad{"float indices", [](json& d) { d["accessors"][1]["componentType"] = 5126; }, "",
                "accessor 1 (mesh 0 'floor' primitive 0 indices): component type 5126 is not allowed"},
        GltfBad{"positions as vec2", [](json& d) { d["accessors"][0]["type"] = "VEC2"; }, "",
                "type is VEC2, expected VEC3"},
        GltfBad{"sparse", [](json& d) {
                  d["accessors"][0]["sparse"] = {{"count", 1}, {"indices", {{"bufferView", 1}, {"componentType", 5123}}},
                                                 {"values", {{"bufferView", 0}}}};
                }, "", "sparse accessors are not supported"},
        GltfBad{"no position", [](json& d) { d["meshes"][0]["primitives"][0]["attributes"].erase("POSITION"); }, "",
                "has no POSITION attribute"},
        GltfBad{"node cycle", [](json& d) { d["nodes"][1]["children"] = {0}; }, "", "reached twice"},
        GltfBad{"missing mesh name", nullptr, R"("gltf_mesh": "chair", )", "no mesh is named 'chair'"},
        GltfBad{"node index", nullptr, R"("gltf_node": 9, )", "node 9 does not exist (the file has 3)"},
        GltfBad{"both", nullptr, R"("gltf_mesh": 0, "gltf_node": 0, )", "give either"},
        GltfBad{"with positions", nullptr, R"("positions": [0,0,0], )", "not allowed together with \"gltf\""},
        GltfBad{"bad buffer", [](json& d) { d["bufferViews"][0]["byteLength"] = 4000; }, "",
                "accessor 0 (mesh 0 'floor' primitive 0 POSITION): bufferView 0 (bytes 0 + 4000) runs past the end of buffer 0"}),
    [](const testing::TestParamInfo<GltfBad>& info) {
      std::string s;
      for (const char* p = info.param.label; *p; ++p) s += std::isalnum((unsigned char)*p) ? *p : '_';
      return s;
    });

TEST(SceneFileGltf, IndexOutOfRangeNamesTheAccessor) {
  GltfBuilder b;
  const std::vector<uint16_t> idx = {0, 1, 7};
  const int p = b.floats(kTriPos, "VEC3", 3), i = b.indices(idx);
  b.doc["meshes"] = {{{"primitives", {{{"attributes", {{"POSITION", p}}}, {"indices", i}}}}}};
  b.doc["nodes"] = {{{"mesh", 0}}};
  b.write("oob");
  plm::SceneFile f;
  const std::string err = parse(R"({"meshes": [{"gltf": "oob.glb"}]})", f);
  EXPECT_NE(err.find("scene.meshes[0].gltf: "), std::string::npos) << err;
  EXPECT_NE(err.find("mesh 0 primitive 0 indices (accessor 1) element 2: vertex 7 is out of range (POSITION has 3)"),
            std::string::npos)
      << err;
  EXPECT_NE(parse(R"({"meshes": [{"gltf": "missing.gltf"}]})", f).find("cannot open"), std::string::npos);
  write_bytes(temp_dir() + "/junk.gltf", "{\"asset\": 3");
  EXPECT_NE(parse(R"({"meshes": [{"gltf": "junk.gltf"}]})", f).find("not a readable glTF 2.0 file"), std::string::npos);
  plm::SceneFileOptions no_files;
  no_files.allow_file_access = false;
  std::string error;
  EXPECT_FALSE(plm::parse_scene_file_text(R"({"meshes": [{"gltf": "oob.glb"}]})", no_files, f, error));
  EXPECT_NE(error.find("file access is disabled"), std::string::npos) << error;
}

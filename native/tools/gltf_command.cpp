// `photonlm gltf SCENE.json BAKE_DIR -o FILE.glb`: the meshes of a scene file
// with the lightmaps `photonlm bake` wrote for it, as one binary glTF, in the
// form the Blender add-on's export writes (docs/gltf.md): each lightmap an
// RGBM PNG on TEXCOORD_1, declared by MOZ_lightmap, FB_materials_lightmap and
// extras.photonlm_lightmap (with light groups, their layers too; with
// directional lightmaps, the SH L1 bands in glTF's axes).
#include "gltf_command.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include <nlohmann/json.hpp>
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>  // (its implementation: io/gltf_mesh.cpp, with the same options)

#define STB_IMAGE_WRITE_STATIC
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb/stb_image_write.h>

#include "bake_command.h"
#include "io/scene_file.h"
#include "photonlm/photonlm.h"

namespace plm_cli {
namespace {

constexpr int kBadInput = 1, kFailed = 2;
constexpr double kPi = 3.14159265358979323846;

int fail(int code, const std::string& message) {
  std::fprintf(stderr, "photonlm gltf: %s\n", message.c_str());
  return code;
}

// A lightmap's RGBM encoding (docs/gltf.md; the add-on's gltf/rgbm.py): range
// is its largest finite channel (1 for a black map), m a texel's largest
// channel over the range rounded up to 1/255, r, g, b rounded to the nearest
// 1/255; value = (r, g, b) m range. Rows top first, as PNG stores them.
std::vector<unsigned char> rgbm(const std::vector<float>& rgb, uint32_t w, uint32_t h, double& range) {
  double top = 0.0;
  for (float v : rgb)
    if (std::isfinite(v)) top = std::max(top, double(v));
  range = top > 0.0 ? top : 1.0;
  std::vector<unsigned char> out(4 * size_t(w) * h);
  for (uint32_t y = 0; y < h; ++y) {
    for (uint32_t x = 0; x < w; ++x) {
      const float* v = &rgb[3 * (size_t(h - 1 - y) * w + x)];  // the EXR's rows bottom first
      double c[3], peak = 0.0;
      for (int k = 0; k < 3; ++k) {
        c[k] = std::isfinite(v[k]) ? std::clamp(double(v[k]) / range, 0.0, 1.0) : 0.0;
        peak = std::max(peak, c[k]);
      }
      const double m = std::ceil(peak * 255.0);
      const double scale = m > 0.0 ? 255.0 / m : 0.0;
      unsigned char* o = &out[4 * (size_t(y) * w + x)];
      for (int k = 0; k < 3; ++k) o[k] = (unsigned char)std::clamp(std::nearbyint(c[k] * scale * 255.0), 0.0, 255.0);
      o[3] = (unsigned char)m;
    }
  }
  return out;
}

// Signed values (SH L1 bands) the same way (the add-on's gltf/rgbm.py
// encode_signed): value = (2 (r, g, b) - 1) m range, range the largest
// finite magnitude, m a texel's largest magnitude over it rounded up.
std::vector<unsigned char> rgbm_signed(const std::vector<float>& rgb, uint32_t w, uint32_t h, double& range) {
  double top = 0.0;
  for (float v : rgb)
    if (std::isfinite(v)) top = std::max(top, std::fabs(double(v)));
  range = top > 0.0 ? top : 1.0;
  std::vector<unsigned char> out(4 * size_t(w) * h);
  for (uint32_t y = 0; y < h; ++y) {
    for (uint32_t x = 0; x < w; ++x) {
      const float* v = &rgb[3 * (size_t(h - 1 - y) * w + x)];
      double c[3], peak = 0.0;
      for (int k = 0; k < 3; ++k) {
        c[k] = std::isfinite(v[k]) ? std::clamp(double(v[k]) / range, -1.0, 1.0) : 0.0;
        peak = std::max(peak, std::fabs(c[k]));
      }
      const double m = std::ceil(peak * 255.0);
      const double scale = m > 0.0 ? 255.0 / m : 0.0;
      unsigned char* o = &out[4 * (size_t(y) * w + x)];
      for (int k = 0; k < 3; ++k)
        o[k] = (unsigned char)std::clamp(std::nearbyint((c[k] * scale + 1.0) * 0.5 * 255.0), 0.0, 255.0);
      o[3] = (unsigned char)m;
    }
  }
  return out;
}

void png_append(void* context, void* data, int size) {
  auto* out = static_cast<std::vector<unsigned char>*>(context);
  out->insert(out->end(), static_cast<unsigned char*>(data), static_cast<unsigned char*>(data) + size);
}

// The whole file as one buffer: views appended 4-byte aligned.
struct Writer {
  tinygltf::Model model;
  std::vector<unsigned char>& bin() { return model.buffers[0].data; }
  int view(const void* data, size_t bytes, int target) {
    while (bin().size() % 4) bin().push_back(0);
    tinygltf::BufferView v;
    v.buffer = 0;
    v.byteOffset = bin().size();
    v.byteLength = bytes;
    v.target = target;
    const auto* p = static_cast<const unsigned char*>(data);
    bin().insert(bin().end(), p, p + bytes);
    model.bufferViews.push_back(v);
    return int(model.bufferViews.size() - 1);
  }
  int accessor(const std::vector<float>& data, int type, int width, bool bounds = false) {
    tinygltf::Accessor a;
    a.bufferView = view(data.data(), data.size() * sizeof(float), TINYGLTF_TARGET_ARRAY_BUFFER);
    a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    a.type = type;
    a.count = data.size() / size_t(width);
    if (bounds) {  // POSITION needs them
      a.minValues.assign(size_t(width), 1e300);
      a.maxValues.assign(size_t(width), -1e300);
      for (size_t i = 0; i < data.size(); ++i) {
        a.minValues[i % size_t(width)] = std::min(a.minValues[i % size_t(width)], double(data[i]));
        a.maxValues[i % size_t(width)] = std::max(a.maxValues[i % size_t(width)], double(data[i]));
      }
    }
    model.accessors.push_back(a);
    return int(model.accessors.size() - 1);
  }
  // A lightmap EXR as an RGBM PNG texture (sign < 0: -1 x the file's
  // values; sign != 0: signed values, RGBM_SIGNED); its range in `range`.
  int texture(const std::string& path, const std::string& name, double& range, std::string& error,
              int sign = 0) {
    uint32_t w = 0, h = 0;
    if (plm_read_lightmap_exr(path.c_str(), &w, &h, nullptr, nullptr, nullptr) != PLM_OK) {
      error = plm_last_error();
      return -1;
    }
    std::vector<float> rgb(3 * size_t(w) * h);
    if (plm_read_lightmap_exr(path.c_str(), &w, &h, rgb.data(), nullptr, nullptr) != PLM_OK) {
      error = plm_last_error();
      return -1;
    }
    if (sign < 0)
      for (float& v : rgb) v = -v;
    const std::vector<unsigned char> px = sign ? rgbm_signed(rgb, w, h, range) : rgbm(rgb, w, h, range);
    std::vector<unsigned char> png;
    if (!stbi_write_png_to_func(png_append, &png, int(w), int(h), 4, px.data(), int(4 * w))) {
      error = path + ": the PNG could not be encoded";
      return -1;
    }
    tinygltf::Image image;
    image.name = name;
    image.mimeType = "image/png";
    image.bufferView = view(png.data(), png.size(), 0);
    model.images.push_back(image);
    if (model.samplers.empty()) {
      tinygltf::Sampler s;
      s.magFilter = s.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
      s.wrapS = s.wrapT = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
      model.samplers.push_back(s);
    }
    tinygltf::Texture t;
    t.name = name;
    t.source = int(model.images.size() - 1);
    t.sampler = 0;
    model.textures.push_back(t);
    return int(model.textures.size() - 1);
  }
};

using tinygltf::Value;

Value number(double v) { return Value(v); }

}  // namespace

int gltf_command(int argc, char** argv) {
  std::vector<std::string> inputs;
  std::string out;
  plm::SceneFileOptions options;
  options.keep_geometry = true;
  for (int i = 0; i < argc; ++i) {
    const std::string opt = argv[i];
    if (opt == "-o" || opt == "--out" || opt == "--max-file-mb") {
      if (i + 1 >= argc) return fail(kBadInput, "option " + opt + " needs a value");
      const std::string v = argv[++i];
      if (opt == "--max-file-mb") {
        const std::string e = parse_max_file_mb(v, options);
        if (!e.empty()) return fail(kBadInput, e);
      } else {
        out = v;
      }
    } else if (!opt.empty() && opt[0] == '-') {
      return fail(kBadInput, "unknown option " + opt);
    } else {
      inputs.push_back(opt);
    }
  }
  if (inputs.size() != 2 || out.empty())
    return fail(kBadInput, "usage: photonlm gltf SCENE.json BAKE_DIR -o FILE.glb");
  const auto t0 = std::chrono::steady_clock::now();
  const std::string& scene_path = inputs[0];
  const std::string dir = inputs[1] + "/";
  plm::SceneFile scene;
  std::string error;
  if (!read_scene(scene_path, options, scene, error)) return fail(kBadInput, error);
  nlohmann::json report;
  {
    std::ifstream in(dir + "report.json");
    if (!in) return fail(kBadInput, dir + "report.json: not found (is " + inputs[1] + " a photonlm bake folder?)");
    try {
      in >> report;
    } catch (const std::exception& e) {
      return fail(kBadInput, dir + "report.json: " + e.what());
    }
  }
  std::map<std::string, nlohmann::json> baked;  // mesh name -> its report entry
  for (const auto& m : report.value("meshes", nlohmann::json::array())) baked[m.value("name", "")] = m;

  Writer w;
  w.model.asset.version = "2.0";
  w.model.asset.generator = std::string("photonlm ") + plm_version();
  w.model.buffers.resize(1);
  w.model.scenes.resize(1);
  w.model.defaultScene = 0;
  size_t lightmaps = 0;
  std::vector<std::string> notes;
  for (const plm::SceneFileMesh& m : scene.meshes) {
    if (!m.geometry) {
      notes.push_back("'" + m.name + "': a subdivision cage (refined by the engine): not written");
      continue;
    }
    const auto& g = *m.geometry;
    const size_t tris = g.indices.size() / 3;
    // Per triangle corner (the UVs are per corner): Blender's z up to glTF's y up.
    std::vector<float> pos, normal, uv0, uv1;
    for (size_t t = 0; t < tris; ++t) {
      float p[3][3];
      for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 3; ++k) p[c][k] = g.positions[3 * size_t(g.indices[3 * t + c]) + size_t(k)];
      const float e1[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
      const float e2[3] = {p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
      float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
      const float len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      for (float& x : n) x = len > 0.0f ? x / len : 0.0f;
      if (len == 0.0f) n[2] = 1.0f;
      for (int c = 0; c < 3; ++c) {
        pos.insert(pos.end(), {p[c][0], p[c][2], -p[c][1]});
        normal.insert(normal.end(), {n[0], n[2], -n[1]});
        const std::vector<float>& t0 = g.texture_uv.empty() ? g.uv : g.texture_uv;
        if (!t0.empty()) uv0.insert(uv0.end(), {t0[6 * t + 2 * c], 1.0f - t0[6 * t + 2 * c + 1]});
        if (!g.uv.empty()) uv1.insert(uv1.end(), {g.uv[6 * t + 2 * c], 1.0f - g.uv[6 * t + 2 * c + 1]});
      }
    }
    // The lightmap and its layers, as the bake folder holds them.
    int texture = -1;
    double range = 1.0;
    Value::Array layers;
    Value sh_info;
    const auto entry = baked.find(m.name);
    if (m.width > 0 && entry != baked.end()) {
      texture = w.texture(dir + entry->second.value("file", ""), m.name + "_lightmap", range, error);
      if (texture < 0) return fail(kBadInput, error);
      for (const auto& layer : entry->second.value("layers", nlohmann::json::array())) {
        double layer_range = 1.0;
        const std::string group = layer.value("group", "");
        const int lt = w.texture(dir + layer.value("file", ""), m.name + "_lightmap." + group, layer_range, error);
        if (lt < 0) return fail(kBadInput, error);
        layers.push_back(Value(Value::Object{{"group", Value(group)},
                                             {"texture", Value(lt)},
                                             {"range", number(layer_range)},
                                             {"intensity", number(kPi * layer_range)},
                                             {"strength", number(1.0)},
                                             {"tint", Value(Value::Array{number(1.0), number(1.0), number(1.0)})}}));
      }
      // SH L1 bands (<mesh>_lightmap_sh1..3: along Blender's y, z, x) in glTF's axes, where
      // Blender's (x, y, z) is (x, -z, y): L1_-1 (glTF's y) is band 2, L1_0 (z) minus band 1, L1_1 band 3.
      const auto sh = entry->second.value("sh", nlohmann::json::array());
      if (sh.size() == 4) {
        Value::Array bands;
        for (const auto& [m_index, band, sign] : {std::tuple{-1, 2, 1}, std::tuple{0, 1, -1}, std::tuple{1, 3, 1}}) {
          double band_range = 1.0;
          const int bt = w.texture(dir + sh[size_t(band)].get<std::string>(),
                                   m.name + "_lightmap_L1_" + std::to_string(m_index), band_range, error, sign);
          if (bt < 0) return fail(kBadInput, error);
          bands.push_back(Value(Value::Object{{"m", Value(m_index)}, {"texture", Value(bt)}, {"range", number(band_range)}}));
        }
        sh_info = Value(Value::Object{{"layout", Value(std::string("Godot 4 SH L1"))},
                                      {"axes", Value(std::string("glTF (y up)"))},
                                      {"encoding", Value(std::string("RGBM_SIGNED"))},
                                      {"decode", Value(std::string("value = (2 * rgb - 1) * a * range"))},
                                      {"l0", Value(std::string("the lightmap's value / (2 * 0.282095)"))},
                                      {"evaluate", Value(std::string(
                                                       "0.282095 * L0 + 0.32573 * (L1_-1 * n.y + L1_0 * n.z + L1_1 * n.x)"))},
                                      {"bands", Value(bands)}});
      }
      ++lightmaps;
    } else if (m.width > 0) {
      notes.push_back("'" + m.name + "': no lightmap in the bake folder: written without one");
    }
    tinygltf::Mesh mesh;
    mesh.name = m.name;
    const int a_pos = w.accessor(pos, TINYGLTF_TYPE_VEC3, 3, true), a_n = w.accessor(normal, TINYGLTF_TYPE_VEC3, 3);
    const int a_uv0 = uv0.empty() ? -1 : w.accessor(uv0, TINYGLTF_TYPE_VEC2, 2);
    const int a_uv1 = uv1.empty() ? -1 : w.accessor(uv1, TINYGLTF_TYPE_VEC2, 2);
    // One primitive per material: its corners' indices into the mesh's corners.
    std::map<uint32_t, std::vector<uint32_t>> by_material;
    for (uint32_t t = 0; t < tris; ++t)
      for (uint32_t c = 0; c < 3; ++c) by_material[g.materials.empty() ? 0 : g.materials[t]].push_back(3 * t + c);
    for (const auto& [material, corners] : by_material) {
      tinygltf::Primitive prim;
      prim.mode = TINYGLTF_MODE_TRIANGLES;
      prim.attributes["POSITION"] = a_pos;
      prim.attributes["NORMAL"] = a_n;
      if (a_uv0 >= 0) prim.attributes["TEXCOORD_0"] = a_uv0;
      if (a_uv1 >= 0) prim.attributes["TEXCOORD_1"] = a_uv1;
      tinygltf::Accessor idx;
      idx.bufferView = w.view(corners.data(), corners.size() * 4, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
      idx.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
      idx.type = TINYGLTF_TYPE_SCALAR;
      idx.count = corners.size();
      w.model.accessors.push_back(idx);
      prim.indices = int(w.model.accessors.size() - 1);
      // A material per mesh and material: a lightmap belongs to a mesh.
      tinygltf::Material mat;
      const bool known = material < scene.material_albedo.size();
      mat.name = (known && !scene.material_names[material].empty() ? scene.material_names[material] : "material") +
                 "." + m.name;
      const auto albedo = known ? scene.material_albedo[material] : std::array<float, 3>{0.8f, 0.8f, 0.8f};
      mat.pbrMetallicRoughness.baseColorFactor = {albedo[0], albedo[1], albedo[2], 1.0};
      mat.pbrMetallicRoughness.metallicFactor = 0.0;
      mat.pbrMetallicRoughness.roughnessFactor = 1.0;
      if (texture >= 0) {
        const double intensity = kPi * range;
        mat.extensions["MOZ_lightmap"] =
            Value(Value::Object{{"index", Value(texture)}, {"texCoord", Value(1)}, {"intensity", number(intensity)}});
        mat.extensions["FB_materials_lightmap"] = Value(Value::Object{
            {"lightmapTexture", Value(Value::Object{{"index", Value(texture)}, {"texCoord", Value(1)}})},
            {"lightmapFactor", Value(Value::Array{number(intensity), number(intensity), number(intensity)})}});
        Value::Object lm{{"encoding", Value(std::string("RGBM"))},
                         {"range", number(range)},
                         {"colorSpace", Value(std::string("linear"))},
                         {"decode", Value(std::string("value = rgb * a * range"))},
                         {"units", Value(std::string("irradiance / pi"))},
                         {"intensity", number(intensity)},
                         {"texture", Value(texture)},
                         {"texCoord", Value(1)},
                         {"object", Value(m.name)},
                         {"image", Value(m.name + "_lightmap")}};
        if (!layers.empty()) lm["layers"] = Value(layers);
        if (sh_info.IsObject()) lm["sh"] = sh_info;
        mat.extras = Value(Value::Object{{"photonlm_lightmap", Value(lm)}});
      }
      w.model.materials.push_back(mat);
      prim.material = int(w.model.materials.size() - 1);
      mesh.primitives.push_back(prim);
    }
    w.model.meshes.push_back(mesh);
    tinygltf::Node node;
    node.name = m.name;
    node.mesh = int(w.model.meshes.size() - 1);
    w.model.nodes.push_back(node);
    w.model.scenes[0].nodes.push_back(int(w.model.nodes.size() - 1));
  }
  if (lightmaps == 0) return fail(kBadInput, inputs[1] + ": no lightmap of the scene's meshes in the bake folder");
  w.model.extensionsUsed = {"MOZ_lightmap", "FB_materials_lightmap"};
  tinygltf::TinyGLTF writer;
  const std::string tmp = out + ".tmp";
  if (!writer.WriteGltfSceneToFile(&w.model, tmp, false, true, false, true) || std::rename(tmp.c_str(), out.c_str()) != 0) {
    std::remove(tmp.c_str());
    return fail(kFailed, out + ": could not be written");
  }
  for (const std::string& n : notes) std::fprintf(stderr, "photonlm gltf: note: %s\n", n.c_str());
  std::printf("%s: %zu meshes, %zu lightmaps, %.2f s\n", out.c_str(), scene.meshes.size(), lightmaps,
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  return 0;
}

}  // namespace plm_cli

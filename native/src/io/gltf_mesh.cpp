// glTF geometry for the scene file (gltf_mesh.h). The only translation unit that compiles
// tinygltf's implementation; images are neither decoded nor read (only geometry is used).
#define TINYGLTF_IMPLEMENTATION
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include "gltf_mesh.h"

#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-parameter"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#endif
#include <tiny_gltf.h>
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

namespace plm {

namespace {

struct GltfError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

[[noreturn]] void fail(const std::string& message) { throw GltfError(message); }

std::string quoted_name(const std::string& name) { return name.empty() ? "" : " '" + name.substr(0, 60) + "'"; }

// 4x4 double matrix, column-major like glTF.
struct Mat4 {
  double m[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  Mat4 operator*(const Mat4& b) const {
    Mat4 r;
    for (int c = 0; c < 4; ++c)
      for (int row = 0; row < 4; ++row) {
        double s = 0;
        for (int k = 0; k < 4; ++k) s += m[k * 4 + row] * b.m[c * 4 + k];
        r.m[c * 4 + row] = s;
      }
    return r;
  }
  double det3() const {
    return m[0] * (m[5] * m[10] - m[9] * m[6]) - m[4] * (m[1] * m[10] - m[9] * m[2]) +
           m[8] * (m[1] * m[6] - m[5] * m[2]);
  }
};

bool finite_all(const std::vector<double>& v) {
  for (double x : v)
    if (!std::isfinite(x)) return false;
  return true;
}

Mat4 local_matrix(const tinygltf::Node& n, const std::string& what) {
  Mat4 r;
  if (!n.matrix.empty()) {
    if (n.matrix.size() != 16 || !finite_all(n.matrix)) fail(what + ": matrix must be 16 finite numbers");
    if (!n.translation.empty() || !n.rotation.empty() || !n.scale.empty())
      fail(what + ": has both a matrix and translation/rotation/scale");
    for (int i = 0; i < 16; ++i) r.m[i] = n.matrix[size_t(i)];
    return r;
  }
  double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
  if (!n.translation.empty()) {
    if (n.translation.size() != 3 || !finite_all(n.translation)) fail(what + ": translation must be 3 finite numbers");
    for (int i = 0; i < 3; ++i) t[i] = n.translation[size_t(i)];
  }
  if (!n.rotation.empty()) {
    if (n.rotation.size() != 4 || !finite_all(n.rotation)) fail(what + ": rotation must be 4 finite numbers");
    const double len = std::sqrt(n.rotation[0] * n.rotation[0] + n.rotation[1] * n.rotation[1] +
                                 n.rotation[2] * n.rotation[2] + n.rotation[3] * n.rotation[3]);
    if (!(len > 0)) fail(what + ": rotation is the zero quaternion");
    for (int i = 0; i < 4; ++i) q[i] = n.rotation[size_t(i)] / len;
  }
  if (!n.scale.empty()) {
    if (n.scale.size() != 3 || !finite_all(n.scale)) fail(what + ": scale must be 3 finite numbers");
    for (int i = 0; i < 3; ++i) s[i] = n.scale[size_t(i)];
  }
  const double x = q[0], y = q[1], z = q[2], w = q[3];
  const double R[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                          {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                          {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
  for (int c = 0; c < 3; ++c)
    for (int row = 0; row < 3; ++row) r.m[c * 4 + row] = R[row][c] * s[c];
  for (int row = 0; row < 3; ++row) r.m[12 + row] = t[row];
  return r;
}

const char* type_name(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR: return "SCALAR";
    case TINYGLTF_TYPE_VEC2: return "VEC2";
    case TINYGLTF_TYPE_VEC3: return "VEC3";
    case TINYGLTF_TYPE_VEC4: return "VEC4";
    default: return "a matrix type";
  }
}

// A checked view of an accessor's elements.
struct View {
  const unsigned char* data = nullptr;
  size_t stride = 0, count = 0;
  int component = 0;
  bool normalized = false;
};

View accessor_view(const tinygltf::Model& model, int index, const std::string& what, int type,
                   std::initializer_list<int> components, uint64_t max_count) {
  if (index < 0 || size_t(index) >= model.accessors.size())
    fail(what + ": accessor " + std::to_string(index) + " does not exist (the file has " +
         std::to_string(model.accessors.size()) + ")");
  const tinygltf::Accessor& a = model.accessors[size_t(index)];
  const std::string at = "accessor " + std::to_string(index) + quoted_name(a.name) + " (" + what + ")";
  if (a.sparse.isSparse) fail(at + ": sparse accessors are not supported");
  if (a.type != type) fail(at + ": type is " + type_name(a.type) + ", expected " + type_name(type));
  bool ok = false;
  for (int c : components) ok = ok || a.componentType == c;
  if (!ok) fail(at + ": component type " + std::to_string(a.componentType) + " is not allowed here");
  if (a.count > max_count)
    fail(at + ": " + std::to_string(a.count) + " elements exceed the limit of " + std::to_string(max_count));
  if (a.bufferView < 0) fail(at + ": has no bufferView (all zeros); not supported");
  if (size_t(a.bufferView) >= model.bufferViews.size())
    fail(at + ": bufferView " + std::to_string(a.bufferView) + " does not exist");
  const tinygltf::BufferView& bv = model.bufferViews[size_t(a.bufferView)];
  if (bv.buffer < 0 || size_t(bv.buffer) >= model.buffers.size())
    fail(at + ": bufferView " + std::to_string(a.bufferView) + " names buffer " + std::to_string(bv.buffer) +
         ", which does not exist");
  const std::vector<unsigned char>& buf = model.buffers[size_t(bv.buffer)].data;
  if (uint64_t(bv.byteOffset) + uint64_t(bv.byteLength) > buf.size())
    fail(at + ": bufferView " + std::to_string(a.bufferView) + " (bytes " + std::to_string(bv.byteOffset) + " + " +
         std::to_string(bv.byteLength) + ") runs past the end of buffer " + std::to_string(bv.buffer) + " (" +
         std::to_string(buf.size()) + " bytes)");
  const int stride = a.ByteStride(bv);
  if (stride <= 0) fail(at + ": invalid byteStride " + std::to_string(bv.byteStride));
  const uint64_t elem = uint64_t(tinygltf::GetComponentSizeInBytes(uint32_t(a.componentType))) *
                        uint64_t(tinygltf::GetNumComponentsInType(uint32_t(a.type)));
  if (uint64_t(stride) < elem) fail(at + ": byteStride " + std::to_string(stride) + " is smaller than an element");
  if (a.count > 0 && uint64_t(a.byteOffset) + uint64_t(stride) * (a.count - 1) + elem > bv.byteLength)
    fail(at + ": " + std::to_string(a.count) + " elements from byte " + std::to_string(a.byteOffset) +
         " run past the end of bufferView " + std::to_string(a.bufferView) + " (" + std::to_string(bv.byteLength) +
         " bytes)");
  View v;
  v.data = buf.data() + bv.byteOffset + a.byteOffset;
  v.stride = size_t(stride);
  v.count = a.count;
  v.component = a.componentType;
  v.normalized = a.normalized;
  return v;
}

float read_float(const View& v, size_t i, int c) {
  const unsigned char* p = v.data + i * v.stride;
  switch (v.component) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
      float f;
      std::memcpy(&f, p + 4 * c, 4);
      return f;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return float(p[c]) / 255.0f;
    default: {  // UNSIGNED_SHORT
      uint16_t s;
      std::memcpy(&s, p + 2 * c, 2);
      return float(s) / 65535.0f;
    }
  }
}

uint32_t read_index(const View& v, size_t i) {
  const unsigned char* p = v.data + i * v.stride;
  switch (v.component) {
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return p[0];
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t s;
      std::memcpy(&s, p, 2);
      return s;
    }
    default: {
      uint32_t u;
      std::memcpy(&u, p, 4);
      return u;
    }
  }
}

struct Builder {
  const tinygltf::Model& model;
  const GltfLimits& limits;
  uint32_t texcoord;
  bool want_uv;
  GltfMeshData& out;
  std::vector<char> visited;

  void add_mesh(int mesh_index, const Mat4& m) {
    const tinygltf::Mesh& mesh = model.meshes[size_t(mesh_index)];
    const bool mirror = m.det3() < 0;
    const std::string attr_uv = "TEXCOORD_" + std::to_string(texcoord);
    for (size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
      const tinygltf::Primitive& prim = mesh.primitives[pi];
      const std::string what = "mesh " + std::to_string(mesh_index) + quoted_name(mesh.name) + " primitive " +
                               std::to_string(pi);
      if (prim.mode != -1 && prim.mode != TINYGLTF_MODE_TRIANGLES) {
        static const char* modes[] = {"POINTS", "LINES", "LINE_LOOP", "LINE_STRIP", "TRIANGLES", "TRIANGLE_STRIP",
                                      "TRIANGLE_FAN"};
        fail(what + ": mode " + std::to_string(prim.mode) +
             (prim.mode >= 0 && prim.mode <= 6 ? std::string(" (") + modes[prim.mode] + ")" : std::string()) +
             " is not supported: only triangles (mode 4)");
      }
      auto pos_it = prim.attributes.find("POSITION");
      if (pos_it == prim.attributes.end()) fail(what + ": has no POSITION attribute");
      const View pos = accessor_view(model, pos_it->second, what + " POSITION", TINYGLTF_TYPE_VEC3,
                                     {TINYGLTF_COMPONENT_TYPE_FLOAT}, limits.max_vertices);
      View uv;
      if (want_uv) {
        auto uv_it = prim.attributes.find(attr_uv);
        if (uv_it == prim.attributes.end())
          fail(what + ": has no " + attr_uv + " attribute (the lightmap UV; choose another with gltf_texcoord)");
        uv = accessor_view(model, uv_it->second, what + " " + attr_uv, TINYGLTF_TYPE_VEC2,
                           {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                            TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT},
                           limits.max_vertices);
        if (uv.component != TINYGLTF_COMPONENT_TYPE_FLOAT && !uv.normalized)
          fail(what + " " + attr_uv + ": integer texture coordinates must be normalized");
        if (uv.count != pos.count)
          fail(what + ": " + attr_uv + " has " + std::to_string(uv.count) + " elements, POSITION " +
               std::to_string(pos.count));
      }
      const size_t base = out.positions.size() / 3;
      if (base + pos.count > limits.max_vertices)
        fail(what + ": more than " + std::to_string(limits.max_vertices) + " vertices in all");
      for (size_t i = 0; i < pos.count; ++i) {
        const double p[3] = {read_float(pos, i, 0), read_float(pos, i, 1), read_float(pos, i, 2)};
        for (int r = 0; r < 3; ++r) {
          const double x = m.m[r] * p[0] + m.m[4 + r] * p[1] + m.m[8 + r] * p[2] + m.m[12 + r];
          if (!std::isfinite(x) || std::fabs(x) > 3.4e38)
            fail(what + " POSITION[" + std::to_string(i) + "]: not a finite 32-bit float (after the node transform)");
          out.positions.push_back(float(x));
        }
      }
      std::vector<uint32_t> idx;
      if (prim.indices >= 0) {
        const View iv = accessor_view(
            model, prim.indices, what + " indices", TINYGLTF_TYPE_SCALAR,
            {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
             TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT},
            uint64_t(limits.max_triangles) * 3);
        idx.resize(iv.count);
        for (size_t i = 0; i < iv.count; ++i) {
          idx[i] = read_index(iv, i);
          if (idx[i] >= pos.count)
            fail(what + " indices (accessor " + std::to_string(prim.indices) + ") element " + std::to_string(i) +
                 ": vertex " + std::to_string(idx[i]) + " is out of range (POSITION has " +
                 std::to_string(pos.count) + ")");
        }
      } else {
        idx.resize(pos.count);
        for (size_t i = 0; i < idx.size(); ++i) idx[i] = uint32_t(i);
      }
      if (idx.size() % 3)
        fail(what + ": " + std::to_string(idx.size()) + " indices are not a whole number of triangles");
      if (out.indices.size() / 3 + idx.size() / 3 > limits.max_triangles)
        fail(what + ": more than " + std::to_string(limits.max_triangles) + " triangles in all");
      for (size_t t = 0; t < idx.size(); t += 3) {
        const uint32_t corner[3] = {idx[t], mirror ? idx[t + 2] : idx[t + 1], mirror ? idx[t + 1] : idx[t + 2]};
        for (uint32_t c : corner) {
          out.indices.push_back(uint32_t(base) + c);
          if (want_uv) {
            out.uv.push_back(read_float(uv, c, 0));
            out.uv.push_back(1.0f - read_float(uv, c, 1));
          }
        }
      }
    }
  }

  void add_node(int index, const Mat4& parent, uint32_t depth) {
    if (index < 0 || size_t(index) >= model.nodes.size())
      fail("node " + std::to_string(index) + " does not exist (the file has " + std::to_string(model.nodes.size()) +
           ")");
    const tinygltf::Node& n = model.nodes[size_t(index)];
    const std::string what = "node " + std::to_string(index) + quoted_name(n.name);
    if (depth > limits.max_depth) fail(what + ": nodes nest deeper than " + std::to_string(limits.max_depth));
    if (visited[size_t(index)]) fail(what + ": reached twice (glTF nodes must form trees)");
    visited[size_t(index)] = 1;
    const Mat4 m = parent * local_matrix(n, what);
    if (n.mesh >= 0) {
      if (size_t(n.mesh) >= model.meshes.size())
        fail(what + ": mesh " + std::to_string(n.mesh) + " does not exist (the file has " +
             std::to_string(model.meshes.size()) + ")");
      add_mesh(n.mesh, m);
    }
    for (int c : n.children) add_node(c, m, depth + 1);
  }
};

template <typename T>
int64_t find_named(const std::vector<T>& items, const GltfSelection& s, const char* what) {
  if (s.index >= 0) {
    if (size_t(s.index) >= items.size())
      fail(std::string(what) + " " + std::to_string(s.index) + " does not exist (the file has " +
           std::to_string(items.size()) + ")");
    return s.index;
  }
  int64_t found = -1;
  for (size_t i = 0; i < items.size(); ++i) {
    if (items[i].name != s.name) continue;
    if (found >= 0) fail(std::string("several ") + what + "s are named '" + s.name + "': use the index");
    found = int64_t(i);
  }
  if (found < 0) fail(std::string("no ") + what + " is named '" + s.name + "'");
  return found;
}

bool noop_image_loader(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int,
                       void*) {
  return true;  // images are not needed
}

}  // namespace

bool read_gltf_mesh(const std::string& file, const GltfSelection& selection, uint32_t texcoord, bool want_uv,
                    const GltfLimits& limits, GltfMeshData& out, std::string& error) {
  out = GltfMeshData{};
  try {
    FILE* f = std::fopen(file.c_str(), "rb");
    if (!f) {
      error = file + ": cannot open: " + std::strerror(errno);
      return false;
    }
    std::vector<unsigned char> bytes;
    unsigned char buf[65536];
    size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) {
      if (bytes.size() + n > limits.max_file_bytes) {
        std::fclose(f);
        error = file + ": the file is larger than the limit of " + std::to_string(limits.max_file_bytes) + " bytes";
        return false;
      }
      bytes.insert(bytes.end(), buf, buf + n);
    }
    std::fclose(f);
    tinygltf::Model model;
    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(noop_image_loader, nullptr);
    std::string err, warn;
    const size_t slash = file.find_last_of('/');
    const std::string dir = slash == std::string::npos ? "." : file.substr(0, slash);
    const bool binary = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
    const bool ok = binary ? loader.LoadBinaryFromMemory(&model, &err, &warn, bytes.data(),
                                                         unsigned(bytes.size()), dir)
                           : loader.LoadASCIIFromString(&model, &err, &warn, reinterpret_cast<const char*>(bytes.data()),
                                                        unsigned(bytes.size()), dir);
    if (!ok) {
      while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
      for (char& c : err)
        if (c == '\n') c = ';';
      error = file + ": not a readable glTF 2.0 file: " + (err.empty() ? "unknown error" : err);
      return false;
    }
    Builder b{model, limits, texcoord, want_uv, out, std::vector<char>(model.nodes.size(), 0)};
    if (selection.kind == GltfSelection::kMesh) {
      b.add_mesh(int(find_named(model.meshes, selection, "mesh")), Mat4{});
    } else if (selection.kind == GltfSelection::kNode) {
      const int64_t node = find_named(model.nodes, selection, "node");
      // The node's world transform: its ancestors' transforms too.
      std::vector<int> parent(model.nodes.size(), -1);
      for (size_t i = 0; i < model.nodes.size(); ++i)
        for (int c : model.nodes[i].children)
          if (c >= 0 && size_t(c) < parent.size()) parent[size_t(c)] = int(i);
      std::vector<int> chain;
      for (int p = parent[size_t(node)]; p >= 0; p = parent[size_t(p)]) {
        if (chain.size() > limits.max_depth) fail("the ancestors of node " + std::to_string(node) + " form a cycle");
        chain.push_back(p);
      }
      Mat4 m;
      for (size_t k = chain.size(); k-- > 0;)
        m = m * local_matrix(model.nodes[size_t(chain[k])], "node " + std::to_string(chain[k]));
      b.add_node(int(node), m, 0);
    } else {
      std::vector<int> roots;
      if (!model.scenes.empty()) {
        const int s = model.defaultScene >= 0 ? model.defaultScene : 0;
        if (size_t(s) >= model.scenes.size()) fail("the default scene " + std::to_string(s) + " does not exist");
        roots = model.scenes[size_t(s)].nodes;
      } else {
        std::vector<char> is_child(model.nodes.size(), 0);
        for (const tinygltf::Node& nd : model.nodes)
          for (int c : nd.children)
            if (c >= 0 && size_t(c) < is_child.size()) is_child[size_t(c)] = 1;
        for (size_t i = 0; i < model.nodes.size(); ++i)
          if (!is_child[i]) roots.push_back(int(i));
      }
      for (int r : roots) b.add_node(r, Mat4{}, 0);
    }
    if (out.indices.empty())
      fail(selection.kind == GltfSelection::kMesh ? "the mesh has no triangles"
                                                  : "no triangles (no node with a mesh; name one with gltf_mesh)");
    return true;
  } catch (const GltfError& e) {
    error = file + ": " + e.what();
  } catch (const std::bad_alloc&) {
    error = file + ": out of memory";
  } catch (const std::exception& e) {
    error = file + ": " + e.what();
  }
  return false;
}

}  // namespace plm

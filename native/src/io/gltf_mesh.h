// Triangle meshes from glTF 2.0 files (.gltf with external or embedded buffers, or .glb) for
// the scene file's "gltf" mesh references (docs/scene-file.md), read with tinygltf. Only
// geometry is read: POSITION, indices (unsigned byte/short/int, or none), one TEXCOORD_n as the
// lightmap UV, node transforms; triangles only. Materials, images, normals, skins, morph
// targets and animations are ignored. Every error names the glTF object (node, mesh,
// primitive, accessor) by index and name.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace plm {

struct GltfSelection {
  enum Kind { kScene, kMesh, kNode } kind = kScene;  // the default scene / one mesh / one node's subtree
  int64_t index = -1;  // the mesh or node index, or -1 to look it up by name
  std::string name;
};

struct GltfMeshData {
  std::vector<float> positions;  // x, y, z per vertex, transformed to the scene's space
  std::vector<uint32_t> indices;  // 3 per triangle, counter-clockwise (mirroring transforms are undone)
  std::vector<float> uv;          // u, v per triangle corner (v = 1 - glTF's v), only if wanted
};

struct GltfLimits {
  uint64_t max_file_bytes;
  uint32_t max_vertices, max_triangles, max_depth;
};

// Reads a glTF file. texcoord: n of TEXCOORD_n, the lightmap UV; want_uv: the mesh has a
// lightmap (so the attribute must exist). Returns false with error set ("<file>: mesh 0
// 'Cube' primitive 1: ...") on any failure.
[[nodiscard]] bool read_gltf_mesh(const std::string& file, const GltfSelection& selection, uint32_t texcoord,
                                  bool want_uv, const GltfLimits& limits, GltfMeshData& out, std::string& error);

}  // namespace plm

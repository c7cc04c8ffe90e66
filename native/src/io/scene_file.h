// The JSON scene file (docs/scene-file.md): materials, meshes (inline, OBJ or glTF
// files), lights, world, CSG solids, OL groups and bake settings, read into a
// plm_scene through the public C API only. Every error names the JSON path of
// the offending value ("scene.meshes[2].positions[7]: expected a number, got
// \"abc\""), a file and line for OBJ files, or the path of the object the
// engine refused. No input crashes the reader (native/fuzz/fuzz_scene_file.cpp).
#pragma once

#include <cstdint>
#include <array>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "photonlm/photonlm.h"

namespace plm {

// Bounds on what a file may ask for, checked before anything is allocated for it.
struct SceneFileLimits {
  uint64_t max_file_bytes = uint64_t(256) << 20;  // scene and OBJ files
  uint32_t max_vertices = 1u << 24;               // per mesh
  uint32_t max_triangles = 1u << 24;              // per mesh
  uint32_t max_items = 65536;  // materials, meshes, lights, OL groups, CSG solids, CSG primitives/nodes
  uint32_t max_depth = 64;     // JSON nesting
};

struct SceneFileOptions {
  SceneFileLimits limits;
  // Folder that OBJ paths are relative to; "" = the current folder.
  std::string base_dir;
  // false: an "obj" reference is an error (the fuzzer reads no files).
  bool allow_file_access = true;
  // Keep each mesh's triangles as given to the engine (SceneFileMesh::geometry;
  // `photonlm gltf` writes them); subdivision cages, refined by the engine, keep none.
  bool keep_geometry = false;
};

struct SceneFileMesh {
  std::string name;
  uint32_t id = 0;                   // plm mesh id
  uint32_t width = 0, height = 0;    // lightmap size; 0 x 0 = geometry only
  int32_t ol_group = -1;             // index into SceneFile::ol_groups, or -1
  // With SceneFileOptions::keep_geometry: the triangles as given to the engine.
  struct Geometry {
    std::vector<float> positions;       // 3 per vertex
    std::vector<uint32_t> indices;      // 3 per triangle
    std::vector<float> uv, texture_uv;  // 6 per triangle each, or empty
    std::vector<uint32_t> materials;    // 1 per triangle, or empty (material 0 or the engine's grey)
  };
  std::shared_ptr<const Geometry> geometry;  // null: not kept (or a subdivision cage)
};

struct SceneFileOlGroup {
  std::string name;
  uint32_t id = 0;          // plm OL group id
  uint32_t resolution = 0;  // as in the file (0 = automatic)
};

// A scene read from a file. Owns the scene handle.
class SceneFile {
 public:
  SceneFile();
  ~SceneFile();
  SceneFile(const SceneFile&) = delete;
  SceneFile& operator=(const SceneFile&) = delete;

  plm_scene* scene = nullptr;
  plm_bake_settings settings{};  // the file's settings over plm_bake_settings_default
  std::vector<SceneFileMesh> meshes;
  std::vector<SceneFileOlGroup> ol_groups;
  std::vector<std::string> material_names;  // "" for unnamed materials
  std::vector<std::array<float, 3>> material_albedo;
};

// Reads the JSON text of a scene file. On failure returns false, sets error
// and leaves out in an unspecified (but releasable) state.
[[nodiscard]] bool parse_scene_file_text(std::string_view text, const SceneFileOptions& options, SceneFile& out,
                                         std::string& error);

// Reads a scene file; OBJ paths are relative to the file's folder
// (options.base_dir is ignored). Errors name the file.
[[nodiscard]] bool read_scene_file(const std::string& path, const SceneFileOptions& options, SceneFile& out,
                                   std::string& error);

// Names used by the file format and the bake report.
const char* texel_value_name(uint32_t value);  // "CYCLES", "AREA" or "?"
const char* sampler_name(uint32_t value);      // "DEFAULT", "RANDOM", "SOBOL" or "?"

}  // namespace plm

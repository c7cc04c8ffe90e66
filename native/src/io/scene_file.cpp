// JSON scene file reader (docs/scene-file.md). Only the public C API builds
// the scene, so the CLI can compile this file against the shared library.
#include "scene_file.h"

#include <cmath>
#include <cstdlib>
#include <limits>

#include "io/gltf_mesh.h"
#include "io/json_input.h"
#include "io/obj_mesh.h"

namespace plm {

namespace {

using namespace scene_input;

void engine(plm_status s, const std::string& path) {
  if (s != PLM_OK) fail(path, plm_last_error());
}

// ---- scene -----------------------------------------------------------------

struct Reader {
  const SceneFileOptions& options;
  SceneFile& out;
  std::vector<std::string> mesh_names, ol_names, light_group_names;

  void materials(const json& v, const std::string& path) {
    array(v, path, options.limits.max_items, "materials");
    for (size_t i = 0; i < v.size(); ++i) {
      const std::string p = index_path(path, i);
      const json& m = object(v[i], p);
      check_keys(m, p, {"name", "albedo", "emission", "albedo_texture", "emission_texture", "lobes", "burley_roughness"});
      const std::string name = name_or(m, p, "");
      float albedo[3] = {0.8f, 0.8f, 0.8f}, emission[3] = {0, 0, 0};
      if (const json* a = optional(m, "albedo")) rgb(*a, p + ".albedo", albedo);
      if (const json* e = optional(m, "emission")) rgb(*e, p + ".emission", emission);
      uint32_t id = 0;
      engine(plm_scene_add_material(out.scene, name.empty() ? nullptr : name.c_str(), albedo, emission, &id), p);
      out.material_albedo.push_back({albedo[0], albedo[1], albedo[2]});
      if (const json* t = optional(m, "albedo_texture")) texture(*t, p + ".albedo_texture", id, PLM_TEXTURE_ALBEDO);
      if (const json* t = optional(m, "emission_texture"))
        texture(*t, p + ".emission_texture", id, PLM_TEXTURE_EMISSION);
      if (const json* l = optional(m, "lobes")) lobes(*l, p + ".lobes", id);
      // "burley_roughness": the diffuse part is Burley's (Blender 3.x's Principled BSDF) of that roughness.
      if (const json* r = optional(m, "burley_roughness"))
        engine(plm_scene_set_material_diffuse(out.scene, id, PLM_DIFFUSE_BURLEY,
                                              float(number(*r, p + ".burley_roughness"))),
               p + ".burley_roughness");
      out.material_names.push_back(name);
    }
  }

  // [{"type": "glass", "color": [r, g, b], "weight": 1, "roughness": 0, "ior": 1.45, "abbe": 0}, ...];
  // all but "type" optional, with plm_lobe_default's values.
  void lobes(const json& v, const std::string& path, uint32_t material) {
    array(v, path, 8, "lobes");
    for (size_t i = 0; i < v.size(); ++i) {
      const std::string p = index_path(path, i);
      const json& l = object(v[i], p);
      check_keys(l, p, {"type", "color", "weight", "roughness", "ior", "abbe"});
      const uint32_t type =
          enum_value(required(l, p, "type"), p + ".type", {"glossy", "fresnel", "glass", "refraction", "transparent", "specular"});
      plm_lobe lobe;
      plm_lobe_default(&lobe, plm_lobe_type(type));
      if (const json* c = optional(l, "color")) rgb(*c, p + ".color", lobe.color);
      if (const json* x = optional(l, "weight")) lobe.weight = to_float(*x, p + ".weight");
      if (const json* x = optional(l, "roughness")) lobe.roughness = to_float(*x, p + ".roughness");
      if (const json* x = optional(l, "ior")) lobe.ior = to_float(*x, p + ".ior");
      if (const json* x = optional(l, "abbe")) lobe.abbe = to_float(*x, p + ".abbe");
      engine(plm_scene_add_material_lobe(out.scene, material, &lobe), p);
    }
  }

  // "file.png" or {"path": "file.png", "colorspace": "auto" | "linear" | "srgb"}; relative to the scene file.
  void texture(const json& v, const std::string& p, uint32_t material, plm_texture_slot slot) {
    std::string rel, space = "auto";
    if (v.is_object()) {
      check_keys(v, p, {"path", "colorspace"});
      rel = string(required(v, p, "path"), p + ".path");
      if (const json* c = optional(v, "colorspace")) space = string(*c, p + ".colorspace");
    } else if (v.is_string()) {
      rel = v.get_ref<const std::string&>();
    } else {
      expected(p, "a file name or an object {\"path\", \"colorspace\"}", v);
    }
    uint32_t flags = PLM_TEXTURE_COLOR_AUTO;
    if (space == "linear") flags = PLM_TEXTURE_COLOR_LINEAR;
    else if (space == "srgb") flags = PLM_TEXTURE_COLOR_SRGB;
    else if (space != "auto") fail(p + ".colorspace", "\"" + space + "\" is not one of auto, linear, srgb");
    if (!options.allow_file_access) fail(p, "file access is disabled");
    if (rel.empty()) fail(p, "empty file name");
    const std::string file = rel[0] == '/' || options.base_dir.empty() ? rel : options.base_dir + "/" + rel;
    engine(plm_scene_set_material_texture(out.scene, material, slot, file.c_str(), flags), p);
  }

  void ol_groups(const json& v, const std::string& path) {
    array(v, path, options.limits.max_items, "OL groups");
    for (size_t i = 0; i < v.size(); ++i) {
      const std::string p = index_path(path, i);
      const json& g = object(v[i], p);
      check_keys(g, p, {"name", "resolution", "backup", "limit_area"});
      const std::string name = name_or(g, p, "ol" + std::to_string(i));
      uint32_t resolution = 0;
      if (const json* r = optional(g, "resolution")) resolution = u32(*r, p + ".resolution", 1024);
      uint32_t id = 0;
      engine(plm_scene_add_ol_group(out.scene, name.c_str(), resolution, &id), p);
      if (const json* b = optional(g, "backup")) {
        if (!b->is_boolean()) expected(p + ".backup", "true or false", *b);
        engine(plm_scene_set_ol_group_backup(out.scene, id, b->get<bool>() ? 1 : 0), p + ".backup");
      }
      if (const json* b = optional(g, "limit_area")) {
        if (!b->is_boolean()) expected(p + ".limit_area", "true or false", *b);
        engine(plm_scene_set_ol_group_limit_area(out.scene, id, b->get<bool>() ? 1 : 0), p + ".limit_area");
      }
      out.ol_groups.push_back({name, id, resolution});
      ol_names.push_back(name);
    }
  }

  // "light_groups": ["day", "night"]: the groups lights, meshes' emission and the world name by "group".
  void light_groups(const json& v, const std::string& path) {
    array(v, path, options.limits.max_items, "light groups");
    for (size_t i = 0; i < v.size(); ++i) {
      const std::string name = string(v[i], index_path(path, i));
      uint32_t id = 0;
      engine(plm_scene_add_light_group(out.scene, name.c_str(), &id), index_path(path, i));
      light_group_names.push_back(name);
    }
  }

  // The engine id of the light group that obj's "group" names (0: none given).
  uint32_t light_group(const json& obj, const std::string& path) {
    const json* g = optional(obj, "group");
    return g ? reference(*g, path + ".group", light_group_names, "scene.light_groups") + 1 : 0;
  }

  void resolution(const json& v, const std::string& path, uint32_t& w, uint32_t& h) {
    if (v.is_array()) {
      if (v.size() != 2) fail(path, "expected N or [width, height], got an array of " + std::to_string(v.size()));
      w = u32(v[0], index_path(path, 0), 16384);
      h = u32(v[1], index_path(path, 1), 16384);
    } else {
      if (!v.is_number()) expected(path, "N or [width, height]", v);
      w = h = u32(v, path, 16384);
    }
    if ((w == 0) != (h == 0)) fail(path, "width and height must both be 0 (no lightmap) or both > 0");
  }

  // A mesh's "lightmap_uv", 2 numbers per corner: required with a lightmap, refused without one.
  // `per` completes "expected 2 numbers (u, v) per " for a wrong count.
  std::vector<float> lightmap_uv(const json& m, const std::string& p, bool lightmap, size_t corners,
                                 const std::string& per) {
    const json* ju = optional(m, "lightmap_uv");
    const std::string pu = p + ".lightmap_uv";
    if (lightmap && !ju) fail(p, "missing field \"lightmap_uv\" (needed for a lightmap_resolution above 0)");
    if (!lightmap && ju) fail(pu, "given, but the mesh has no lightmap (set lightmap_resolution)");
    std::vector<float> uv;
    if (!ju) return uv;
    array(*ju, pu, uint64_t(options.limits.max_triangles) * 6, "numbers");
    if (ju->size() != corners * 2)
      fail(pu, "expected 2 numbers (u, v) per " + per + ", got " + std::to_string(ju->size()));
    uv.resize(ju->size());
    for (size_t k = 0; k < ju->size(); ++k) uv[k] = to_float((*ju)[k], index_path(pu, k));
    return uv;
  }

  // A Catmull-Clark cage: inline "positions", "indices" = the polygons' vertex indices one face
  // after another, "subdivision": {"level": n, "face_sizes": [...] (default: all quads),
  // "creases": [[v0, v1, crease], ...]}, "lightmap_uv" per face corner, "materials" per face.
  // A mesh's "smooth" flag and, for inline meshes (triangles > 0), its "normals".
  void shading(const json& m, const std::string& p, uint32_t id, size_t triangles) {
    const SceneFileLimits& lim = options.limits;
    if (const json* jn = optional(m, "normals")) {
      const std::string pn = p + ".normals";
      if (optional(m, "obj") || optional(m, "gltf")) fail(pn, "only allowed for inline meshes (positions, indices)");
      if (optional(m, "smooth")) fail(pn, "give either \"normals\" or \"smooth\", not both");
      array(*jn, pn, uint64_t(lim.max_triangles) * 9, "numbers");
      if (jn->size() != triangles * 9)
        fail(pn, "expected 3 numbers (x, y, z) per triangle corner: " + std::to_string(triangles * 9) + " for " +
                     std::to_string(triangles) + " triangles, got " + std::to_string(jn->size()));
      std::vector<float> normals(jn->size());
      for (size_t k = 0; k < jn->size(); ++k) normals[k] = to_float((*jn)[k], index_path(pn, k));
      engine(plm_scene_set_mesh_normals(out.scene, id, normals.data()), pn);
    }
    if (const json* js = optional(m, "smooth")) {
      if (!js->is_boolean()) expected(p + ".smooth", "true or false", *js);
      engine(plm_scene_set_mesh_smooth(out.scene, id, js->get<bool>() ? 1 : 0), p + ".smooth");
    }
  }

  uint32_t subdivision_mesh(const json& m, const json& sd, const std::string& p, const SceneFileMesh& info,
                            bool lightmap, const uint32_t* one_material, const json* per_face) {
    const SceneFileLimits& lim = options.limits;
    const std::string ps = p + ".subdivision";
    object(sd, ps);
    check_keys(sd, ps, {"level", "face_sizes", "creases"});
    for (const char* k : {"obj", "gltf", "gltf_mesh", "gltf_node", "gltf_texcoord", "texture_uv", "normals"})
      if (optional(m, k)) fail(p + "." + k, "not allowed together with \"subdivision\" (give the cage inline)");
    const uint32_t level = uint32_t(integer(required(sd, ps, "level"), ps + ".level", 10));
    if (level < 1) fail(ps + ".level", "must be in [1, 10]");
    const std::string pp = p + ".positions", pi = p + ".indices";
    const json& jp = array(required(m, p, "positions"), pp, uint64_t(lim.max_vertices) * 3, "numbers");
    if (jp.size() % 3) fail(pp, "expected 3 numbers per vertex, got " + std::to_string(jp.size()) + " numbers");
    std::vector<float> positions(jp.size());
    for (size_t k = 0; k < jp.size(); ++k) positions[k] = to_float(jp[k], index_path(pp, k));
    const size_t vertex_count = positions.size() / 3;
    const json& ji = array(required(m, p, "indices"), pi, uint64_t(lim.max_triangles) * 3, "indices");
    const std::vector<uint32_t> indices = vertex_indices(ji, pi, vertex_count);
    std::vector<uint32_t> sizes;
    if (const json* jf = optional(sd, "face_sizes")) {
      const std::string pf = ps + ".face_sizes";
      array(*jf, pf, uint64_t(lim.max_triangles), "numbers");
      uint64_t total = 0;
      for (size_t k = 0; k < jf->size(); ++k) {
        const uint64_t n = integer((*jf)[k], index_path(pf, k), 1u << 16);
        if (n < 3) fail(index_path(pf, k), "a face needs at least 3 vertices, got " + std::to_string(n));
        sizes.push_back(uint32_t(n));
        total += n;
      }
      if (total != indices.size())
        fail(pf, "the face sizes add up to " + std::to_string(total) + " but \"indices\" has " +
                     std::to_string(indices.size()) + " entries");
    } else {
      if (indices.size() % 4)
        fail(pi, "without \"face_sizes\" every face is a quad: expected a multiple of 4 indices, got " +
                     std::to_string(indices.size()));
      sizes.assign(indices.size() / 4, 4u);
    }
    if (sizes.empty()) fail(pi, "a subdivision cage needs at least one face");
    std::vector<uint32_t> crease_edges;
    std::vector<float> crease_weights;
    if (const json* jc = optional(sd, "creases")) {
      const std::string pc = ps + ".creases";
      array(*jc, pc, uint64_t(lim.max_triangles), "creases");
      for (size_t k = 0; k < jc->size(); ++k) {
        const std::string pk = index_path(pc, k);
        const json& c = array((*jc)[k], pk, 3, "numbers");
        if (c.size() != 3) fail(pk, "expected [vertex, vertex, crease]");
        for (int e = 0; e < 2; ++e) {
          const uint64_t x = integer(c[size_t(e)], index_path(pk, size_t(e)), std::numeric_limits<uint32_t>::max());
          if (x >= vertex_count)
            fail(index_path(pk, size_t(e)), "vertex index " + std::to_string(x) + " is out of range (the mesh has " +
                                                std::to_string(vertex_count) + " vertices)");
          crease_edges.push_back(uint32_t(x));
        }
        const float w = to_float(c[2], index_path(pk, 2));
        if (!(w >= 0.0f && w <= 1.0f)) fail(index_path(pk, 2), "a crease is in [0, 1]");
        crease_weights.push_back(w);
      }
    }
    const std::vector<float> uv =
        lightmap_uv(m, p, lightmap, indices.size(), "face corner: " + std::to_string(indices.size() * 2));
    std::vector<uint32_t> mats;
    if (per_face) {
      const std::string pm = p + ".materials";
      array(*per_face, pm, lim.max_triangles, "materials");
      if (per_face->size() != sizes.size())
        fail(pm, "expected one material per face: " + std::to_string(sizes.size()) + ", got " +
                     std::to_string(per_face->size()));
      for (size_t k = 0; k < sizes.size(); ++k)
        mats.push_back(reference((*per_face)[k], index_path(pm, k), out.material_names, "scene.materials"));
    } else if (one_material) {
      mats.assign(sizes.size(), *one_material);
    }
    uint32_t id = 0;
    engine(plm_scene_add_subdiv_mesh(out.scene, info.name.c_str(), positions.data(), uint32_t(vertex_count),
                                     sizes.data(), uint32_t(sizes.size()), indices.data(),
                                     lightmap ? uv.data() : nullptr, mats.empty() ? nullptr : mats.data(),
                                     crease_edges.empty() ? nullptr : crease_edges.data(),
                                     crease_weights.empty() ? nullptr : crease_weights.data(),
                                     uint32_t(crease_weights.size()), level, info.width, info.height, &id),
           p);
    return id;
  }

  // A "gltf" mesh reference: the default scene, one mesh ("gltf_mesh") or one node's subtree
  // ("gltf_node"), each by index or name; "gltf_texcoord" n: TEXCOORD_n is the lightmap UV.
  void gltf_mesh(const json& m, const json& file_field, const std::string& p, bool lightmap,
                 std::vector<float>& positions, std::vector<uint32_t>& indices, std::vector<float>& uv) {
    for (const char* k : {"positions", "indices", "lightmap_uv", "materials", "obj"})
      if (optional(m, k)) fail(p + "." + k, "not allowed together with \"gltf\" (the glTF file gives the geometry)");
    const std::string& rel = string(file_field, p + ".gltf");
    if (!options.allow_file_access) fail(p + ".gltf", "file access is disabled");
    if (rel.empty()) fail(p + ".gltf", "empty file name");
    const json* mesh = optional(m, "gltf_mesh");
    const json* node = optional(m, "gltf_node");
    if (mesh && node) fail(p + ".gltf_node", "give either \"gltf_mesh\" or \"gltf_node\", not both");
    GltfSelection sel;
    if (mesh || node) {
      const json& ref = mesh ? *mesh : *node;
      const std::string pr = p + (mesh ? ".gltf_mesh" : ".gltf_node");
      sel.kind = mesh ? GltfSelection::kMesh : GltfSelection::kNode;
      if (ref.is_string()) sel.name = ref.get_ref<const std::string&>();
      else if (ref.is_number()) sel.index = int64_t(u32(ref, pr, std::numeric_limits<int32_t>::max()));
      else expected(pr, "a name or an index", ref);
    }
    uint32_t texcoord = 0;
    if (const json* t = optional(m, "gltf_texcoord")) {
      texcoord = u32(*t, p + ".gltf_texcoord", 31);
      if (!lightmap) fail(p + ".gltf_texcoord", "given, but the mesh has no lightmap (set lightmap_resolution)");
    }
    const std::string file = rel[0] == '/' || options.base_dir.empty() ? rel : options.base_dir + "/" + rel;
    const SceneFileLimits& lim = options.limits;
    GltfMeshData data;
    std::string error;
    if (!read_gltf_mesh(file, sel, texcoord, lightmap,
                        GltfLimits{lim.max_file_bytes, lim.max_vertices, lim.max_triangles, lim.max_depth}, data,
                        error))
      fail(p + ".gltf", error);
    positions = std::move(data.positions);
    indices = std::move(data.indices);
    uv = std::move(data.uv);
  }

  void meshes(const json& v, const std::string& path) {
    array(v, path, options.limits.max_items, "meshes");
    const SceneFileLimits& lim = options.limits;
    for (size_t i = 0; i < v.size(); ++i) {
      const std::string p = index_path(path, i);
      const json& m = object(v[i], p);
      check_keys(m, p,
                 {"name", "positions", "indices", "lightmap_uv", "obj", "material", "materials",
                  "lightmap_resolution", "ol_group", "gltf", "gltf_mesh", "gltf_node", "gltf_texcoord",
                  "texture_uv", "normals", "smooth", "subdivision", "group"});
      SceneFileMesh info;
      info.name = name_or(m, p, "mesh" + std::to_string(i));
      if (const json* r = optional(m, "lightmap_resolution")) resolution(*r, p + ".lightmap_resolution", info.width, info.height);
      const bool lightmap = info.width > 0;
      const json* one_material = optional(m, "material");
      const json* per_triangle = optional(m, "materials");
      if (one_material && per_triangle) fail(p + ".materials", "give either \"material\" or \"materials\", not both");
      uint32_t material = 0;
      if (one_material) material = reference(*one_material, p + ".material", out.material_names, "scene.materials");

      if (const json* sd = optional(m, "subdivision")) {  // a polygon cage refined by the engine
        info.id = subdivision_mesh(m, *sd, p, info, lightmap, one_material ? &material : nullptr, per_triangle);
        shading(m, p, info.id, 0);
        if (const uint32_t group = light_group(m, p))
          engine(plm_scene_set_mesh_light_group(out.scene, info.id, group), p + ".group");
        if (const json* g = optional(m, "ol_group")) {
          const uint32_t group = reference(*g, p + ".ol_group", ol_names, "scene.ol_groups");
          engine(plm_scene_set_mesh_ol_group(out.scene, info.id, out.ol_groups[group].id), p + ".ol_group");
          info.ol_group = int32_t(group);
        }
        out.meshes.push_back(info);
        mesh_names.push_back(info.name);
        continue;
      }
      std::vector<float> positions, uv;
      std::vector<uint32_t> indices, mats;
      for (const char* k : {"gltf_mesh", "gltf_node", "gltf_texcoord"})
        if (optional(m, k) && !optional(m, "gltf")) fail(p + "." + k, "only allowed together with \"gltf\"");
      if (const json* gltf = optional(m, "gltf")) {
        gltf_mesh(m, *gltf, p, lightmap, positions, indices, uv);
      } else if (const json* obj = optional(m, "obj")) {
        for (const char* k : {"positions", "indices", "lightmap_uv", "materials"})
          if (optional(m, k)) fail(p + "." + k, "not allowed together with \"obj\" (the OBJ file gives it)");
        const std::string& rel = string(*obj, p + ".obj");
        if (!options.allow_file_access) fail(p + ".obj", "file access is disabled");
        if (rel.empty()) fail(p + ".obj", "empty file name");
        const std::string file =
            rel[0] == '/' || options.base_dir.empty() ? rel : options.base_dir + "/" + rel;
        std::string text, error;
        if (!read_file(file, lim.max_file_bytes, text, error)) fail(p + ".obj", error);
        ObjReader reader{file, lim, out.material_names, lightmap, material, 0, {}};
        try {
          ObjMesh o = reader.read(text);
          positions = std::move(o.positions);
          indices = std::move(o.indices);
          uv = std::move(o.uv);
          mats = std::move(o.materials);
          if (!one_material && !o.usemtl) mats.clear();  // material 0, or the engine's grey default
        } catch (const InputError& e) {
          fail(p + ".obj", e.what());
        }
      } else {
        const std::string pp = p + ".positions", pi = p + ".indices";
        const json& jp = array(required(m, p, "positions"), pp, uint64_t(lim.max_vertices) * 3, "numbers");
        if (jp.size() % 3) fail(pp, "expected 3 numbers per vertex, got " + std::to_string(jp.size()) + " numbers");
        positions.resize(jp.size());
        for (size_t k = 0; k < jp.size(); ++k) positions[k] = to_float(jp[k], index_path(pp, k));
        const json& ji = array(required(m, p, "indices"), pi, uint64_t(lim.max_triangles) * 3, "indices");
        if (ji.size() % 3) fail(pi, "expected 3 indices per triangle, got " + std::to_string(ji.size()) + " indices");
        if (ji.empty()) fail(pi, "a mesh needs at least one triangle");
        const size_t vertex_count = positions.size() / 3;
        indices = vertex_indices(ji, pi, vertex_count);
        uv = lightmap_uv(m, p, lightmap, indices.size(),
                         "triangle corner: " + std::to_string(indices.size() * 2) + " for " +
                             std::to_string(indices.size() / 3) + " triangles");
        if (per_triangle) {
          const std::string pm = p + ".materials";
          array(*per_triangle, pm, lim.max_triangles, "materials");
          if (per_triangle->size() != indices.size() / 3)
            fail(pm, "expected one material per triangle: " + std::to_string(indices.size() / 3) + ", got " +
                         std::to_string(per_triangle->size()));
          mats.resize(per_triangle->size());
          for (size_t k = 0; k < mats.size(); ++k)
            mats[k] = reference((*per_triangle)[k], index_path(pm, k), out.material_names, "scene.materials");
        }
      }
      if (mats.empty() && one_material) mats.assign(indices.size() / 3, material);
      uint32_t id = 0;
      engine(plm_scene_add_mesh(out.scene, info.name.c_str(), positions.data(), uint32_t(positions.size() / 3),
                                indices.data(), uint32_t(indices.size() / 3), lightmap ? uv.data() : nullptr,
                                mats.empty() ? nullptr : mats.data(), info.width, info.height, &id),
             p);
      info.id = id;
      if (const json* jt = optional(m, "texture_uv")) {
        const std::string pt = p + ".texture_uv";
        if (optional(m, "obj") || optional(m, "gltf")) fail(pt, "only allowed for inline meshes (positions, indices)");
        array(*jt, pt, uint64_t(lim.max_triangles) * 6, "numbers");
        if (jt->size() != indices.size() * 2)
          fail(pt, "expected 2 numbers (u, v) per triangle corner: " + std::to_string(indices.size() * 2) + " for " +
                       std::to_string(indices.size() / 3) + " triangles, got " + std::to_string(jt->size()));
        std::vector<float> tuv(jt->size());
        for (size_t k = 0; k < jt->size(); ++k) tuv[k] = to_float((*jt)[k], index_path(pt, k));
        engine(plm_scene_set_mesh_texture_uv(out.scene, id, tuv.data()), pt);
      }
      shading(m, p, id, indices.size() / 3);
      if (options.keep_geometry) {
        auto g = std::make_shared<SceneFileMesh::Geometry>();
        g->positions = std::move(positions);
        g->indices = std::move(indices);
        if (lightmap) g->uv = std::move(uv);
        g->materials = std::move(mats);
        if (const json* jt = optional(m, "texture_uv"))
          for (const json& x : *jt) g->texture_uv.push_back(x.get<float>());
        info.geometry = std::move(g);
      }
      if (const uint32_t group = light_group(m, p))
        engine(plm_scene_set_mesh_light_group(out.scene, id, group), p + ".group");
      if (const json* g = optional(m, "ol_group")) {
        const uint32_t group = reference(*g, p + ".ol_group", ol_names, "scene.ol_groups");
        engine(plm_scene_set_mesh_ol_group(out.scene, id, out.ol_groups[group].id), p + ".ol_group");
        info.ol_group = int32_t(group);
      }
      out.meshes.push_back(info);
      mesh_names.push_back(info.name);
    }
  }

  void lights(const json& v, const std::string& path) {
    array(v, path, options.limits.max_items, "lights");
    for (size_t i = 0; i < v.size(); ++i) {
      const std::string p = index_path(path, i);
      const json& l = object(v[i], p);
      check_keys(l, p,
                 {"name", "type", "color", "power", "matrix", "location", "radius", "angle", "size_x", "size_y",
                  "spot_size", "spot_blend", "group"});
      const std::string name = name_or(l, p, "light" + std::to_string(i));
      const uint32_t type =
          enum_value(required(l, p, "type"), p + ".type", {"POINT", "SPOT", "SUN", "AREA_RECT", "AREA_DISK", "PORTAL"});
      plm_light light;
      plm_light_default(&light, plm_light_type(type));
      if (const json* c = optional(l, "color")) rgb(*c, p + ".color", light.color);
      const json* matrix = optional(l, "matrix");
      const json* location = optional(l, "location");
      if (matrix && location) fail(p + ".location", "give either \"matrix\" or \"location\", not both");
      if (matrix) fixed_floats(*matrix, p + ".matrix", 16, light.matrix);
      if (location) {
        float t[3];
        fixed_floats(*location, p + ".location", 3, t);
        light.matrix[3] = t[0];
        light.matrix[7] = t[1];
        light.matrix[11] = t[2];
      }
      struct {
        const char* key;
        float* field;
      } scalars[] = {{"power", &light.power},   {"radius", &light.radius},       {"angle", &light.angle},
                     {"size_x", &light.size_x}, {"size_y", &light.size_y},       {"spot_size", &light.spot_size},
                     {"spot_blend", &light.spot_blend}};
      for (const auto& s : scalars)
        if (const json* x = optional(l, s.key)) *s.field = to_float(*x, p + "." + s.key);
      uint32_t id = 0;
      engine(plm_scene_add_light(out.scene, name.c_str(), &light, &id), p);
      if (const uint32_t group = light_group(l, p)) engine(plm_scene_set_light_group(out.scene, id, group), p + ".group");
    }
  }

  // {"radiance": colour} or {"map": "sky.exr", "rotation": [9 numbers], "strength": s} (map relative to the file).
  void world(const json& v, const std::string& path) {
    object(v, path);
    check_keys(v, path, {"radiance", "map", "rotation", "strength", "group"});
    if (const uint32_t group = light_group(v, path))
      engine(plm_scene_set_world_light_group(out.scene, group), path + ".group");
    const json* map = optional(v, "map");
    if (!map) {
      for (const char* k : {"rotation", "strength"})
        if (optional(v, k)) fail(path + "." + k, "only with \"map\"");
      float radiance[3] = {0, 0, 0};
      if (const json* r = optional(v, "radiance")) rgb(*r, path + ".radiance", radiance);
      engine(plm_scene_set_world(out.scene, radiance), path);
      return;
    }
    if (optional(v, "radiance")) fail(path + ".radiance", "give either \"radiance\" or \"map\", not both");
    const std::string rel = string(*map, path + ".map");
    float rotation[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, strength = 1.0f;
    if (const json* r = optional(v, "rotation")) fixed_floats(*r, path + ".rotation", 9, rotation);
    if (const json* st = optional(v, "strength")) strength = to_float(*st, path + ".strength");
    if (!options.allow_file_access) fail(path + ".map", "file access is disabled");
    if (rel.empty()) fail(path + ".map", "empty file name");
    const std::string file = rel[0] == '/' || options.base_dir.empty() ? rel : options.base_dir + "/" + rel;
    engine(plm_scene_set_world_map_file(out.scene, file.c_str(), rotation, strength), path + ".map");
  }

  void csg(const json& v, const std::string& path) {
    array(v, path, options.limits.max_items, "CSG solids");
    const uint32_t max = options.limits.max_items;
    for (size_t i = 0; i < v.size(); ++i) {
      const std::string p = index_path(path, i);
      const json& c = object(v[i], p);
      check_keys(c, p, {"name", "primitives", "nodes", "children", "root", "carrier"});
      const std::string name = name_or(c, p, "csg" + std::to_string(i));
      const std::string pp = p + ".primitives", pn = p + ".nodes", pc = p + ".children";
      const json& jp = array(required(c, p, "primitives"), pp, max, "primitives");
      std::vector<plm_csg_primitive> prims(jp.size());
      for (size_t k = 0; k < jp.size(); ++k) {
        const std::string q = index_path(pp, k);
        const json& e = object(jp[k], q);
        check_keys(e, q, {"shape", "material", "matrix", "major_radius", "minor_radius"});
        plm_csg_primitive& prim = prims[k];
        prim = plm_csg_primitive{};
        prim.struct_size = sizeof prim;
        prim.shape = enum_value(required(e, q, "shape"), q + ".shape",
                                {"SPHERE", "BOX", "CYLINDER", "CONE", "TORUS", "PARABOLOID", "HALF_SPACE"});
        if (const json* m = optional(e, "material"))
          prim.material = reference(*m, q + ".material", out.material_names, "scene.materials");
        const double identity[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
        std::memcpy(prim.matrix, identity, sizeof identity);
        if (const json* m = optional(e, "matrix")) {
          const std::string pm = q + ".matrix";
          if (!m->is_array()) expected(pm, "an array", *m);
          if (m->size() != 12) fail(pm, "expected 12 numbers (3x4, row-major), got " + std::to_string(m->size()));
          for (size_t j = 0; j < 12; ++j) prim.matrix[j] = number((*m)[j], index_path(pm, j));
        }
        prim.major_radius = 1.0;
        prim.minor_radius = 0.25;
        if (const json* r = optional(e, "major_radius")) prim.major_radius = number(*r, q + ".major_radius");
        if (const json* r = optional(e, "minor_radius")) prim.minor_radius = number(*r, q + ".minor_radius");
      }
      const json& jn = array(required(c, p, "nodes"), pn, max, "nodes");
      std::vector<plm_csg_node> nodes(jn.size());
      for (size_t k = 0; k < jn.size(); ++k) {
        const std::string q = index_path(pn, k);
        const json& e = object(jn[k], q);
        check_keys(e, q, {"op", "first", "count"});
        nodes[k].struct_size = sizeof nodes[k];
        nodes[k].op = enum_value(required(e, q, "op"), q + ".op", {"UNION", "INTERSECTION", "DIFFERENCE", "LEAF"});
        nodes[k].first = u32(required(e, q, "first"), q + ".first");
        nodes[k].count = 0;
        if (const json* n = optional(e, "count")) nodes[k].count = u32(*n, q + ".count");
        else if (nodes[k].op != PLM_CSG_LEAF) fail(q, "missing field \"count\"");
      }
      std::vector<uint32_t> children;
      if (const json* jc = optional(c, "children")) {
        array(*jc, pc, max, "children");
        for (size_t k = 0; k < jc->size(); ++k) children.push_back(u32((*jc)[k], index_path(pc, k)));
      }
      uint32_t root = 0;
      if (const json* r = optional(c, "root")) root = u32(*r, p + ".root");
      uint32_t id = 0;
      engine(plm_scene_add_csg(out.scene, name.c_str(), prims.data(), uint32_t(prims.size()), nodes.data(),
                               uint32_t(nodes.size()), children.empty() ? nullptr : children.data(),
                               uint32_t(children.size()), root, &id),
             p);
      if (const json* carrier = optional(c, "carrier")) {
        const uint32_t mesh = reference(*carrier, p + ".carrier", mesh_names, "scene.meshes");
        engine(plm_scene_set_csg_carrier(out.scene, id, out.meshes[mesh].id), p + ".carrier");
      }
    }
  }

  void settings(const json& v, const std::string& path) {
    object(v, path);
    check_keys(v, path,
               {"photon_count", "max_bounces", "seed", "thread_count", "dilation", "target_error", "time_budget",
                "direct_samples", "filter_radius", "texel_value", "sampler", "directional"});
    plm_bake_settings& s = out.settings;
    if (const json* x = optional(v, "photon_count")) s.photon_count = integer(*x, path + ".photon_count", uint64_t(1) << 40);
    struct {
      const char* key;
      uint32_t* field;
    } ints[] = {{"max_bounces", &s.max_bounces},       {"seed", &s.seed},
                {"thread_count", &s.thread_count},     {"dilation", &s.dilation},
                {"direct_samples", &s.direct_samples}, {"filter_radius", &s.filter_radius}};
    for (const auto& f : ints)
      if (const json* x = optional(v, f.key)) *f.field = u32(*x, path + "." + f.key);
    for (const char* key : {"target_error", "time_budget"}) {
      if (const json* x = optional(v, key)) {
        const double d = number(*x, path + "." + key);
        if (d < 0) fail(path + "." + key, "must be >= 0, got " + shown(*x));
        (std::strcmp(key, "target_error") == 0 ? s.target_error : s.time_budget) = d;
      }
    }
    if (const json* x = optional(v, "texel_value")) s.texel_value = enum_value(*x, path + ".texel_value", {"CYCLES", "AREA"});
    if (const json* x = optional(v, "sampler"))
      s.sampler = enum_value(*x, path + ".sampler", {"DEFAULT", "RANDOM", "SOBOL"});
    if (const json* x = optional(v, "directional")) {
      if (!x->is_boolean()) fail(path + ".directional", "must be true or false, got " + shown(*x));
      s.directional = x->get<bool>() ? 1 : 0;
    }
  }

  void scene(const json& root) {
    const std::string p = "scene";
    object(root, p);
    // "metadata": free-form, for the tools that write the file (the Blender export); not read.
    check_keys(root, p,
               {"version", "settings", "world", "materials", "ol_groups", "meshes", "lights", "csg", "metadata",
                "conventions", "light_groups"});
    if (const json* ver = optional(root, "version")) {
      if (u32(*ver, p + ".version") != 1) fail(p + ".version", "this reader knows version 1, got " + shown(*ver));
    }
    // "conventions": whose Cycles the lights follow (plm_conventions), "cycles-3.4" by default.
    if (const json* x = optional(root, "conventions"))
      engine(plm_scene_set_conventions(
                 out.scene, int32_t(enum_value(*x, p + ".conventions", {"cycles-3.4", "cycles-4"}))),
             p + ".conventions");
    if (const json* x = optional(root, "light_groups")) light_groups(*x, p + ".light_groups");
    if (const json* x = optional(root, "materials")) materials(*x, p + ".materials");
    if (const json* x = optional(root, "ol_groups")) ol_groups(*x, p + ".ol_groups");
    if (const json* x = optional(root, "meshes")) meshes(*x, p + ".meshes");
    if (const json* x = optional(root, "lights")) lights(*x, p + ".lights");
    if (const json* x = optional(root, "world")) world(*x, p + ".world");
    if (const json* x = optional(root, "csg")) csg(*x, p + ".csg");
    if (const json* x = optional(root, "settings")) settings(*x, p + ".settings");
  }
};

}  // namespace

SceneFile::SceneFile() { plm_bake_settings_default(&settings); }
SceneFile::~SceneFile() { plm_scene_release(scene); }

bool parse_scene_file_text(std::string_view text, const SceneFileOptions& options, SceneFile& out, std::string& error) {
  try {
    if (text.size() > options.limits.max_file_bytes) {
      error = "the scene file is larger than the limit of " + std::to_string(options.limits.max_file_bytes) + " bytes";
      return false;
    }
    json root;
    const uint32_t max_depth = options.limits.max_depth;
    try {
      root = json::parse(text.begin(), text.end(), [max_depth](int depth, json::parse_event_t, json&) {
        if (depth > int(max_depth))
          throw InputError("JSON nesting deeper than " + std::to_string(max_depth) + " levels");
        return true;
      });
    } catch (const json::exception& e) {
      // e.what() is "[json.exception.parse_error.101] parse error at line 3, column 5: ..." or
      // "[json.exception.out_of_range.406] number overflow parsing '1e999'".
      std::string what = e.what();
      const size_t at = what.find("] ");
      error = "JSON syntax: " + (at == std::string::npos ? what : what.substr(at + 2));
      return false;
    }
    plm_scene_release(out.scene);
    out.scene = nullptr;
    out.meshes.clear();
    out.ol_groups.clear();
    out.material_names.clear();
    plm_bake_settings_default(&out.settings);
    if (plm_scene_create(&out.scene) != PLM_OK) {
      error = std::string("cannot create a scene: ") + plm_last_error();
      return false;
    }
    Reader reader{options, out, {}, {}, {}};
    reader.scene(root);
    return true;
  } catch (const InputError& e) {
    error = e.what();
  } catch (const std::bad_alloc&) {
    error = "out of memory";
  } catch (const std::exception& e) {
    error = std::string("internal error: ") + e.what();
  }
  return false;
}

bool read_scene_file(const std::string& path, const SceneFileOptions& options, SceneFile& out, std::string& error) {
  std::string text;
  if (!read_file(path, options.limits.max_file_bytes, text, error)) return false;
  SceneFileOptions o = options;
  const size_t slash = path.find_last_of('/');
  o.base_dir = slash == std::string::npos ? "" : (slash == 0 ? "/" : path.substr(0, slash));
  if (!parse_scene_file_text(text, o, out, error)) {
    error = path + ": " + error;
    return false;
  }
  return true;
}

const char* texel_value_name(uint32_t value) {
  return value == PLM_TEXEL_CYCLES ? "CYCLES" : value == PLM_TEXEL_AREA ? "AREA" : "?";
}

const char* sampler_name(uint32_t value) {
  return value == PLM_SAMPLER_DEFAULT ? "DEFAULT" : value == PLM_SAMPLER_RANDOM ? "RANDOM"
         : value == PLM_SAMPLER_SOBOL ? "SOBOL" : "?";
}

}  // namespace plm

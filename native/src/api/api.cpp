// The C API: every entry point catches every exception and turns it into a
// status code plus a per-thread message; nothing escapes into the host.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <new>
#include <string>
#include <vector>

#include "api/handles.h"
#include "api/settings.h"
#include "api/struct_size.h"
#include "lsystem/lsystem_object.h"
#include "photonlm/photonlm.h"
#include "scene/scene.h"
#include "subdiv/limit_area.h"
#include "subdiv/subdiv.h"
#include "transport/control/bake.h"
#include "transport/jobs/bake_jobs.h"
#include "transport/farm/partial_file.h"
#include "util/error.h"
#include "util/image_file.h"


namespace {

thread_local std::string t_last_error;

plm_status set_error(plm_status status, const std::string& message) {
  t_last_error = message;
  return status;
}

// Runs f, mapping exceptions to status codes and messages.
template <typename F>
plm_status guarded(const char* function, F&& f) {
  try {
    f();
    return PLM_OK;
  } catch (const plm::Error& e) {
    return set_error(e.status(), e.what());
  } catch (const std::bad_alloc&) {
    return set_error(PLM_ERROR_OUT_OF_MEMORY, std::string(function) + ": out of memory");
  } catch (const std::exception& e) {
    return set_error(PLM_ERROR_INTERNAL, std::string(function) + ": internal error: " + e.what());
  } catch (...) {
    return set_error(PLM_ERROR_INTERNAL, std::string(function) + ": unknown internal error");
  }
}

void require(const void* p, const char* function, const char* what) {
  if (!p) plm::fail(PLM_ERROR_INVALID_ARGUMENT, function, ": ", what, " must not be NULL");
}

// The result's `items`[index], or an error naming the item and how many the scene had.
template <typename T>
const T& result_item(const std::vector<T>& items, uint32_t index, const char* function, const char* what,
                     const char* plural) {
  if (index >= items.size())
    plm::fail(PLM_ERROR_INVALID_ARGUMENT, function, ": ", what, " ", index, " is out of range (the scene had ",
              items.size(), " ", plural, ")");
  return items[index];
}

const plm::LightmapImage& lightmap_of(const plm_result* r, uint32_t mesh_id, const char* function) {
  require(r, function, "result");
  const plm::LightmapImage& map = result_item(r->output.lightmaps, mesh_id, function, "mesh id", "meshes");
  if (map.width == 0) plm::fail(PLM_ERROR_INVALID_ARGUMENT, function, ": mesh ", mesh_id, " has no lightmap");
  return map;
}

const plm::LightmapImage& sh_lightmap_of(const plm_result* result, uint32_t mesh_id, uint32_t band,
                                         const char* function) {
  const plm::LightmapImage& img = lightmap_of(result, mesh_id, function);
  if (!result->output.directional)
    plm::fail(PLM_ERROR_INVALID_ARGUMENT, function, ": the bake has no directional lightmaps (bake with "
              "plm_bake_settings.directional = 1)");
  if (band > 3) plm::fail(PLM_ERROR_INVALID_ARGUMENT, function, ": band ", band, " is not 0 (L0) to 3 (L1_1)");
  return img;
}

const plm::OlImage& ol_of(const plm_result* r, uint32_t group, const char* function) {
  require(r, function, "result");
  return result_item(r->output.ols, group, function, "OL group", "OL groups");
}

const plm::LSystemOutput& lsystem_of(const plm_result* r, uint32_t id, const char* function) {
  require(r, function, "result");
  return result_item(r->output.lsystems, id, function, "L-system", "L-system objects");
}

// The caller's bake settings (NULL: the defaults) as a whole current struct.
plm_bake_settings settings_or_default(const plm_bake_settings* settings, const char* function) {
  if (!settings) return plm::default_settings();
  return plm::api::read_sized(settings, plm::default_settings(), function, "settings");
}

// The caller's L-system settings (NULL: the defaults) as a whole current struct.
plm_lsystem_settings lsystem_settings_or_default(const plm_lsystem_settings* settings, const char* function) {
  const plm_lsystem_settings defaults = plm::lsystem::default_lsystem_settings();
  if (!settings) return defaults;
  return plm::api::read_sized(settings, defaults, function, "settings");
}

// A caller's array of `count` structs, each carrying struct_size (the first
// element's is the stride; every element must carry the same), as current structs.
template <typename T>
std::vector<T> read_sized_array(const T* items, uint32_t count, const T& defaults, const char* function,
                                const char* what) {
  std::vector<T> out;
  if (!items || count == 0) return out;
  const uint32_t stride = plm::api::checked_size<T>(items->struct_size, function, std::string(what) + "[0]");
  out.reserve(count);
  const auto* bytes = reinterpret_cast<const unsigned char*>(items);
  for (uint32_t i = 0; i < count; ++i) {
    const T* item = reinterpret_cast<const T*>(bytes + size_t(stride) * i);
    if (item->struct_size != stride)
      plm::fail(PLM_ERROR_STRUCT_SIZE, function, ": ", what, "[", i, "] (", plm::api::Layouts<T>::name,
                ") has struct_size ", item->struct_size, ", ", what, "[0] ", stride, " (current ", sizeof(T),
                "; every element of an array carries the same size)");
    out.push_back(plm::api::read_sized(item, defaults, function, std::string(what) + "[" + std::to_string(i) + "]"));
  }
  return out;
}

// plm_bake and plm_bake_with_preview, named `function` in errors.
plm_status run_bake(const char* function, plm_scene* scene, const plm_bake_settings* settings,
                    plm_progress_fn progress, plm_preview_fn preview, double preview_interval, void* user_data,
                    plm_result** out_result) {
  return guarded(function, [&] {
    require(scene, function, "scene");
    require(out_result, function, "out_result");
    *out_result = nullptr;
    if (!(preview_interval >= 0.0) || !std::isfinite(preview_interval))
      plm::fail(PLM_ERROR_INVALID_ARGUMENT, function, ": preview_interval must be a finite number of seconds >= 0, "
                "got ", preview_interval);
    const plm_bake_settings s = settings_or_default(settings, function);
    plm::ProgressFn fn;
    if (progress) fn = [&](double f, const char* stage) { return progress(user_data, f, stage) != 0; };
    plm::PreviewHook hook;
    hook.interval = preview_interval;
    if (preview)
      hook.callback = [&](const plm::Snapshot& snapshot) {
        const plm_preview handle{snapshot};
        return preview(user_data, &handle) != 0;
      };
    auto* result = new plm_result();
    try {
      result->output = plm::bake(scene->scene, plm::api::engine_settings(s, scene->scene), fn, &hook);
    } catch (...) {
      delete result;
      throw;
    }
    *out_result = result;
  });
}

// The cage arguments of plm_scene_add_subdiv_mesh and plm_subdiv_refine.
plm::subdiv::Cage make_cage(const float* positions, uint32_t vertex_count, const uint32_t* face_sizes,
                            uint32_t face_count, const uint32_t* face_indices, const float* uv,
                            const uint32_t* crease_edges, const float* crease_weights, uint32_t crease_count,
                            uint32_t level) {
  plm::subdiv::Cage cage;
  cage.positions = positions;
  cage.vertex_count = vertex_count;
  cage.face_sizes = face_sizes;
  cage.face_count = face_count;
  cage.face_indices = face_indices;
  cage.uv = uv;
  cage.crease_edges = crease_edges;
  cage.crease_weights = crease_weights;
  cage.crease_count = crease_count;
  cage.level = level;
  return cage;
}

// The host's progress callback as the engine's (empty without one).
plm::ProgressFn progress_fn(plm_progress_fn progress, void* user_data) {
  if (!progress) return {};
  return [progress, user_data](double f, const char* stage) { return progress(user_data, f, stage) != 0; };
}

std::vector<std::string> part_list(const char* fn, const char* const* part_paths, uint32_t part_count) {
  if (part_count > 0) require(part_paths, fn, "part_paths");
  std::vector<std::string> paths;
  for (uint32_t i = 0; i < part_count; ++i) {
    if (!part_paths[i]) plm::fail(PLM_ERROR_INVALID_ARGUMENT, fn, ": part_paths[", i, "] is NULL");
    paths.push_back(part_paths[i]);
  }
  return paths;
}

// A caller's image to write: between 1 x 1 and 2^28 texels.
void require_image_size(const char* function, const char* path, uint32_t width, uint32_t height) {
  if (width == 0 || height == 0 || double(width) * double(height) > double(1u << 28))
    plm::fail(PLM_ERROR_INVALID_ARGUMENT, function, ": '", path, "': size ", width, " x ", height,
              " is not between 1 x 1 and 2^28 texels");
}

}  // namespace

extern "C" {

const char* plm_version(void) { return "0.1.0"; }

const char* plm_status_string(plm_status status) {
  switch (status) {
    case PLM_OK: return "PLM_OK";
    case PLM_ERROR_INVALID_ARGUMENT: return "PLM_ERROR_INVALID_ARGUMENT";
    case PLM_ERROR_INVALID_SCENE: return "PLM_ERROR_INVALID_SCENE";
    case PLM_ERROR_OUT_OF_MEMORY: return "PLM_ERROR_OUT_OF_MEMORY";
    case PLM_ERROR_IO: return "PLM_ERROR_IO";
    case PLM_ERROR_CANCELLED: return "PLM_ERROR_CANCELLED";
    case PLM_ERROR_INTERNAL: return "PLM_ERROR_INTERNAL";
    case PLM_ERROR_STRUCT_SIZE: return "PLM_ERROR_STRUCT_SIZE";
  }
  return "PLM_ERROR_UNKNOWN";
}

const char* plm_last_error(void) { return t_last_error.c_str(); }

plm_status plm_scene_create(plm_scene** out_scene) {
  return guarded("plm_scene_create", [&] {
    require(out_scene, "plm_scene_create", "out_scene");
    *out_scene = nullptr;
    *out_scene = new plm_scene();
  });
}

void plm_scene_release(plm_scene* scene) { delete scene; }

plm_status plm_scene_add_material(plm_scene* scene, const char* name, const float albedo[3],
                                  const float emission[3], uint32_t* out_material_id) {
  return guarded("plm_scene_add_material", [&] {
    require(scene, "plm_scene_add_material", "scene");
    const uint32_t id = scene->scene.add_material(name, albedo, emission);
    if (out_material_id) *out_material_id = id;
  });
}

void plm_lobe_default(plm_lobe* lobe, plm_lobe_type type) {
  if (lobe) *lobe = plm::default_lobe(type);
}

plm_status plm_scene_add_material_lobe(plm_scene* scene, uint32_t material_id, const plm_lobe* lobe) {
  return guarded("plm_scene_add_material_lobe", [&] {
    require(scene, "plm_scene_add_material_lobe", "scene");
    require(lobe, "plm_scene_add_material_lobe", "lobe");
    plm::api::checked_size<plm_lobe>(lobe->struct_size, "plm_scene_add_material_lobe", "lobe");
    // The defaults of its type for the fields an older layout lacks (an unknown type is refused later).
    const bool known = lobe->type >= PLM_LOBE_GLOSSY && lobe->type <= PLM_LOBE_SPECULAR;
    const plm_lobe defaults = plm::default_lobe(known ? plm_lobe_type(lobe->type) : PLM_LOBE_GLOSSY);
    const plm_lobe l = plm::api::read_sized(lobe, defaults, "plm_scene_add_material_lobe", "lobe");
    scene->scene.add_material_lobe(material_id, l);
  });
}

plm_status plm_scene_set_material_diffuse(plm_scene* scene, uint32_t material_id, int32_t model, float roughness) {
  return guarded("plm_scene_set_material_diffuse", [&] {
    require(scene, "plm_scene_set_material_diffuse", "scene");
    scene->scene.set_material_diffuse(material_id, model, roughness);
  });
}

plm_status plm_scene_set_material_texture(plm_scene* scene, uint32_t material_id, int32_t slot,
                                          const char* path, uint32_t flags) {
  return guarded("plm_scene_set_material_texture", [&] {
    require(scene, "plm_scene_set_material_texture", "scene");
    scene->scene.set_material_texture(material_id, slot, path, flags);
  });
}

plm_status plm_scene_set_mesh_texture_uv(plm_scene* scene, uint32_t mesh_id, const float* uv) {
  return guarded("plm_scene_set_mesh_texture_uv", [&] {
    require(scene, "plm_scene_set_mesh_texture_uv", "scene");
    scene->scene.set_mesh_texture_uv(mesh_id, uv);
  });
}

plm_status plm_scene_set_mesh_normals(plm_scene* scene, uint32_t mesh_id, const float* normals) {
  return guarded("plm_scene_set_mesh_normals", [&] {
    require(scene, "plm_scene_set_mesh_normals", "scene");
    scene->scene.set_mesh_normals(mesh_id, normals);
  });
}

plm_status plm_scene_set_mesh_smooth(plm_scene* scene, uint32_t mesh_id, int smooth) {
  return guarded("plm_scene_set_mesh_smooth", [&] {
    require(scene, "plm_scene_set_mesh_smooth", "scene");
    scene->scene.set_mesh_smooth(mesh_id, smooth != 0);
  });
}

plm_status plm_scene_add_mesh(plm_scene* scene, const char* name, const float* positions, uint32_t vertex_count,
                              const uint32_t* indices, uint32_t triangle_count, const float* lightmap_uv,
                              const uint32_t* material_ids, uint32_t lightmap_width, uint32_t lightmap_height,
                              uint32_t* out_mesh_id) {
  return guarded("plm_scene_add_mesh", [&] {
    require(scene, "plm_scene_add_mesh", "scene");
    const uint32_t id = scene->scene.add_mesh(name, positions, vertex_count, indices, triangle_count, lightmap_uv,
                                              material_ids, lightmap_width, lightmap_height);
    if (out_mesh_id) *out_mesh_id = id;
  });
}

plm_status plm_scene_add_subdiv_mesh(plm_scene* scene, const char* name, const float* positions,
                                     uint32_t vertex_count, const uint32_t* face_sizes, uint32_t face_count,
                                     const uint32_t* face_indices, const float* lightmap_uv,
                                     const uint32_t* material_ids, const uint32_t* crease_edges,
                                     const float* crease_weights, uint32_t crease_count, uint32_t level,
                                     uint32_t lightmap_width, uint32_t lightmap_height, uint32_t* out_mesh_id) {
  return guarded("plm_scene_add_subdiv_mesh", [&] {
    require(scene, "plm_scene_add_subdiv_mesh", "scene");
    const size_t index = scene->scene.meshes.size();
    const std::string owner = "mesh '" + (name && *name ? std::string(name) : "#" + std::to_string(index)) + "'";
    if (lightmap_width > 0 && !lightmap_uv)
      plm::fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": has a ", lightmap_width, " x ", lightmap_height,
                " lightmap but no lightmap UVs (pass UVs, or size 0 x 0 for geometry only)");
    plm::subdiv::Cage cage = make_cage(positions, vertex_count, face_sizes, face_count, face_indices,
                                       lightmap_width > 0 ? lightmap_uv : nullptr, crease_edges, crease_weights,
                                       crease_count, level);
    cage.material_ids = material_ids;
    const uint32_t id = scene->scene.add_subdiv_mesh(name, cage, lightmap_width, lightmap_height);
    if (out_mesh_id) *out_mesh_id = id;
  });
}

plm_status plm_scene_refine_subdiv_meshes(plm_scene* scene, uint32_t thread_count) {
  return guarded("plm_scene_refine_subdiv_meshes", [&] {
    require(scene, "plm_scene_refine_subdiv_meshes", "scene");
    scene->scene.refine_cages(thread_count);
  });
}

plm_status plm_subdiv_refine(const float* positions, uint32_t vertex_count, const uint32_t* face_sizes,
                             uint32_t face_count, const uint32_t* face_indices, const float* lightmap_uv,
                             const uint32_t* crease_edges, const float* crease_weights, uint32_t crease_count,
                             uint32_t level, float* out_positions, uint32_t vertex_capacity, uint32_t* out_indices,
                             float* out_uv, uint32_t triangle_capacity, uint32_t* out_vertex_count,
                             uint32_t* out_triangle_count) {
  return guarded("plm_subdiv_refine", [&] {
    require(out_vertex_count, "plm_subdiv_refine", "out_vertex_count");
    require(out_triangle_count, "plm_subdiv_refine", "out_triangle_count");
    const plm::subdiv::Cage cage = make_cage(positions, vertex_count, face_sizes, face_count, face_indices,
                                             lightmap_uv, crease_edges, crease_weights, crease_count, level);
    const plm::subdiv::RefinedMesh m = plm::subdiv::refine("plm_subdiv_refine", cage);
    *out_vertex_count = m.vertex_count();
    *out_triangle_count = m.triangle_count();
    if (!out_positions && !out_indices && !out_uv) return;
    if (!out_positions || !out_indices || (lightmap_uv && !out_uv) || vertex_capacity < m.vertex_count() ||
        triangle_capacity < m.triangle_count())
      plm::fail(PLM_ERROR_INVALID_ARGUMENT, "plm_subdiv_refine: the buffers must hold ", m.vertex_count(),
                " vertices and ", m.triangle_count(), " triangles (positions, indices",
                lightmap_uv ? " and UVs" : "", "); got room for ", vertex_capacity, " and ", triangle_capacity);
    std::copy(m.positions.begin(), m.positions.end(), out_positions);
    std::copy(m.indices.begin(), m.indices.end(), out_indices);
    if (lightmap_uv) std::copy(m.uv.begin(), m.uv.end(), out_uv);
  });
}

void plm_light_default(plm_light* light, plm_light_type type) {
  if (light) *light = plm::default_light(type);
}

plm_status plm_scene_add_light(plm_scene* scene, const char* name, const plm_light* light, uint32_t* out_light_id) {
  return guarded("plm_scene_add_light", [&] {
    require(scene, "plm_scene_add_light", "scene");
    require(light, "plm_scene_add_light", "light");
    const plm_light l =
        plm::api::read_sized(light, plm::default_light(PLM_LIGHT_POINT), "plm_scene_add_light", "light");
    const uint32_t id = scene->scene.add_light(name, l);
    if (out_light_id) *out_light_id = id;
  });
}

plm_status plm_scene_add_csg(plm_scene* scene, const char* name, const plm_csg_primitive* primitives,
                             uint32_t primitive_count, const plm_csg_node* nodes, uint32_t node_count,
                             const uint32_t* children, uint32_t child_count, uint32_t root, uint32_t* out_csg) {
  return guarded("plm_scene_add_csg", [&] {
    require(scene, "plm_scene_add_csg", "scene");
    plm_csg_primitive no_primitive{};
    plm_csg_node no_node{};
    no_primitive.struct_size = sizeof no_primitive;
    no_node.struct_size = sizeof no_node;
    const std::vector<plm_csg_primitive> p =
        read_sized_array(primitives, primitive_count, no_primitive, "plm_scene_add_csg", "primitives");
    const std::vector<plm_csg_node> n = read_sized_array(nodes, node_count, no_node, "plm_scene_add_csg", "nodes");
    const uint32_t id = scene->scene.add_csg(name, primitives ? p.data() : nullptr, primitive_count,
                                             nodes ? n.data() : nullptr, node_count, children, child_count, root);
    if (out_csg) *out_csg = id;
  });
}

plm_status plm_scene_set_csg_carrier(plm_scene* scene, uint32_t csg, uint32_t mesh) {
  return guarded("plm_scene_set_csg_carrier", [&] {
    require(scene, "plm_scene_set_csg_carrier", "scene");
    scene->scene.set_csg_carrier(csg, mesh);
  });
}

plm_status plm_scene_set_conventions(plm_scene* scene, int32_t conventions) {
  return guarded("plm_scene_set_conventions", [&] {
    require(scene, "plm_scene_set_conventions", "scene");
    scene->scene.set_conventions(conventions);
  });
}

plm_status plm_scene_get_conventions(const plm_scene* scene, int32_t* out_conventions) {
  return guarded("plm_scene_get_conventions", [&] {
    require(scene, "plm_scene_get_conventions", "scene");
    require(out_conventions, "plm_scene_get_conventions", "out_conventions");
    *out_conventions = scene->scene.conventions;
  });
}

plm_status plm_scene_set_world(plm_scene* scene, const float radiance[3]) {
  return guarded("plm_scene_set_world", [&] {
    require(scene, "plm_scene_set_world", "scene");
    scene->scene.set_world(radiance);
  });
}

plm_status plm_scene_set_world_map(plm_scene* scene, const float* rgb, uint32_t width, uint32_t height,
                                   const float rotation[9], float strength) {
  return guarded("plm_scene_set_world_map", [&] {
    require(scene, "plm_scene_set_world_map", "scene");
    scene->scene.set_world_map(rgb, width, height, rotation, strength);
  });
}

plm_status plm_scene_set_world_map_file(plm_scene* scene, const char* path, const float rotation[9], float strength) {
  return guarded("plm_scene_set_world_map_file", [&] {
    require(scene, "plm_scene_set_world_map_file", "scene");
    scene->scene.set_world_map_file(path, rotation, strength);
  });
}

void plm_bake_settings_default(plm_bake_settings* settings) {
  if (settings) *settings = plm::default_settings();
}

plm_status plm_bake(plm_scene* scene, const plm_bake_settings* settings, plm_progress_fn progress, void* user_data,
                    plm_result** out_result) {
  return run_bake("plm_bake", scene, settings, progress, nullptr, 0.0, user_data, out_result);
}

plm_status plm_bake_with_preview(plm_scene* scene, const plm_bake_settings* settings, plm_progress_fn progress,
                                 plm_preview_fn preview, double preview_interval, void* user_data,
                                 plm_result** out_result) {
  return run_bake("plm_bake_with_preview", scene, settings, progress, preview, preview_interval, user_data,
                  out_result);
}

plm_status plm_preview_photons(const plm_preview* preview, uint64_t* out_photons) {
  return guarded("plm_preview_photons", [&] {
    require(preview, "plm_preview_photons", "preview");
    require(out_photons, "plm_preview_photons", "out_photons");
    *out_photons = preview->snapshot.photons();
  });
}

plm_status plm_preview_lightmap_size(const plm_preview* preview, uint32_t mesh_id, uint32_t* out_width,
                                     uint32_t* out_height) {
  return guarded("plm_preview_lightmap_size", [&] {
    require(preview, "plm_preview_lightmap_size", "preview");
    try {
      const plm::Mesh& mesh = preview->snapshot.lightmap_mesh(mesh_id);
      if (out_width) *out_width = mesh.lightmap_width;
      if (out_height) *out_height = mesh.lightmap_height;
    } catch (const plm::Error& e) {
      plm::fail(e.status(), "plm_preview_lightmap_size: ", e.what());
    }
  });
}

plm_status plm_preview_copy_lightmap(const plm_preview* preview, uint32_t mesh_id, float* rgb, int* out_written) {
  return guarded("plm_preview_copy_lightmap", [&] {
    require(preview, "plm_preview_copy_lightmap", "preview");
    require(rgb, "plm_preview_copy_lightmap", "rgb");
    if (out_written) *out_written = 0;
    try {
      const bool written = preview->snapshot.copy_lightmap(mesh_id, rgb);
      if (out_written) *out_written = written ? 1 : 0;
    } catch (const plm::Error& e) {
      plm::fail(e.status(), "plm_preview_copy_lightmap: ", e.what());
    }
  });
}

plm_status plm_bake_shard(plm_scene* scene, const plm_bake_settings* settings, uint32_t shard, uint32_t shard_count,
                          const char* scene_path, const char* part_path, plm_progress_fn progress, void* user_data) {
  return guarded("plm_bake_shard", [&] {
    require(scene, "plm_bake_shard", "scene");
    require(part_path, "plm_bake_shard", "part_path");
    if (shard_count == 0 || shard >= shard_count)
      plm::fail(PLM_ERROR_INVALID_ARGUMENT, "plm_bake_shard: shard ", shard, " of ", shard_count,
                ": expected 0 <= shard < shard_count");
    if (scene_path && std::strlen(scene_path) > 255)
      plm::fail(PLM_ERROR_INVALID_ARGUMENT, "plm_bake_shard: scene_path is longer than 255 bytes");
    const plm::BakeSettings s =
        plm::api::engine_settings(settings_or_default(settings, "plm_bake_shard"), scene->scene);
    plm::bake_shard(scene->scene, s, shard, shard_count, {scene_path ? scene_path : "", part_path},
                    progress_fn(progress, user_data));
  });
}

plm_status plm_bake_texels(plm_scene* scene, const plm_bake_settings* settings, uint32_t stage, uint32_t range,
                           uint32_t range_count, const char* const* part_paths, uint32_t part_count,
                           const char* scene_path, const char* part_path, plm_progress_fn progress, void* user_data) {
  return guarded("plm_bake_texels", [&] {
    require(scene, "plm_bake_texels", "scene");
    require(part_path, "plm_bake_texels", "part_path");
    if (stage != PLM_TEXELS_DIRECT && stage != PLM_TEXELS_GATHER)
      plm::fail(PLM_ERROR_INVALID_ARGUMENT, "plm_bake_texels: stage ", stage,
                " is neither PLM_TEXELS_DIRECT nor PLM_TEXELS_GATHER");
    if (range_count == 0 || range >= range_count)
      plm::fail(PLM_ERROR_INVALID_ARGUMENT, "plm_bake_texels: range ", range, " of ", range_count,
                ": expected 0 <= range < range_count");
    if (scene_path && std::strlen(scene_path) > 255)
      plm::fail(PLM_ERROR_INVALID_ARGUMENT, "plm_bake_texels: scene_path is longer than 255 bytes");
    const std::vector<std::string> paths = part_list("plm_bake_texels", part_paths, part_count);
    const plm::PartTarget target{scene_path ? scene_path : "", part_path};
    const plm_bake_settings s = settings_or_default(settings, "plm_bake_texels");
    if (stage == PLM_TEXELS_GATHER) {
      plm::bake_gather_range(scene->scene, s.thread_count, range, range_count, paths, target,
                             progress_fn(progress, user_data));
      return;
    }
    if (part_count > 0)
      plm::fail(PLM_ERROR_INVALID_ARGUMENT, "plm_bake_texels: the direct pass of a texel range reads no parts (",
                part_count, " given)");
    plm::bake_direct_range(scene->scene, plm::api::engine_settings(s, scene->scene), range, range_count, target,
                           progress_fn(progress, user_data));
  });
}

plm_status plm_part_info(const char* part_path, plm_bake_settings* out_settings, uint32_t* out_shard,
                         uint32_t* out_shard_count, char* scene_path, size_t scene_path_capacity) {
  return guarded("plm_part_info", [&] {
    require(part_path, "plm_part_info", "part_path");
    const plm::PartHeader h = plm::read_part_header(part_path);
    if (out_settings) {
      const plm_bake_settings s = plm::api::c_settings(h.settings);
      plm::api::write_sized(out_settings, s, "plm_part_info", "out_settings");
    }
    if (out_shard) *out_shard = h.shard_index;
    if (out_shard_count) *out_shard_count = h.shard_count;
    if (scene_path && scene_path_capacity > 0) {
      const size_t n = std::min(h.scene_path.size(), scene_path_capacity - 1);
      std::memcpy(scene_path, h.scene_path.data(), n);
      scene_path[n] = '\0';
    }
  });
}

plm_status plm_bake_merge(plm_scene* scene, const char* const* part_paths, uint32_t part_count, uint32_t thread_count,
                          plm_progress_fn progress, void* user_data, plm_result** out_result) {
  return guarded("plm_bake_merge", [&] {
    require(scene, "plm_bake_merge", "scene");
    require(out_result, "plm_bake_merge", "out_result");
    *out_result = nullptr;
    const std::vector<std::string> paths = part_list("plm_bake_merge", part_paths, part_count);
    auto* result = new plm_result();
    try {
      result->output = plm::bake_merge(scene->scene, paths, thread_count, progress_fn(progress, user_data));
    } catch (...) {
      delete result;
      throw;
    }
    *out_result = result;
  });
}

void plm_result_release(plm_result* result) { delete result; }

plm_status plm_result_stats(const plm_result* result, plm_bake_stats* out_stats) {
  return guarded("plm_result_stats", [&] {
    require(result, "plm_result_stats", "result");
    require(out_stats, "plm_result_stats", "out_stats");
    plm::api::write_sized(out_stats, result->output.stats, "plm_result_stats", "out_stats");
  });
}

uint32_t plm_result_warning_count(const plm_result* result) {
  return result ? static_cast<uint32_t>(result->output.warnings.size()) : 0u;
}

const char* plm_result_warning(const plm_result* result, uint32_t index) {
  if (!result || index >= result->output.warnings.size()) return "";
  return result->output.warnings[index].c_str();
}

plm_status plm_result_lightmap_size(const plm_result* result, uint32_t mesh_id, uint32_t* out_width,
                                    uint32_t* out_height) {
  return guarded("plm_result_lightmap_size", [&] {
    const plm::LightmapImage& img = lightmap_of(result, mesh_id, "plm_result_lightmap_size");
    if (out_width) *out_width = img.width;
    if (out_height) *out_height = img.height;
  });
}

plm_status plm_result_copy_lightmap(const plm_result* result, uint32_t mesh_id, float* rgb, float* error,
                                    float* hits, float* coverage) {
  return guarded("plm_result_copy_lightmap", [&] {
    const plm::LightmapImage& img = lightmap_of(result, mesh_id, "plm_result_copy_lightmap");
    const size_t n = size_t(img.width) * img.height;
    if (rgb) std::memcpy(rgb, img.rgb.data(), 3 * n * sizeof(float));
    if (error) std::memcpy(error, img.error.data(), n * sizeof(float));
    if (hits) std::memcpy(hits, img.hits.data(), n * sizeof(float));
    if (coverage) std::memcpy(coverage, img.coverage.data(), n * sizeof(float));
  });
}

plm_status plm_result_write_exr(const plm_result* result, uint32_t mesh_id, const char* path) {
  return guarded("plm_result_write_exr", [&] {
    const plm::LightmapImage& img = lightmap_of(result, mesh_id, "plm_result_write_exr");
    require(path, "plm_result_write_exr", "path");
    plm::write_rgb_exr_atomic(path, img.width, img.height, img.rgb.data(), {"error", "hits"},
                              {img.error.data(), img.hits.data()});
  });
}

plm_status plm_write_lightmap_exr(const char* path, uint32_t width, uint32_t height, const float* rgb,
                                  const float* error, const float* hits) {
  return guarded("plm_write_lightmap_exr", [&] {
    require(path, "plm_write_lightmap_exr", "path");
    require(rgb, "plm_write_lightmap_exr", "rgb");
    require_image_size("plm_write_lightmap_exr", path, width, height);
    const std::vector<float> zeros(error && hits ? 0 : size_t(width) * height, 0.0f);
    plm::write_rgb_exr_atomic(path, width, height, rgb, {"error", "hits"},
                              {error ? error : zeros.data(), hits ? hits : zeros.data()});
  });
}

plm_status plm_write_heat_map_exr(const char* path, uint32_t width, uint32_t height, const float* values) {
  return guarded("plm_write_heat_map_exr", [&] {
    require(path, "plm_write_heat_map_exr", "path");
    require(values, "plm_write_heat_map_exr", "values");
    require_image_size("plm_write_heat_map_exr", path, width, height);
    const size_t n = size_t(width) * height;
    std::vector<float> rgb(3 * n);
    for (size_t t = 0; t < n; ++t) rgb[3 * t] = rgb[3 * t + 1] = rgb[3 * t + 2] = values[t];
    plm::write_exr_atomic(path, width, height, {"R", "G", "B"}, rgb.data(), true);
  });
}

plm_status plm_read_lightmap_exr(const char* path, uint32_t* width, uint32_t* height, float* rgb, float* error,
                                 float* hits) {
  return guarded("plm_read_lightmap_exr", [&] {
    require(path, "plm_read_lightmap_exr", "path");
    require(width, "plm_read_lightmap_exr", "width");
    require(height, "plm_read_lightmap_exr", "height");
    const bool size_only = !rgb && !error && !hits;
    uint32_t w = 0, h = 0;
    if (size_only) {
      plm::read_exr_channels(path, {}, w, h);
      *width = w;
      *height = h;
      return;
    }
    const std::vector<float> px = plm::read_exr_channels(path, {"R", "G", "B", "error", "hits"}, w, h);
    if (w != *width || h != *height)
      plm::fail(PLM_ERROR_INVALID_ARGUMENT, "plm_read_lightmap_exr: '", path, "' is ", w, " x ", h,
                ", the buffers are for ", *width, " x ", *height);
    const size_t n = size_t(w) * h;
    for (size_t t = 0; t < n; ++t) {
      if (rgb)
        for (size_t c = 0; c < 3; ++c) rgb[3 * t + c] = px[5 * t + c];
      if (error) error[t] = px[5 * t + 3];
      if (hits) hits[t] = px[5 * t + 4];
    }
  });
}

plm_status plm_scene_add_ol_group(plm_scene* scene, const char* name, uint32_t resolution, uint32_t* out_group) {
  return guarded("plm_scene_add_ol_group", [&] {
    require(scene, "plm_scene_add_ol_group", "scene");
    const uint32_t id = scene->scene.add_ol_group(name, resolution);
    if (out_group) *out_group = id;
  });
}

plm_status plm_scene_set_ol_group_backup(plm_scene* scene, uint32_t group, int backup) {
  return guarded("plm_scene_set_ol_group_backup", [&] {
    require(scene, "plm_scene_set_ol_group_backup", "scene");
    scene->scene.set_ol_group_backup(group, backup != 0);
  });
}

plm_status plm_scene_set_ol_group_limit_area(plm_scene* scene, uint32_t group, int limit_area) {
  return guarded("plm_scene_set_ol_group_limit_area", [&] {
    require(scene, "plm_scene_set_ol_group_limit_area", "scene");
    scene->scene.ol_group(group, "set OL group limit area").limit_area = limit_area != 0;
  });
}

plm_status plm_scene_set_mesh_ol_group(plm_scene* scene, uint32_t mesh, uint32_t group) {
  return guarded("plm_scene_set_mesh_ol_group", [&] {
    require(scene, "plm_scene_set_mesh_ol_group", "scene");
    scene->scene.set_mesh_ol_group(mesh, group);
  });
}

plm_status plm_scene_add_light_group(plm_scene* scene, const char* name, uint32_t* out_group) {
  return guarded("plm_scene_add_light_group", [&] {
    require(scene, "plm_scene_add_light_group", "scene");
    const uint32_t id = scene->scene.add_light_group(name);
    if (out_group) *out_group = id;
  });
}

plm_status plm_scene_set_light_group(plm_scene* scene, uint32_t light, uint32_t group) {
  return guarded("plm_scene_set_light_group", [&] {
    require(scene, "plm_scene_set_light_group", "scene");
    scene->scene.set_light_group(light, group);
  });
}

plm_status plm_scene_set_mesh_light_group(plm_scene* scene, uint32_t mesh, uint32_t group) {
  return guarded("plm_scene_set_mesh_light_group", [&] {
    require(scene, "plm_scene_set_mesh_light_group", "scene");
    scene->scene.set_mesh_light_group(mesh, group);
  });
}

plm_status plm_scene_set_world_light_group(plm_scene* scene, uint32_t group) {
  return guarded("plm_scene_set_world_light_group", [&] {
    require(scene, "plm_scene_set_world_light_group", "scene");
    scene->scene.set_world_light_group(group);
  });
}

uint32_t plm_result_layer_count(const plm_result* result) {
  return result ? uint32_t(result->output.layer_names.size()) : 0;
}

const char* plm_result_layer_name(const plm_result* result, uint32_t layer) {
  if (!result || layer >= result->output.layer_names.size()) return nullptr;
  return result->output.layer_names[layer].c_str();
}

plm_status plm_result_layer_error(const plm_result* result, uint32_t layer, double* out_relative_error) {
  return guarded("plm_result_layer_error", [&] {
    require(result, "plm_result_layer_error", "result");
    require(out_relative_error, "plm_result_layer_error", "out_relative_error");
    *out_relative_error = result_item(result->output.layer_errors, layer, "plm_result_layer_error", "layer", "layers");
  });
}

plm_status plm_result_copy_lightmap_layer(const plm_result* result, uint32_t mesh_id, uint32_t layer, float* rgb,
                                          float* error) {
  return guarded("plm_result_copy_lightmap_layer", [&] {
    const plm::LightmapImage& img = lightmap_of(result, mesh_id, "plm_result_copy_lightmap_layer");
    result_item(img.layer_rgb, layer, "plm_result_copy_lightmap_layer", "layer", "layers");
    const size_t n = size_t(img.width) * img.height;
    if (rgb) std::memcpy(rgb, img.layer_rgb[layer].data(), 3 * n * sizeof(float));
    if (error) std::memcpy(error, img.layer_error[layer].data(), n * sizeof(float));
  });
}

plm_status plm_result_write_layer_exr(const plm_result* result, uint32_t mesh_id, uint32_t layer, const char* path) {
  return guarded("plm_result_write_layer_exr", [&] {
    const plm::LightmapImage& img = lightmap_of(result, mesh_id, "plm_result_write_layer_exr");
    result_item(img.layer_rgb, layer, "plm_result_write_layer_exr", "layer", "layers");
    require(path, "plm_result_write_layer_exr", "path");
    plm::write_rgb_exr_atomic(path, img.width, img.height, img.layer_rgb[layer].data(), {"error", "hits"},
                              {img.layer_error[layer].data(), img.hits.data()});
  });
}

uint32_t plm_result_directional(const plm_result* result) {
  return result && result->output.directional ? 1 : 0;
}

plm_status plm_result_copy_lightmap_sh(const plm_result* result, uint32_t mesh_id, uint32_t band, float* rgb) {
  return guarded("plm_result_copy_lightmap_sh", [&] {
    const plm::LightmapImage& img = sh_lightmap_of(result, mesh_id, band, "plm_result_copy_lightmap_sh");
    require(rgb, "plm_result_copy_lightmap_sh", "rgb");
    plm::sh_band(img, band, rgb);
  });
}

plm_status plm_result_write_sh_exr(const plm_result* result, uint32_t mesh_id, uint32_t band, const char* path) {
  return guarded("plm_result_write_sh_exr", [&] {
    const plm::LightmapImage& img = sh_lightmap_of(result, mesh_id, band, "plm_result_write_sh_exr");
    require(path, "plm_result_write_sh_exr", "path");
    std::vector<float> rgb(3 * size_t(img.width) * img.height);
    plm::sh_band(img, band, rgb.data());
    plm::write_rgb_exr_atomic(path, img.width, img.height, rgb.data(), {"hits"}, {img.hits.data()});
  });
}

plm_status plm_result_ol(const plm_result* result, uint32_t group, const float** rgb, const float** error,
                         uint32_t* resolution) {
  return guarded("plm_result_ol", [&] {
    const plm::OlImage& img = ol_of(result, group, "plm_result_ol");
    if (rgb) *rgb = img.rgb.data();
    if (error) *error = img.error.data();
    if (resolution) *resolution = img.resolution;
  });
}

plm_status plm_result_ol_bins(const plm_result* result, uint32_t group, const float** area, const float** hits) {
  return guarded("plm_result_ol_bins", [&] {
    const plm::OlImage& img = ol_of(result, group, "plm_result_ol_bins");
    if (area) *area = img.area.data();
    if (hits) *hits = img.hits.data();
  });
}

plm_status plm_result_ol_stats(const plm_result* result, uint32_t group, plm_ol_stats* out_stats) {
  return guarded("plm_result_ol_stats", [&] {
    const plm::OlImage& img = ol_of(result, group, "plm_result_ol_stats");
    require(out_stats, "plm_result_ol_stats", "out_stats");
    plm::api::write_sized(out_stats, img.stats, "plm_result_ol_stats", "out_stats");
  });
}

plm_status plm_result_write_ol_exr(const plm_result* result, uint32_t group, const char* path) {
  return guarded("plm_result_write_ol_exr", [&] {
    const plm::OlImage& img = ol_of(result, group, "plm_result_write_ol_exr");
    require(path, "plm_result_write_ol_exr", "path");
    plm::write_rgb_exr_atomic(path, img.resolution, img.resolution, img.rgb.data(), {"area", "error", "hits"},
                              {img.area.data(), img.error.data(), img.hits.data()});
  });
}

void plm_lsystem_settings_default(plm_lsystem_settings* settings) {
  if (settings) *settings = plm::lsystem::default_lsystem_settings();
}

plm_status plm_scene_add_lsystem(plm_scene* scene, const char* name, const char* rules,
                                 const plm_lsystem_settings* settings, uint32_t* out_id) {
  return guarded("plm_scene_add_lsystem", [&] {
    require(scene, "plm_scene_add_lsystem", "scene");
    const plm_lsystem_settings s = lsystem_settings_or_default(settings, "plm_scene_add_lsystem");
    const uint32_t id = scene->scene.add_lsystem(name, rules, s);
    if (out_id) *out_id = id;
  });
}

plm_status plm_lsystem_flatten(const char* rules, const plm_lsystem_settings* settings, uint64_t max_primitives,
                               uint32_t* shapes, double* matrices, uint32_t* materials, uint64_t* out_count,
                               int* out_truncated) {
  return guarded("plm_lsystem_flatten", [&] {
    const plm_lsystem_settings s = lsystem_settings_or_default(settings, "plm_lsystem_flatten");
    if (max_primitives > (uint64_t(1) << 32))
      plm::fail(PLM_ERROR_INVALID_ARGUMENT, "plm_lsystem_flatten: max_primitives ", max_primitives,
                " exceeds 2^32");
    const plm::lsystem::FlattenResult r = plm::lsystem::flatten_lsystem(rules, s, size_t(max_primitives));
    for (size_t i = 0; i < r.primitives.size(); ++i) {
      const plm::lsystem::TurtlePrimitive& p = r.primitives[i];
      if (shapes) {
        switch (p.shape) {
          case plm::lsystem::ShapeKind::Cylinder: shapes[i] = PLM_CSG_CYLINDER; break;
          case plm::lsystem::ShapeKind::Sphere: shapes[i] = PLM_CSG_SPHERE; break;
          case plm::lsystem::ShapeKind::Cone: shapes[i] = PLM_CSG_CONE; break;
          case plm::lsystem::ShapeKind::Box: shapes[i] = PLM_CSG_BOX; break;
        }
      }
      if (matrices) std::memcpy(matrices + 12 * i, p.to_world, 12 * sizeof(double));
      if (materials) {
        const uint32_t t = uint32_t(std::max(p.material, 0));
        materials[i] = s.material_count && s.materials ? s.materials[std::min(t, s.material_count - 1)] : t;
      }
    }
    if (out_count) *out_count = r.primitives.size();
    if (out_truncated) *out_truncated = r.truncated ? 1 : 0;
  });
}

plm_status plm_result_lsystem_lookup(const plm_result* result, uint32_t lsystem, uint64_t count, const float* points,
                                     const float* normals, float* out_rgb) {
  return guarded("plm_result_lsystem_lookup", [&] {
    const plm::LSystemOutput& lo = lsystem_of(result, lsystem, "plm_result_lsystem_lookup");
    if (count == 0) return;
    require(points, "plm_result_lsystem_lookup", "points");
    require(normals, "plm_result_lsystem_lookup", "normals");
    require(out_rgb, "plm_result_lsystem_lookup", "out_rgb");
    for (uint64_t i = 0; i < count; ++i) {
      const plm::Vec3d p{points[3 * i], points[3 * i + 1], points[3 * i + 2]};
      plm::Vec3d n{normals[3 * i], normals[3 * i + 1], normals[3 * i + 2]};
      const double len = plm::length(n);
      if (!plm::is_finite(p) || !(len > 0.0) || !std::isfinite(len))
        plm::fail(PLM_ERROR_INVALID_ARGUMENT, "plm_result_lsystem_lookup: item ", i,
                  " has a non-finite point or a zero or non-finite normal");
      n = n / len;
      const plm::Vec3 v = lo.light_at(p, n);
      for (int c = 0; c < 3; ++c) out_rgb[3 * i + c] = v[c];
    }
  });
}

plm_status plm_result_lsystem_stats(const plm_result* result, uint32_t lsystem, plm_lsystem_stats* out_stats) {
  return guarded("plm_result_lsystem_stats", [&] {
    const plm::LSystemOutput& lo = lsystem_of(result, lsystem, "plm_result_lsystem_stats");
    require(out_stats, "plm_result_lsystem_stats", "out_stats");
    plm::api::write_sized(out_stats, lo.stats, "plm_result_lsystem_stats", "out_stats");
  });
}

}  // extern "C"

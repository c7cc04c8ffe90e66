// What the user described: materials, triangle meshes with lightmap UVs,
// lights and the world. Everything is validated on the way in, so the bake
// only sees legal data; degenerate triangles are kept and counted.
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "csg/csg.h"
#include "photonlm/photonlm.h"
#include "scene/lobe.h"
#include "util/math.h"

namespace plm {
class EnvironmentMap;
namespace lsystem {
class LSystemObject;
}
namespace subdiv {
struct Cage;
struct CageCopy;
}
struct PendingCage;

struct Material {
  std::string name;
  Vec3 albedo;
  Vec3 emission;  // radiance, both sides
  // Image textures (scene/texture.h), multiplied by albedo / emission; empty = none.
  std::string albedo_texture, emission_texture;
  uint32_t albedo_texture_flags = 0, emission_texture_flags = 0;  // PLM_TEXTURE_COLOR_*
  uint64_t albedo_texture_pixels = 0, emission_texture_pixels = 0;  // their sizes (the memory estimate)
  std::vector<Lobe> lobes;  // specular lobes (scene/lobe.h); empty: Lambertian
  // The diffuse part's model (plm_diffuse_model) and its roughness (Burley's).
  int32_t diffuse_model = PLM_DIFFUSE_LAMBERT;
  float diffuse_roughness = 0.0f;
};

struct Mesh {
  std::string name;
  // One padding element at the end: Embree reads 16 bytes at the last vertex.
  std::vector<Vec3> positions;
  uint32_t vertex_count = 0;
  std::vector<uint32_t> indices;  // 3 per triangle
  std::vector<float> uv;          // 6 per triangle, empty when no lightmap
  std::vector<uint32_t> material_ids;  // 1 per triangle
  std::vector<float> texture_uv;       // 6 per triangle, empty when none (textures use their mean)
  // Shading normals (smooth shading, custom split normals): one unit normal
  // per triangle corner, empty where every corner has its triangle's
  // geometric normal (a flat mesh pays nothing).
  std::vector<Vec3> normals;
  uint32_t lightmap_width = 0, lightmap_height = 0;
  int32_t csg_carrier = -1;  // the CSG solid this mesh tessellates (not traced), -1 for none
  int32_t ol_group = -1;  // orientation-lightmap group, -1 for none (a mesh has a lightmap or a group, not both)
  uint32_t light_group = 0;  // its emission's light group (Scene::light_groups index + 1; 0: the default group)
  // Subdivision meshes: the cage, whose limit surface gives the mesh's OL areas
  // (subdiv/limit_area.h); null for other meshes.
  std::shared_ptr<const subdiv::CageCopy> cage;
  // A subdivision mesh waiting for Scene::refine_cages (no triangles yet); null once refined.
  std::shared_ptr<PendingCage> pending;

  uint32_t triangle_count() const { return static_cast<uint32_t>(indices.size() / 3); }
  bool has_lightmap() const { return lightmap_width > 0; }
  Vec3 vertex(uint32_t tri, int corner) const { return positions[indices[3 * tri + corner]]; }
  bool smooth() const { return !normals.empty(); }
  // The shading normal at barycentrics (b1, b2) of corners 1 and 2 (Embree's
  // u, v): the corners' normals interpolated and normalised, or `geometric`
  // where they cancel out.
  Vec3 shading_normal(uint32_t tri, float b1, float b2, Vec3 geometric) const {
    const Vec3* c = &normals[3 * size_t(tri)];
    const Vec3 n = c[0] * (1.0f - b1 - b2) + c[1] * b1 + c[2] * b2;
    const float len2 = dot(n, n);
    return len2 > 1e-12f ? n * (1.0f / std::sqrt(len2)) : geometric;
  }
};

struct Light {
  std::string name;
  plm_light desc;
  uint32_t light_group = 0;  // Scene::light_groups index + 1; 0: the default group
};

// An orientation-lightmap group ([Thesis §6.2]): lightmap-less meshes whose
// light is stored per surface normal in one shared octahedral map.
struct CsgSolid {
  std::unique_ptr<csg::CsgObject> object;  // stable address: Embree keeps a pointer to it
  int32_t carrier = -1;                    // mesh that receives its light, -1 for none
};

struct OlGroup {
  std::string name;
  uint32_t resolution = 0;  // bins per side of the map; 0 = automatic (see bake.h)
  bool backup = false;      // its meshes keep their lightmaps; the OL backs up their indirect light
  bool limit_area = false;  // subdivision meshes' bin areas from their limit surface (subdiv/limit_area.h)
};

struct Scene {
  std::vector<Material> materials;
  std::vector<Mesh> meshes;
  std::vector<Light> lights;
  std::vector<OlGroup> ol_groups;
  std::vector<CsgSolid> csgs;
  // L-system objects (lsystem/lsystem_object.h); shared with bake results,
  // whose lookups trace them. Embree ids after the CSG solids.
  std::vector<std::shared_ptr<const lsystem::LSystemObject>> lsystems;
  Vec3 world{0, 0, 0};
  // An environment map as the world (scene/environment.h), null for the
  // uniform world; setting one clears the other.
  std::shared_ptr<const EnvironmentMap> world_map;
  // Whose Cycles the lights follow (plm_conventions;
  // docs/design/cycles-versions.md).
  int32_t conventions = PLM_CONVENTIONS_CYCLES_3_4;
  // Light groups (docs/design/light-groups.md): the names of the groups
  // declared; lights, emissive meshes and the world name one by its index + 1
  // (0: the default group, every emitter not given another).
  std::vector<std::string> light_groups;
  uint32_t world_light_group = 0;

  void set_conventions(int32_t value);
  uint32_t add_material(const char* name, const float albedo[3], const float emission[3]);
  // Appends a lobe (scene/lobe.cpp). Throws naming the material, the lobe and the bad field.
  void add_material_lobe(uint32_t material, const plm_lobe& lobe);
  bool has_lobes() const {
    for (const Material& m : materials)
      if (!m.lobes.empty()) return true;
    return false;
  }
  // Sets a material's diffuse model (plm_scene_set_material_diffuse). Throws naming the material.
  void set_material_diffuse(uint32_t material, int32_t model, float roughness);
  bool has_burley() const {
    for (const Material& m : materials)
      if (m.diffuse_model == PLM_DIFFUSE_BURLEY) return true;
    return false;
  }
  uint32_t add_mesh(const char* name, const float* positions, uint32_t vertex_count,
                    const uint32_t* indices, uint32_t triangle_count, const float* uv,
                    const uint32_t* material_ids, uint32_t width, uint32_t height);
  // Checks a mesh's triangles as add_mesh does (errors name `owner`) and puts
  // them into `mesh`; reads only the materials' count.
  void set_mesh_geometry(Mesh& mesh, const std::string& owner, const float* positions, uint32_t vertex_count,
                         const uint32_t* indices, uint32_t triangle_count, const float* uv,
                         const uint32_t* material_ids, uint32_t width, uint32_t height) const;
  // Subdivision meshes (scene/subdiv_meshes.cpp): the cage is checked and
  // copied here (errors name the mesh) and refined by refine_cages(), which
  // every use of the scene's triangles runs first; until then the mesh has
  // its name, lightmap size and groups, no triangles.
  uint32_t add_subdiv_mesh(const char* name, const subdiv::Cage& cage, uint32_t width, uint32_t height);
  // Refines every pending cage, in parallel on thread_count threads (0: all
  // cores); results do not depend on threads. Errors name the mesh (the
  // lowest id among those that failed), and again on every later call.
  void refine_cages(unsigned thread_count = 0);
  bool has_pending_cages() const;
  void set_pending_smooth(Mesh& mesh, bool smooth);  // set_mesh_smooth of a mesh still pending
  // set_mesh_normals and set_mesh_smooth's work on a mesh that has its triangles
  // (no refine_cages first; refine_cages itself uses them, one mesh per thread).
  void store_mesh_normals(uint32_t mesh, const float* normals);
  void store_smooth_normals(uint32_t mesh);
  uint32_t add_light(const char* name, const plm_light& light);
  void set_world(const float radiance[3]);
  void set_world_map(const float* rgb, uint32_t width, uint32_t height, const float rotation[9], float strength);
  void set_world_map_file(const char* path, const float rotation[9], float strength);
  // slot: plm_texture_slot; path NULL or "" removes. Throws for a bad index or an unreadable file.
  void set_material_texture(uint32_t material, int slot, const char* path, uint32_t flags);
  void set_mesh_texture_uv(uint32_t mesh, const float* uv);
  // 9 floats per triangle (x, y, z of each corner's normal); NULL removes them.
  void set_mesh_normals(uint32_t mesh, const float* normals);
  // Smooth: every corner takes its vertex's normal, the mean of the normals
  // of the triangles around the vertex weighted by their angle there (as
  // Blender computes a smooth face's normals); flat: no shading normals.
  void set_mesh_smooth(uint32_t mesh, bool smooth);
  bool has_textures() const {
    for (const Material& m : materials)
      if (!m.albedo_texture.empty() || !m.emission_texture.empty()) return true;
    return false;
  }
  uint32_t add_ol_group(const char* name, uint32_t resolution);
  // Declares a light group; returns its id (1, 2, ...; 0 is the default
  // group). Throws for a name that is empty, "default", taken, or holds
  // other characters than letters, digits, '_' and '-' (it names files).
  uint32_t add_light_group(const char* name);
  // Puts a light, a mesh's emission or the world into a group (0: the default
  // group). Throws naming the bad index.
  void set_light_group(uint32_t light, uint32_t group);
  void set_mesh_light_group(uint32_t mesh, uint32_t group);
  void set_world_light_group(uint32_t group);
  // Puts a mesh into a group (a later call moves it). Throws for bad indices
  // and for a mesh that has a lightmap.
  void set_mesh_ol_group(uint32_t mesh, uint32_t group);
  void set_ol_group_backup(uint32_t group, bool backup) { ol_group(group, "set OL group backup").backup = backup; }
  OlGroup& ol_group(uint32_t group, const char* what);  // fails naming `what` if there is no such group
  // A mesh with its own texels (direct pass, photon sums): no OL, or a backup OL.
  bool own_texels(const Mesh& m) const {
    return m.has_lightmap() && m.csg_carrier < 0 && (m.ol_group < 0 || ol_groups[size_t(m.ol_group)].backup);
  }
  uint32_t add_csg(const char* name, const plm_csg_primitive* primitives, uint32_t primitive_count,
                   const plm_csg_node* nodes, uint32_t node_count, const uint32_t* children, uint32_t child_count,
                   uint32_t root);
  void set_csg_carrier(uint32_t csg, uint32_t mesh);
  uint32_t add_lsystem(const char* name, const char* rules, const plm_lsystem_settings& settings);
};

// Blender's defaults for a light of the given type.
plm_light default_light(plm_light_type type);

}  // namespace plm

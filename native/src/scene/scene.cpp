#include "scene/scene.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "lsystem/lsystem_object.h"
#include "ol/octahedral.h"
#include "scene/environment.h"
#include "scene/texture.h"
#include "util/error.h"

namespace plm {
namespace {

// How errors and warnings name an object: 'name', or '#index' when unnamed
// (the same name the scene keeps for it).
std::string quoted_or(const char* name, size_t index) {
  return std::string("'") + (name && *name ? std::string(name) : "#" + std::to_string(index)) + "'";
}

void check_rgb(const float* v, const char* what, const std::string& owner, float max_value) {
  for (int c = 0; c < 3; ++c) {
    if (!std::isfinite(v[c]) || v[c] < 0.0f || v[c] > max_value)
      fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": ", what, "[", c, "] = ", v[c], " is not in [0, ",
           max_value, "]");
  }
}

// items[index], or an error: "<what>: <noun> <index> does not exist (the scene has <count> <plural>)".
template <typename Items>
auto& existing(Items& items, uint32_t index, const std::string& what, const char* noun, const char* plural) {
  if (index >= items.size())
    fail(PLM_ERROR_INVALID_ARGUMENT, what, ": ", noun, " ", index, " does not exist (the scene has ", items.size(), " ",
         plural, ")");
  return items[index];
}

}  // namespace

uint32_t Scene::add_material(const char* name, const float albedo[3], const float emission[3]) {
  const std::string owner = "material " + quoted_or(name, materials.size());
  if (!albedo || !emission) fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": albedo and emission must not be NULL");
  check_rgb(albedo, "albedo", owner, 1.0f);
  check_rgb(emission, "emission", owner, 1e30f);
  Material m;
  m.name = name ? name : "";
  m.albedo = {albedo[0], albedo[1], albedo[2]};
  m.emission = {emission[0], emission[1], emission[2]};
  materials.push_back(m);
  return static_cast<uint32_t>(materials.size() - 1);
}

uint32_t Scene::add_mesh(const char* name, const float* positions, uint32_t vertex_count,
                         const uint32_t* indices, uint32_t triangle_count, const float* uv,
                         const uint32_t* material_ids, uint32_t width, uint32_t height) {
  Mesh mesh;
  mesh.name = name && *name ? name : "#" + std::to_string(meshes.size());
  set_mesh_geometry(mesh, "mesh " + quoted_or(name, meshes.size()), positions, vertex_count, indices, triangle_count,
                    uv, material_ids, width, height);
  meshes.push_back(std::move(mesh));
  return static_cast<uint32_t>(meshes.size() - 1);
}

void Scene::set_mesh_geometry(Mesh& mesh, const std::string& owner, const float* positions, uint32_t vertex_count,
                              const uint32_t* indices, uint32_t triangle_count, const float* uv,
                              const uint32_t* material_ids, uint32_t width, uint32_t height) const {
  if (vertex_count == 0 || triangle_count == 0)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": has ", vertex_count, " vertices and ", triangle_count,
         " triangles; both must be > 0");
  if (!positions || !indices) fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": positions and indices must not be NULL");
  if ((width == 0) != (height == 0))
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": lightmap size ", width, " x ", height,
         " is invalid (both 0 for no lightmap, or both > 0)");
  if (width > 16384 || height > 16384)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": lightmap size ", width, " x ", height, " exceeds 16384");
  if (width > 0 && !uv)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": has a ", width, " x ", height,
         " lightmap but no lightmap UVs (pass UVs, or size 0 x 0 for geometry only)");

  mesh.vertex_count = vertex_count;
  mesh.positions.resize(size_t(vertex_count) + 1);
  for (uint32_t i = 0; i < vertex_count; ++i) {
    const Vec3 p{positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]};
    if (!is_finite(p))
      fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": vertex ", i, " has a non-finite position (", p.x, ", ", p.y,
           ", ", p.z, ")");
    if (max_abs_component(p) > kMaxCoordinate)
      fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": vertex ", i, " at (", p.x, ", ", p.y, ", ", p.z,
           ") is beyond the engine's range of +-", kMaxCoordinate, " m");
    mesh.positions[i] = p;
  }
  mesh.indices.assign(indices, indices + size_t(triangle_count) * 3);
  for (size_t k = 0; k < mesh.indices.size(); ++k) {
    if (mesh.indices[k] >= vertex_count)
      fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": triangle ", k / 3, " corner ", k % 3, " uses vertex ",
           mesh.indices[k], " but the mesh has ", vertex_count, " vertices");
  }
  if (width > 0) {
    mesh.uv.assign(uv, uv + size_t(triangle_count) * 6);
    for (size_t k = 0; k < mesh.uv.size(); ++k) {
      if (!std::isfinite(mesh.uv[k]))
        fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": triangle ", k / 6, " corner ", (k % 6) / 2,
             " has a non-finite lightmap UV");
      // Outside [0, 1] is legal (warned at bake time); beyond +-1e4 is surely broken.
      if (std::fabs(mesh.uv[k]) > 1e4f)
        fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": triangle ", k / 6, " corner ", (k % 6) / 2,
             " has the lightmap UV coordinate ", mesh.uv[k], ", far outside the [0, 1] square");
    }
  }
  if (material_ids) {
    mesh.material_ids.assign(material_ids, material_ids + triangle_count);
    for (uint32_t t = 0; t < triangle_count; ++t) {
      if (mesh.material_ids[t] >= materials.size())
        fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": triangle ", t, " uses material ", mesh.material_ids[t],
             " but the scene has ", materials.size(), " materials (add materials before meshes)");
    }
  } else {
    mesh.material_ids.assign(triangle_count, 0u);
  }
  mesh.lightmap_width = width;
  mesh.lightmap_height = height;
}

plm_light default_light(plm_light_type type) {
  plm_light l;
  std::memset(&l, 0, sizeof(l));
  l.struct_size = uint32_t(sizeof l);
  l.type = type;
  l.color[0] = l.color[1] = l.color[2] = 1.0f;
  l.power = type == PLM_LIGHT_SUN ? 1.0f : 1000.0f;
  for (int i = 0; i < 4; ++i) l.matrix[5 * i] = 1.0f;
  l.radius = 0.1f;
  l.angle = 0.00918043f;  // Blender's default sun angle, 0.526 degrees
  l.size_x = l.size_y = 1.0f;
  l.spot_size = 45.0f * kPi / 180.0f;
  l.spot_blend = 0.15f;
  return l;
}

uint32_t Scene::add_light(const char* name, const plm_light& l) {
  const std::string owner = "light " + quoted_or(name, lights.size());
  if (l.type < PLM_LIGHT_POINT || l.type > PLM_LIGHT_PORTAL)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": unknown light type ", l.type);
  check_rgb(l.color, "color", owner, 1e30f);
  if (!std::isfinite(l.power) || l.power < 0.0f)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": power ", l.power, " must be finite and >= 0");
  for (int i = 0; i < 16; ++i) {
    if (!std::isfinite(l.matrix[i])) fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": matrix element ", i, " is not finite");
    if (std::fabs(l.matrix[i]) > kMaxCoordinate)
      fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": matrix element ", i, " = ", l.matrix[i],
           " is beyond the engine's range of +-", kMaxCoordinate);
  }
  // Fields a type does not use must still be numbers: NaN or Inf anywhere is a
  // bad input (a program filling the struct wrongly), not something to ignore.
  const std::pair<const char*, float> fields[] = {{"radius", l.radius},       {"spot_size", l.spot_size},
                                                  {"spot_blend", l.spot_blend}, {"angle", l.angle},
                                                  {"size_x", l.size_x},       {"size_y", l.size_y}};
  for (const auto& [field, value] : fields)
    if (!std::isfinite(value)) fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": ", field, " ", value, " is not finite");
  const Affine3f m = Affine3f::from_array(l.matrix);
  switch (l.type) {
    case PLM_LIGHT_POINT:
    case PLM_LIGHT_SPOT:
      if (!std::isfinite(l.radius) || l.radius < 0.0f || l.radius > kMaxCoordinate)
        fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": radius ", l.radius, " must be in [0, ", kMaxCoordinate, "] m");
      if (l.type == PLM_LIGHT_SPOT) {
        if (!(l.spot_size > 0.0f && l.spot_size <= kPi))
          fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": spot_size ", l.spot_size, " must be in (0, pi] radians");
        if (!(l.spot_blend >= 0.0f && l.spot_blend <= 1.0f))
          fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": spot_blend ", l.spot_blend, " must be in [0, 1]");
        if (length(m.vector({0, 0, 1})) <= 0.0f)
          fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": matrix has no direction (zero scale)");
      }
      break;
    case PLM_LIGHT_SUN:
      if (!(l.angle >= 0.0f && l.angle < kPi))
        fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": angle ", l.angle, " must be in [0, pi) radians");
      if (length(m.vector({0, 0, 1})) <= 0.0f)
        fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": matrix has no direction (zero scale)");
      break;
    case PLM_LIGHT_AREA_RECT:
    case PLM_LIGHT_AREA_DISK:
    case PLM_LIGHT_PORTAL: {
      const char* what = l.type == PLM_LIGHT_PORTAL ? "portal" : "area light";
      if (!(l.size_x > 0.0f && l.size_y > 0.0f) || !std::isfinite(l.size_x) || !std::isfinite(l.size_y))
        fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": ", what, " size ", l.size_x, " x ", l.size_y,
             " must be > 0 (a zero-area light emits nothing)");
      const Vec3 n = cross(m.vector({l.size_x, 0, 0}), m.vector({0, l.size_y, 0}));
      if (!(length(n) > 0.0f))
        fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": the matrix scales the ", what, " to zero area");
      if (!(max_abs_component(m.vector({l.size_x, 0, 0})) <= kMaxCoordinate &&
            max_abs_component(m.vector({0, l.size_y, 0})) <= kMaxCoordinate))
        fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": ", what, " size ", l.size_x, " x ", l.size_y,
             " (after the matrix's scale) is beyond the engine's range of ", kMaxCoordinate, " m");
      break;
    }
  }
  lights.push_back({name && *name ? name : "#" + std::to_string(lights.size()), l});
  return static_cast<uint32_t>(lights.size() - 1);
}

void Scene::set_conventions(int32_t value) {
  if (value != PLM_CONVENTIONS_CYCLES_3_4 && value != PLM_CONVENTIONS_CYCLES_4)
    fail(PLM_ERROR_INVALID_ARGUMENT, "conventions ", value,
         " are unknown (PLM_CONVENTIONS_CYCLES_3_4 = 0, PLM_CONVENTIONS_CYCLES_4 = 1)");
  conventions = value;
}

void Scene::set_world(const float radiance[3]) {
  if (!radiance) fail(PLM_ERROR_INVALID_ARGUMENT, "world: radiance must not be NULL");
  check_rgb(radiance, "radiance", "world", 1e30f);
  world = {radiance[0], radiance[1], radiance[2]};
  world_map.reset();
}

void Scene::set_world_map(const float* rgb, uint32_t width, uint32_t height, const float rotation[9],
                          float strength) {
  world_map = std::make_shared<const EnvironmentMap>(rgb, width, height, rotation, strength, "world map");
  world = {0, 0, 0};
}

void Scene::set_world_map_file(const char* path, const float rotation[9], float strength) {
  if (!path || !*path) fail(PLM_ERROR_INVALID_ARGUMENT, "world map: path must not be NULL or empty");
  world_map = std::make_shared<const EnvironmentMap>(EnvironmentMap::from_file(path, rotation, strength));
  world = {0, 0, 0};
}

uint32_t Scene::add_light_group(const char* name) {
  const std::string owner = "light group " + quoted_or(name, light_groups.size());
  if (!name || !*name) fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": the name must not be empty");
  const std::string n = name;
  if (n.size() > 64) fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": the name is longer than 64 characters");
  for (const char c : n)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-'))
      fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": the name holds '", std::string(1, c),
           "' (letters, digits, '_' and '-' only: it names the layer's files)");
  if (n == "default") fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": 'default' is the default group's name");
  if (std::find(light_groups.begin(), light_groups.end(), n) != light_groups.end())
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": a light group of that name exists");
  light_groups.push_back(n);
  return uint32_t(light_groups.size());
}

namespace {
void check_light_group(const Scene& s, uint32_t group, const std::string& owner) {
  if (group > s.light_groups.size())
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": light group ", group, " does not exist (",
         s.light_groups.size(), " declared; 0 is the default group)");
}
}  // namespace

void Scene::set_light_group(uint32_t light, uint32_t group) {
  if (light >= lights.size())
    fail(PLM_ERROR_INVALID_ARGUMENT, "set light group: light ", light, " does not exist (", lights.size(), " lights)");
  check_light_group(*this, group, "light '" + lights[light].name + "'");
  lights[light].light_group = group;
}

void Scene::set_mesh_light_group(uint32_t mesh, uint32_t group) {
  if (mesh >= meshes.size())
    fail(PLM_ERROR_INVALID_ARGUMENT, "set mesh light group: mesh ", mesh, " does not exist (", meshes.size(), " meshes)");
  check_light_group(*this, group, "mesh '" + meshes[mesh].name + "'");
  meshes[mesh].light_group = group;
}

void Scene::set_world_light_group(uint32_t group) {
  check_light_group(*this, group, "world");
  world_light_group = group;
}

uint32_t Scene::add_ol_group(const char* name, uint32_t resolution) {
  const std::string owner = "OL group " + quoted_or(name, ol_groups.size()) + " (" + std::to_string(ol_groups.size()) + ")";
  if (resolution > ol::kMaxOlResolution)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": resolution ", resolution, " exceeds ", ol::kMaxOlResolution,
         " bins per side (0 = automatic)");
  ol_groups.push_back({name && *name ? name : "#" + std::to_string(ol_groups.size()), resolution});
  return static_cast<uint32_t>(ol_groups.size() - 1);
}

void Scene::set_material_texture(uint32_t material, int slot, const char* path, uint32_t flags) {
  Material& m = existing(materials, material, "set material texture", "material", "materials");
  const std::string owner = "material " + quoted_or(m.name.c_str(), material) + " (" + std::to_string(material) + ")";
  if (slot != PLM_TEXTURE_ALBEDO && slot != PLM_TEXTURE_EMISSION)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": texture slot ", slot,
         " is not PLM_TEXTURE_ALBEDO (0) or PLM_TEXTURE_EMISSION (1)");
  if (flags > PLM_TEXTURE_COLOR_SRGB)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": texture flags ", flags,
         " are not a PLM_TEXTURE_COLOR_* value (0, 1, 2)");
  const std::string file = path ? path : "";
  const uint64_t pixels = file.empty() ? 0 : check_texture_file(file, owner);
  (slot == PLM_TEXTURE_ALBEDO ? m.albedo_texture : m.emission_texture) = file;
  (slot == PLM_TEXTURE_ALBEDO ? m.albedo_texture_pixels : m.emission_texture_pixels) = pixels;
  (slot == PLM_TEXTURE_ALBEDO ? m.albedo_texture_flags : m.emission_texture_flags) = flags;
}

void Scene::set_material_diffuse(uint32_t material, int32_t model, float roughness) {
  Material& m = existing(materials, material, "set material diffuse", "material", "materials");
  const std::string owner = "material " + quoted_or(m.name.c_str(), material) + " (" + std::to_string(material) + ")";
  if (model != PLM_DIFFUSE_LAMBERT && model != PLM_DIFFUSE_BURLEY)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": diffuse model ", model,
         " is not PLM_DIFFUSE_LAMBERT (0) or PLM_DIFFUSE_BURLEY (1)");
  if (!(roughness >= 0.0f && roughness <= 1.0f))
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": diffuse roughness ", roughness, " is not in [0, 1]");
  m.diffuse_model = model;
  m.diffuse_roughness = roughness;
}

void Scene::set_mesh_texture_uv(uint32_t mesh, const float* uv) {
  if (existing(meshes, mesh, "set mesh texture UV", "mesh", "meshes").pending) refine_cages();
  Mesh& m = meshes[mesh];
  if (!uv) {
    m.texture_uv.clear();
    return;
  }
  std::vector<float> values(uv, uv + size_t(m.triangle_count()) * 6);
  for (size_t k = 0; k < values.size(); ++k)
    if (!std::isfinite(values[k]))
      fail(PLM_ERROR_INVALID_ARGUMENT, "mesh '", m.name, "' (", mesh, "): triangle ", k / 6, " corner ", (k % 6) / 2,
           " has a non-finite texture UV");
  m.texture_uv.swap(values);
}

void Scene::set_mesh_normals(uint32_t mesh, const float* normals) {
  if (existing(meshes, mesh, "set mesh normals", "mesh", "meshes").pending) refine_cages();
  store_mesh_normals(mesh, normals);
}

void Scene::store_mesh_normals(uint32_t mesh, const float* normals) {
  Mesh& m = meshes[mesh];
  m.normals.clear();
  if (!normals) return;
  std::vector<Vec3> values(size_t(m.triangle_count()) * 3);
  bool flat = true;
  for (uint32_t t = 0; t < m.triangle_count(); ++t) {
    const Vec3 p0 = m.vertex(t, 0), p1 = m.vertex(t, 1), p2 = m.vertex(t, 2);
    const Vec3 g = degenerate_triangle(p0, p1, p2) ? Vec3{} : normalize(cross(p1 - p0, p2 - p0));
    for (int c = 0; c < 3; ++c) {
      const float* v = &normals[9 * size_t(t) + 3 * size_t(c)];
      Vec3 n{v[0], v[1], v[2]};
      if (!is_finite(n))
        fail(PLM_ERROR_INVALID_ARGUMENT, "mesh '", m.name, "' (", mesh, "): triangle ", t, " corner ", c,
             " has a non-finite normal (", n.x, ", ", n.y, ", ", n.z, ")");
      const float len2 = dot(n, n);
      // A zero normal (a flat-shaded face, a degenerate one) shades with the geometric one.
      n = len2 > 1e-20f ? n * (1.0f / std::sqrt(len2)) : g;
      flat = flat && (dot(g, g) == 0.0f || dot(n - g, n - g) < 1e-12f);
      values[3 * size_t(t) + size_t(c)] = n;
    }
  }
  if (!flat) m.normals.swap(values);
}

void Scene::set_mesh_smooth(uint32_t mesh, bool smooth) {
  Mesh& m = existing(meshes, mesh, "set mesh smooth", "mesh", "meshes");
  if (m.pending) {  // applied after the refinement (refine_cages), with it
    set_pending_smooth(m, smooth);
    return;
  }
  if (!smooth) {
    m.normals.clear();
    return;
  }
  store_smooth_normals(mesh);
}

void Scene::store_smooth_normals(uint32_t mesh) {
  const Mesh& m = meshes[mesh];
  // Each corner's share of its vertex normal (its triangle's normal weighted by the corner's
  // angle) in parallel, a block of triangles at a time; the shares are then added up in
  // triangle order, so the sums do not depend on threads.
  constexpr uint32_t kBlock = 1u << 16, kGrain = 2048;
  std::vector<Vec3d> vertex(m.vertex_count), share(size_t(std::min(kBlock, m.triangle_count())) * 3);
  std::vector<uint8_t> used(share.size() / 3);
  for (uint32_t first = 0; first < m.triangle_count(); first += kBlock) {
    const uint32_t count = std::min(kBlock, m.triangle_count() - first);
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, count, kGrain), [&](const tbb::blocked_range<uint32_t>& r) {
      for (uint32_t i = r.begin(); i < r.end(); ++i) {
        const uint32_t t = first + i;
        Vec3d p[3];
        for (int c = 0; c < 3; ++c) p[c] = to_double(m.vertex(t, c));
        const Vec3d n = cross(p[1] - p[0], p[2] - p[0]);
        const double len = length(n);
        used[i] = len > 0.0;
        if (!used[i]) continue;
        for (int c = 0; c < 3; ++c) {
          const Vec3d a = p[(c + 1) % 3] - p[c], b = p[(c + 2) % 3] - p[c];
          const double angle = std::atan2(length(cross(a, b)), dot(a, b));
          share[3 * size_t(i) + size_t(c)] = n * (angle / len);
        }
      }
    });
    for (uint32_t i = 0; i < count; ++i) {
      if (!used[i]) continue;
      for (int c = 0; c < 3; ++c) {
        Vec3d& v = vertex[m.indices[3 * (size_t(first) + i) + size_t(c)]];
        v = v + share[3 * size_t(i) + size_t(c)];
      }
    }
  }
  std::vector<float> corners(size_t(m.triangle_count()) * 9);
  for (size_t k = 0; k < m.indices.size(); ++k) {
    const Vec3d n = vertex[m.indices[k]];
    corners[3 * k] = float(n.x), corners[3 * k + 1] = float(n.y), corners[3 * k + 2] = float(n.z);
  }
  store_mesh_normals(mesh, corners.data());
}

void Scene::set_mesh_ol_group(uint32_t mesh, uint32_t group) {
  Mesh& m = existing(meshes, mesh, "set mesh OL group", "mesh", "meshes");
  existing(ol_groups, group, "set mesh OL group: mesh '" + m.name + "' (" + std::to_string(mesh) + ")", "OL group",
           "OL groups");
  m.ol_group = int32_t(group);
}

OlGroup& Scene::ol_group(uint32_t group, const char* what) {
  return existing(ol_groups, group, what, "OL group", "OL groups");
}

uint32_t Scene::add_csg(const char* name, const plm_csg_primitive* primitives, uint32_t primitive_count,
                       const plm_csg_node* nodes, uint32_t node_count, const uint32_t* children,
                       uint32_t child_count, uint32_t root) {
  const std::string label = "CSG solid " + quoted_or(name, csgs.size());
  constexpr uint32_t kMaxCount = 1u << 24;
  if (primitive_count == 0 || !primitives)
    fail(PLM_ERROR_INVALID_ARGUMENT, label, ": no primitives");
  if (node_count == 0 || !nodes) fail(PLM_ERROR_INVALID_ARGUMENT, label, ": no tree nodes");
  if (child_count && !children) fail(PLM_ERROR_INVALID_ARGUMENT, label, ": children is NULL");
  if (primitive_count > kMaxCount || node_count > kMaxCount || child_count > kMaxCount)
    fail(PLM_ERROR_INVALID_ARGUMENT, label, ": more than 2^24 primitives, nodes or children");
  csg::CsgDesc desc;
  desc.name = name && *name ? name : "#" + std::to_string(csgs.size());
  for (uint32_t i = 0; i < primitive_count; ++i) {
    const plm_csg_primitive& p = primitives[i];
    if (p.shape > PLM_CSG_HALF_SPACE)
      fail(PLM_ERROR_INVALID_ARGUMENT, label, ": primitive ", i, ": shape ", p.shape, " is not a plm_csg_shape");
    const uint32_t material_limit = std::max<uint32_t>(1, uint32_t(materials.size()));
    if (p.material >= material_limit)
      fail(PLM_ERROR_INVALID_ARGUMENT, label, ": primitive ", i, ": material ", p.material, " does not exist (",
           materials.size(), " materials)");
    csg::PrimitiveDesc d;
    d.shape = csg::Shape(p.shape);
    std::copy(p.matrix, p.matrix + 12, d.to_world);
    d.major_radius = p.major_radius;
    d.minor_radius = p.minor_radius;
    desc.primitives.push_back(d);
    desc.materials.push_back(p.material);
  }
  for (uint32_t i = 0; i < node_count; ++i) {
    if (nodes[i].op > PLM_CSG_LEAF)
      fail(PLM_ERROR_INVALID_ARGUMENT, label, ": node ", i, ": op ", nodes[i].op, " is not a plm_csg_op");
    desc.nodes.push_back({csg::Op(nodes[i].op), nodes[i].first, nodes[i].count});
  }
  desc.children.assign(children, children + child_count);
  desc.root = root;
  csgs.push_back({std::make_unique<csg::CsgObject>(desc), -1});  // validates; throws naming the item
  return static_cast<uint32_t>(csgs.size() - 1);
}

void Scene::set_csg_carrier(uint32_t csg, uint32_t mesh) {
  existing(csgs, csg, "set CSG carrier", "CSG solid", "CSG solids");
  const std::string label = "set CSG carrier: CSG solid '" + csgs[csg].object->name() + "' (" + std::to_string(csg) + ")";
  Mesh& m = existing(meshes, mesh, label, "mesh", "meshes");
  if (!m.has_lightmap())
    fail(PLM_ERROR_INVALID_ARGUMENT, label, ": mesh '", m.name, "' (", mesh, ") has no lightmap to receive its light");
  if (m.csg_carrier >= 0 && uint32_t(m.csg_carrier) != csg)
    fail(PLM_ERROR_INVALID_ARGUMENT, label, ": mesh '", m.name, "' (", mesh, ") already carries CSG solid ",
         m.csg_carrier);
  if (csgs[csg].carrier >= 0 && uint32_t(csgs[csg].carrier) != mesh) meshes[size_t(csgs[csg].carrier)].csg_carrier = -1;
  csgs[csg].carrier = int32_t(mesh);
  m.csg_carrier = int32_t(csg);
}

uint32_t Scene::add_lsystem(const char* name, const char* rules, const plm_lsystem_settings& settings) {
  const std::string label = name && *name ? std::string(name) : "#" + std::to_string(lsystems.size());
  lsystems.push_back(std::make_shared<const lsystem::LSystemObject>(label, rules, settings, materials.size()));
  return static_cast<uint32_t>(lsystems.size() - 1);
}

}  // namespace plm

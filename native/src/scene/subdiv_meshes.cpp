// Subdivision meshes of a scene: the add call checks and copies the cage (so a
// cage the engine refuses fails there, naming the mesh); refine_cages() refines
// all cages added since, one TBB task per cage (a large cage also splits its
// per-vertex work), before anything reads the scene's triangles.
#include <algorithm>
#include <cstdint>
#include <exception>
#include <new>
#include <unordered_map>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "scene/scene.h"
#include "subdiv/subdiv.h"
#include "util/error.h"

namespace plm {

struct PendingCage {
  subdiv::PreparedCagePtr cage;  // consumed by the refinement
  std::string owner;             // how errors name the mesh
  bool smooth = false;           // set_mesh_smooth before the refinement
  // A refinement that failed: its error, raised again by every later refine_cages().
  plm_status status = PLM_OK;
  std::string error;
};

uint32_t Scene::add_subdiv_mesh(const char* name, const subdiv::Cage& cage, uint32_t width, uint32_t height) {
  const size_t index = meshes.size();
  const std::string label = name && *name ? std::string(name) : "#" + std::to_string(index);
  const std::string owner = "mesh '" + label + "'";
  if ((width == 0) != (height == 0))
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": lightmap size ", width, " x ", height,
         " is invalid (both 0 for no lightmap, or both > 0)");
  if (width > 16384 || height > 16384)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": lightmap size ", width, " x ", height, " exceeds 16384");
  if (width > 0 && !cage.uv)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": has a ", width, " x ", height,
         " lightmap but no lightmap UVs (pass UVs, or size 0 x 0 for geometry only)");
  if (cage.material_ids && cage.face_sizes) {
    for (uint32_t f = 0; f < cage.face_count; ++f)
      if (cage.material_ids[f] >= materials.size())
        fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": cage face ", f, " uses material ", cage.material_ids[f],
             " but the scene has ", materials.size(), " materials (add materials before meshes)");
  }
  auto pending = std::make_shared<PendingCage>();
  pending->cage = subdiv::prepare(owner, cage);
  pending->owner = owner;
  Mesh mesh;
  mesh.name = label;
  mesh.lightmap_width = width;
  mesh.lightmap_height = height;
  // Kept for the OL areas on the limit surface, should the mesh join an OL group.
  mesh.cage = subdiv::shape(*pending->cage);
  mesh.pending = std::move(pending);
  meshes.push_back(std::move(mesh));
  return static_cast<uint32_t>(index);
}

bool Scene::has_pending_cages() const {
  return std::any_of(meshes.begin(), meshes.end(), [](const Mesh& m) { return m.pending != nullptr; });
}

void Scene::set_pending_smooth(Mesh& mesh, bool smooth) {
  mesh.pending->smooth = smooth;
  mesh.normals.clear();
}

namespace {

// Runs f; an exception it throws becomes p's error.
template <typename F>
void keep_error(PendingCage& p, F&& f) {
  try {
    f();
  } catch (const Error& e) {
    p.status = e.status();
    p.error = e.what();
  } catch (const std::bad_alloc&) {
    p.status = PLM_ERROR_OUT_OF_MEMORY;
    p.error = p.owner + ": out of memory while refining the subdivision cage";
  } catch (const std::exception& e) {
    p.status = PLM_ERROR_INTERNAL;
    p.error = p.owner + ": internal error while refining the subdivision cage: " + e.what();
  }
}

}  // namespace

void Scene::refine_cages(unsigned thread_count) {
  std::vector<uint32_t> ids;
  for (size_t id = 0; id < meshes.size(); ++id)
    if (meshes[id].pending) ids.push_back(uint32_t(id));
  if (ids.empty()) return;
  // Cages of one topology (copies of a mesh) share OpenSubdiv's refinement plan: the
  // first of them, its leader, makes it.
  struct Group {
    uint32_t leader;
    subdiv::RefinementPlanPtr plan;
  };
  std::vector<Group> groups;
  std::vector<size_t> group_of(ids.size(), SIZE_MAX);
  {
    std::unordered_map<uint64_t, std::vector<size_t>> by_hash;  // topology hash -> groups
    for (size_t k = 0; k < ids.size(); ++k) {
      const PendingCage& p = *meshes[ids[k]].pending;
      if (p.status != PLM_OK) continue;  // failed before: its cage is gone
      std::vector<size_t>& candidates = by_hash[subdiv::topology_hash(*p.cage)];
      for (size_t g : candidates)
        if (subdiv::same_topology(*meshes[groups[g].leader].pending->cage, *p.cage)) group_of[k] = g;
      if (group_of[k] == SIZE_MAX) {
        group_of[k] = groups.size();
        candidates.push_back(groups.size());
        groups.push_back(Group{ids[k], nullptr});
      }
    }
  }
  // Each task writes its own group or mesh only; the scene's vectors keep their sizes meanwhile.
  const int threads = thread_count ? int(thread_count) : tbb::task_arena::automatic;
  tbb::task_arena arena(threads);
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, groups.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t g = r.begin(); g < r.end(); ++g) {
        PendingCage& p = *meshes[groups[g].leader].pending;
        keep_error(p, [&] { groups[g].plan = subdiv::plan(p.owner, *p.cage); });
      }
    });
    tbb::parallel_for(tbb::blocked_range<size_t>(0, ids.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t k = r.begin(); k < r.end(); ++k) {
        if (group_of[k] == SIZE_MAX) continue;
        const uint32_t id = ids[k];
        Mesh& mesh = meshes[id];
        PendingCage& p = *mesh.pending;
        const Group& group = groups[group_of[k]];
        if (!group.plan) {  // its leader's plan failed
          if (id != group.leader) {
            const PendingCage& leader = *meshes[group.leader].pending;
            p.status = leader.status;
            p.error = p.owner + ": its topology's refinement failed (" + leader.error + ")";
          }
          continue;
        }
        keep_error(p, [&] {
          const subdiv::RefinedMesh r = subdiv::refine(*group.plan, *p.cage);
          set_mesh_geometry(mesh, p.owner, r.positions.data(), r.vertex_count(), r.indices.data(),
                            r.triangle_count(), r.uv.empty() ? nullptr : r.uv.data(),
                            r.material_ids.empty() ? nullptr : r.material_ids.data(), mesh.lightmap_width,
                            mesh.lightmap_height);
          if (p.smooth) store_smooth_normals(id);
        });
      }
    });
  });
  groups.clear();  // the plans, before the cages they were made from
  for (uint32_t id : ids) {
    Mesh& mesh = meshes[id];
    if (mesh.pending->status == PLM_OK) mesh.pending.reset();
  }
  for (uint32_t id : ids) {
    const Mesh& mesh = meshes[id];
    if (mesh.pending) {
      mesh.pending->cage.reset();
      fail(mesh.pending->status, mesh.pending->error);
    }
  }
}

}  // namespace plm

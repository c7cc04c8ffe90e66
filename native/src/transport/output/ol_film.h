// The orientation lightmaps a bake fills ([Thesis ch. 6, 7]): one OL per OL group
// and each L-system object's root and stub OLs. Set up before the photon
// pass (bin areas, each OL mesh's triangle splats), filled with each photon
// batch's OL hits in batch order (photon batch b goes to OL replicate
// b % kOlBatches, whose spread gives the error), finalized at the end.
#pragma once

#include <tbb/task_arena.h>

#include <cstdint>
#include <string>
#include <vector>

#include "lsystem/lsystem_object.h"
#include "ol/orientation_lightmap.h"
#include "scene/scene.h"
#include "transport/output/images.h"
#include "transport/context/bake_scene.h"
#include "transport/photons/photon_tracer.h"

namespace plm {

struct OlGroups {
  std::vector<ol::OrientationLightmap> maps;  // per OL group
  std::vector<uint32_t> mesh_counts;          // per OL group: its meshes
  // Per mesh: each triangle's splat (empty outside a group): 36 bytes a
  // triangle of an OL mesh.
  std::vector<std::vector<ol::Splat>> splats;
  std::vector<OlMeshView> views;              // per mesh, for the photon tracer
};

// Each group's OL with its area per bin: each triangle's exact area splatted
// over the bins the OL's lookup reads at its normal (ol::Splat), so that the
// lightmap resolved from the OL holds the light the triangles received; or,
// for subdivision meshes of a group that asks for it (OlGroup::limit_area),
// samples of their limit surface (subdiv/limit_area.h) in nearest bins, and
// those meshes' hits in the nearest bin of their triangle's normal (the limit
// surface's normals are not the triangles': no triangle's taps describe its
// area). Area and hits use the same double-precision normal and weights, so
// a hit never lands in a bin its triangle's area missed.
OlGroups build_ol_groups(const Scene& scene, std::vector<std::string>& warnings);

// L-system objects: each one's OL grid and its root and stub areas from the
// flattened object (LSystemOls, transport/context/bake_scene.h); out gets one
// LSystemOutput per object with its root OL.
LSystemOls build_lsystem_ols(const Scene& scene, tbb::task_arena& arena, std::vector<LSystemOutput>& out,
                             std::vector<std::string>& warnings);

// Adds the OL and L-system hits of batch `batch`; returns how many there were.
uint64_t merge_ol_hits(uint64_t batch, const BatchOutput& bo, OlGroups& groups, const LSystemOls& ls,
                       std::vector<LSystemOutput>& lsystems);

// Finalizes the OLs after `photons` photons (none: they stay black) into
// one image per OL group, and the L-system objects' OLs and statistics.
void finish_ol_groups(const Scene& scene, uint64_t photons, OlGroups& groups, std::vector<OlImage>& images);
void finish_lsystems(uint64_t photons, std::vector<LSystemOutput>& lsystems);

}  // namespace plm

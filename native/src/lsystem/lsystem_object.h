// An L-system placed in a scene ([Thesis ch. 7]): the graph of lsystem/graph/graph.h
// in its own frame, a placement into the world (a similarity: rotation or
// mirror times a uniform scale, plus a translation), the mapping of turtle
// material indices to scene materials, and what its orientation lightmaps
// need: the OL level of its stubs and their per-bin areas.
//
// Tracing. attach_lsystem() adds the object to an Embree scene as one user
// geometry whose callbacks map the ray into the graph's frame (the direction
// is not renormalised, so t is the world ray's parameter) and map the hit
// normal back (for a similarity the inverse transpose is the linear part up
// to scale: n_world = normalize(M n_local)). The full GraphHit of a hit goes
// into the ray's record in its HitContext (util/user_geometry.h), where
// SurfaceMap::hit finds it.
//
// Areas (OlAreas). v1 estimates bin areas from the flattened object: at most
// kMaxAreaPrimitives primitives (beyond: the areas found are scaled by the
// graph's primitive count / the cap, with a warning), each face sampled at
// max(kAreaSamplesPerFace, kAreaSamplesTotal x its share of the total area)
// points uniform by area (csg::sample_face on the primitive in world space),
// each adding face area / samples to the bin of its normal: a lone large
// cylinder gets ~65k samples over the ~32 bins of its side, a plant of 10^5
// primitives 16 per face, which average out over the many alike faces. Primitives are grouped by their instance key at ol_level
// (Graph::flatten(cap, level)), which gives every stub its own area. Planar
// faces (caps, boxes) land in one bin exactly; curved faces are unbiased
// with a per-bin variance from the sample counts. Primitives that overlap
// (branch joints) count their hidden surface too.
#pragma once

#include <embree3/rtcore.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "lsystem/graph/graph.h"
#include "ol/octahedral.h"
#include "photonlm/photonlm.h"
#include "util/math.h"

namespace plm::lsystem {

constexpr size_t kMaxAreaPrimitives = size_t(1) << 21;
constexpr int kAreaSamplesPerFace = 16;          // at least, per face
constexpr size_t kAreaSamplesTotal = 1u << 16;    // faces share these by area (a face gets the larger)
// Stub OLs hold ~200 bytes per bin: more than this many bins over all stub
// instances at ol_level (4096 stubs of 16 x 16 bins) and the object keeps
// only its root OL, with a warning.
constexpr size_t kMaxStubBins = size_t(1) << 20;

struct OlAreas {
  std::vector<double> root, root_variance;  // per bin, world m^2 / m^4
  std::unordered_map<uint64_t, std::vector<double>> stubs;  // per stub key: area per bin
  uint64_t primitives = 0;
  bool truncated = false;
  double scale = 1.0;      // applied to everything when truncated
  bool stubs_dropped = false;
  size_t stub_instances = 0;
};

class LSystemObject {
 public:
  // Parses and builds; throws plm::Error naming the object ("L-system 'name': ...").
  // scene_materials: the scene's material count (material ids must be below
  // max(1, count)).
  LSystemObject(const std::string& name, const char* rules, const plm_lsystem_settings& settings,
                size_t scene_materials);

  const std::string& name() const { return name_; }
  const Graph& graph() const { return *graph_; }
  uint32_t ol_level() const { return ol_level_; }
  uint32_t ol_resolution() const { return ol_resolution_; }
  // Scene material of a turtle material index (past the table: its last entry).
  uint32_t scene_material(int32_t turtle) const;
  const Affine3d& to_world() const { return to_world_; }
  Affine3d to_world_affine() const { return to_world_; }

  // World-space trace (o, d any length; t is the world parameter); n is the
  // world unit normal.
  bool first_hit(Vec3d o, Vec3d d, double tnear, double tfar, GraphHit* hit) const;
  bool occluded(Vec3d o, Vec3d d, double tnear, double tfar) const;
  Vec3d bounds_lo() const { return lo_; }
  Vec3d bounds_hi() const { return hi_; }
  // Stub key of a hit: the ancestor key at ol_level, or 0 with ol_level 0.
  uint64_t stub_key(const GraphHit& hit) const;

  // Bin areas for OLs on grid (see above); warnings appended.
  OlAreas estimate_areas(const ol::OctGrid& grid, std::vector<std::string>& warnings) const;

 private:
  std::string name_;
  std::unique_ptr<Graph> graph_;
  Affine3d to_world_, to_local_;
  std::vector<uint32_t> materials_;
  uint32_t ol_level_ = 0, ol_resolution_ = 16;
  Vec3d lo_, hi_;
};

// Flattened primitives in world space (the placement included), for previews.
FlattenResult flatten_lsystem(const char* rules, const plm_lsystem_settings& settings, size_t max_primitives);
// Checks and normalises settings (throws naming `label`): defaults filled in.
void check_lsystem_settings(const plm_lsystem_settings& settings, const std::string& label);
plm_lsystem_settings default_lsystem_settings();

// One user geometry (not committed into the scene); returns its geometry id.
unsigned attach_lsystem(RTCDevice device, RTCScene scene, const LSystemObject& object);

}  // namespace plm::lsystem

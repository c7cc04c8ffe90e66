// An L-system as a cyclic scene graph of node classes, traced without
// flattening (docs/design/geometry-kinds.md, "L-system objects"): Graph builds
// the classes with their bounds from a parsed system and answers closest-hit
// and occlusion queries (or Embree's, through attach_graph) with per-thread
// caches of expanded nodes; it also flattens the plant for areas and tests.
#pragma once

#include <embree3/rtcore.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "csg/primitive.h"
#include "lsystem/language/lsystem.h"
#include "lsystem/language/turtle.h"
#include "util/math.h"

namespace plm::lsystem {

// The traversal stack has one frame per level: the root plus one per derivation step.
constexpr int kMaxGraphLevels = 64;

struct GraphOptions {
  int depth = -1;                 // < 0: the system's `depth:`
  uint64_t seed = 0;              // stochastic choices: the root's path key is splitmix64(seed)
  double step = -1, angle = -1, width = -1;  // < 0: the system's
  int32_t material = 0;
  int max_levels = kMaxGraphLevels;          // depth + 1 may not exceed it
  size_t max_classes = 200'000;
  size_t max_classes_per_symbol_depth = 64;
  size_t cache_entries = 4096;    // per thread; 0: no limit on entries
  size_t cache_bytes = 64u << 20; // per thread; 0: no limit on bytes
  size_t bounds_budget = 1u << 15; // nodes one child's exact-bounds unfolding may visit (lsystem/graph/graph_bounds.h)
  size_t bounds_total = 1u << 22;  // nodes all the set-up's unfoldings may visit together
  // The object's placement (graph frame -> world, any affine map): only for
  // world_bounds_lo() / hi(), the exact box of the placed primitives.
  Affine3d world = Affine3d::identity();
};

// Traversal views inline small descendants (lsystem/graph/graph_view.h): each at
// most kGraphInlineItems primitives and children, down to kGraphInlineDepth - 1
// steps below the node, at most kGraphInlineViewItems primitives and hops per
// view. An inlining view costs the expansions of its inlined descendants and
// holds several times the bytes, so with GraphOptions::cache_bytes below
// kGraphInlineMinCacheBytes views inline nothing (one visit per level).
constexpr size_t kGraphInlineItems = 16;
constexpr int kGraphInlineDepth = 5;
constexpr size_t kGraphInlineViewItems = 64;
// A child reference keeps its descendants' boxes (for inlining) only down to
// the deepest step at which they number at most this many: a view inlines at
// most ~kGraphInlineViewItems of them, while a stochastic class's union over
// its productions grows as the sum of their children per step.
constexpr uint64_t kGraphInlineDescBoxes = 256;
static_assert(kGraphInlineDepth >= 2, "a view inlines at least its children");
constexpr size_t kGraphInlineMinCacheBytes = size_t(1) << 20;

struct GraphNodeClass {
  uint32_t symbol;        // UINT32_MAX for the root (the axiom)
  int depth;              // remaining derivation steps (root: D + 1)
  double width;           // turtle width on entry
  int32_t material;       // turtle material on entry
  std::vector<double> params;
  std::vector<std::pair<int32_t, double>> alternatives;  // (production, weight); weight < 0: deterministic
  double total_weight = 0;
  bool path_dependent = false;
  Vec3d lo, hi;           // bounds in the node frame (lo > hi: empty)
  uint64_t max_primitives = 0;  // flattened count (max over productions; saturates at UINT64_MAX)
};

struct GraphHit {
  double t = 0;
  Vec3d n;                       // unit world normal, outward from the primitive
  ShapeKind shape = ShapeKind::Cylinder;
  int32_t material = 0;
  uint32_t prim = 0;             // index in the hit node's expansion
  int levels = 0;                // child steps from the root to the hit node
  // Valid up to `levels` (not cleared beyond: a hit record is made per ray).
  uint32_t path[kMaxGraphLevels];              // child index at each step
  uint32_t classes[kMaxGraphLevels + 1];       // node class at each level (0: the root)
  uint64_t node_key = 0;         // path key of the hit node
  uint64_t instance_key = 0;     // child_key(node_key, prim): the primitive instance
};

// The normal as OL bins see it, for area samples and photon hits alike:
// components within 1e-12 of 0 become +0, so that a normal on an octahedral
// fold (a vertical cylinder's side: z = 0) falls on the same side of it
// whether it came from sampling or from a ray hit.
inline Vec3d ol_normal(Vec3d n) {
  auto snap = [](double c) { return std::fabs(c) < 1e-12 ? 0.0 : c; };
  return {snap(n.x), snap(n.y), snap(n.z)};
}

struct GraphStats {
  size_t classes = 0;
  int levels = 0;
  size_t class_bytes = 0;        // the immutable graph
  uint64_t cache_hits = 0, cache_misses = 0, evictions = 0;
  uint64_t bypassed = 0;         // misses held for their traversal only (a full cache did not admit them)
  size_t cached_entries = 0, cached_bytes = 0, peak_cached_bytes = 0;  // summed over thread caches
  uint64_t flattened_primitives = 0;  // exact when the root is not path dependent, else an upper bound
  uint64_t truncated = 0;        // traversals cut by the stack bound (0 by construction: depth is checked)
  uint64_t bounds_visits = 0;    // nodes the set-up's child-bounds unfoldings visited (<= bounds_total)
};

struct FlattenResult {
  std::vector<TurtlePrimitive> primitives;  // world space, in successor (string) order
  bool truncated = false;                   // the cap was reached
  // Only from flatten(max, key_level): per primitive, the path key of its
  // node's ancestor at key_level (the node itself when it lies higher up):
  // what ancestor_key(hit, key_level) gives for a hit on that primitive.
  std::vector<uint64_t> keys;
};

class Graph {
 public:
  // Throws plm::Error (PLM_ERROR_INVALID_ARGUMENT) for what the graph cannot
  // represent: context-sensitive productions and rand() ("... need the
  // flattened path"); parameters that are not (nearly) constant per (module,
  // depth), i.e. more than max_classes_per_symbol_depth distinct (parameters,
  // width, material) states of one module at one depth; a stochastic module
  // whose productions end in different turtle states followed, in its branch,
  // by anything that reads that state; brackets that cross node boundaries;
  // depth + 1 over max_levels. More than max_classes classes:
  // PLM_ERROR_OUT_OF_MEMORY.
  Graph(const LSystem& system, const GraphOptions& options = {});
  ~Graph();
  Graph(const Graph&) = delete;
  Graph& operator=(const Graph&) = delete;

  // Closest hit with t in [tnear, tfar); the direction need not be unit (t is
  // the world ray's parameter). False if none.
  bool first_hit(Vec3d o, Vec3d d, double tnear, double tfar, GraphHit* hit) const;
  bool occluded(Vec3d o, Vec3d d, double tnear, double tfar) const;

  Vec3d bounds_lo() const;
  Vec3d bounds_hi() const;
  // The box under GraphOptions::world of every primitive, unfolded once at
  // set-up like a child's bounds (exact up to bounds_budget nodes, then mapped
  // class boxes; padded by 1e-9 relative): tight for a rotated object, where
  // the 8 corners of bounds_lo() / hi() mapped by world are not. Empty (lo >
  // hi) when the plant draws nothing.
  Vec3d world_bounds_lo() const;
  Vec3d world_bounds_hi() const;
  const GraphNodeClass& node_class(uint32_t id) const;
  uint64_t root_key() const;
  static uint64_t child_key(uint64_t key, uint32_t index);
  // Path key of the hit's ancestor at `level` (0: root, hit.levels: the hit node).
  uint64_t ancestor_key(const GraphHit& hit, int level) const;

  // Sums over the thread caches; call it and reset_cache() while no thread traces.
  GraphStats stats() const;
  void reset_cache() const;  // empties every thread's cache and zeroes the counters

  // All primitives in world space, at most max_primitives (then truncated).
  FlattenResult flatten(size_t max_primitives = 10'000'000) const;
  // The same, with FlattenResult::keys filled for level key_level >= 0
  // (e.g. to group primitives by the instance that holds them).
  FlattenResult flatten(size_t max_primitives, int key_level) const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// csg::make_primitive(desc) without the face areas (area[] is NaN), for a
// sphere, cylinder, cone or box that csg::check_primitive accepts: what the
// graph's expansions hold (the areas are numerical integrals, most of an
// expansion's cost; the traversal never reads them).
csg::Primitive trace_primitive(const csg::PrimitiveDesc& desc);

// Attaches the graph to scene as one user geometry (not yet committed; with
// a sentinel primitive, util/user_geometry.h) and returns its geometry id.
// The hit carries tfar, a unit Ng, u = the ShapeKind, v = 0, primID = the
// material; the path key and the rest go into the ray's record of the
// HitContext (util/user_geometry.h) that closest-hit queries must be traced
// with. Filter functions are not called for this geometry. The graph must
// outlive the scene's use.
unsigned attach_graph(RTCDevice device, RTCScene scene, const Graph& graph);

}  // namespace plm::lsystem

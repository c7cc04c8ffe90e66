// An L-system as a cyclic scene graph, ray traced without flattening
// (thesis 4.3-4.4: the plant is a graph of shared nodes, unfolded once at
// set-up for bounds, expanded on demand while tracing and kept in an LRU
// cache of expanded instances; 7.4.2: instance keys from the traversal path).
//
// Nodes. A node class is (module symbol, constant parameters, remaining
// depth d, turtle width and material on entry). Expanding an instance of
// (X, d) rewrites X once and interprets the successor with the turtle of
// lsystem/turtle.h from a local frame at the origin (H = +Z, L = -X, U = -Y):
// turtle symbols that are terminal draw primitives in that frame, every
// non-terminal module Y becomes a child reference (Y, d-1) with the turtle's
// frame at that point as a rigid 3x4 transform. A module is terminal at d = 0
// or when no production can rewrite it (it is then copied unchanged and
// drawn at the end). The root is the axiom at the derivation depth D. Memory
// is ~ classes x successor size; the number of classes is ~ symbols x depth
// (times the few widths / materials that reach a symbol), not the number of
// leaves.
//
// Turtle state across node boundaries:
//   position, orientation  the child's transform (rotation + translation; the
//                          turtle never scales a frame, so transforms are rigid)
//   width, material        part of the child's class (exact: no scaling trick);
//                          the child reports the width and material it ends with
//   end of a child         a child's net effect (end frame, width, material) is
//                          part of its class and is composed into the parent's
//                          turtle after the reference, so `F -> FF` followed by
//                          drawing continues where the child stopped
//   step, angle            global (GraphOptions or the system), as in the turtle
// Rejected with plm::Error (PLM_ERROR_INVALID_ARGUMENT):
//   context-sensitive productions and rand() in any expression
//       ("... need the flattened path");
//   parametric productions whose parameters are not (nearly) constant per
//       (module, depth): more than max_classes_per_symbol_depth distinct
//       (parameters, width, material) states of one module at one depth
//       ("parametric productions need the flattened path: ...");
//   a stochastic module whose productions end in different turtle states
//       (frame, width or material) and is followed, in the same branch, by
//       anything that would read that state;
//   depth + 1 levels over max_levels (<= kMaxGraphLevels), more than
//       max_classes classes.
//
// Stochastic choices and keys. Every instance has a path key: the root's is
// splitmix64(seed), the i-th child reference (0-based, in successor order) of
// an instance with key k has child_key(k, i) = splitmix64(k ^ splitmix64(i + 1)).
// Unlike the thesis (which records a digit only at nodes with more than one
// subnode), every step is hashed, so a parent and its only child have
// different keys. A stochastic instance draws its production from
// RandomStream{stream_key(key, depth, symbol, 3)} with the probabilities of
// derive(); the draw depends only on (seed, path), never on threads or on the
// cache. The result differs from derive() with the same seed (derive keys
// draws on string positions, which a graph does not have); flatten() is the
// reference. A class is path dependent if it or anything below it has more
// than one applicable production; its expansions are cached under
// (class, path key), other classes under (class, 0) and shared by all paths.
//
// Bounds: one unfolding over classes at set-up, bottom-up and memoised; a
// stochastic class takes the union over its productions, so bounds never
// depend on the path. A child's bounds are the exact box, in the parent's
// frame, of every primitive of the child's subtree (each primitive's exact
// extent: sphere, cylinder / cone hull, box), found by unfolding the subtree
// under the composed transforms. The same unfolding gives the boxes of the
// child's descendants that views may inline (see Traversal), so a child
// reference costs one unfolding of at most GraphOptions::bounds_budget
// nodes, and the set-up's unfoldings together visit at most
// GraphOptions::bounds_total (a stochastic class unfolds every production:
// its subtree grows as the sum of the productions' children to the power of
// the depth). Where a budget runs out, a box is the class's own box mapped by
// its transform (8 corners): conservative, looser only there. Boxes are
// padded by 1e-9 relative. A class box is the union of its primitives' and
// children's boxes.
//
// Traversal: an expansion's traversal view (GraphExpansion::tprims, hops,
// clusters) inlines its small descendants (kGraphInlineDepth: down to four
// steps below the node), so one visit covers up to five derivation steps: a
// node's cache entry is looked up and a hop queued once per up to five
// levels. Inlined primitives are placed in the node's frame (their transforms
// composed) and a hop maps the ray from the node's frame straight into its
// target's (composed), so a visit transforms nothing and entering a hop is
// one map whatever the steps. Every primitive and hop has its box in the
// node's frame (the exact box, for inlined levels from set-up unfoldings per
// class, rounded outward to float); the boxes are grouped by SAH into
// clusters of four, and a visit tests the clusters' boxes, then the boxes in
// the clusters met, four at a time in float SIMD (conservative: a box the ray
// meets always passes, see boxes4 in graph.cpp), before any intersection.
// Hops are entered front to back (sorted by box entry, skipped once the entry
// lies beyond the closest hit so far). The hit record (path, classes per
// level, keys, normal) is made once per ray, from the hops that led to the
// closest hit.
//
// Threads: the graph (classes, bounds) is immutable after set-up. Each thread
// that traces gets its own LRU cache of expansions (tbb::enumerable_thread_
// specific inside the Graph): no lock and no shared atomic per ray; the cost
// is that every thread expands (and holds up to the capacity of) its own
// copies. A traversal holds plain pointers to expansions: every entry it
// looked up is stamped with the traversal's number and not evicted before the
// traversal ends, so a capacity below what one ray touches is exceeded by
// those entries until the ray ends (then the cache is trimmed back to its
// capacity). A full cache admits a miss only if its class was looked up more
// often lately than the class of the entry LRU would evict (otherwise the
// expansion lives for its traversal only: GraphStats::bypassed), so the many
// cold nodes deep in a plant do not push out the nodes most rays visit when
// the working set exceeds the cache. stats() sums the thread caches; call it
// and reset_cache() while no thread traces.
#pragma once

#include <embree3/rtcore.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "csg/primitive.h"
#include "lsystem/lsystem.h"
#include "lsystem/turtle.h"

namespace plm::lsystem {

// The traversal stack has one frame per level: the root plus one per derivation step.
constexpr int kMaxGraphLevels = 64;

struct GraphOptions {
  int depth = -1;                 // < 0: the system's `depth:`
  uint64_t seed = 0;              // stochastic choices (see the key scheme above)
  double step = -1, angle = -1, width = -1;  // < 0: the system's
  int32_t material = 0;
  int max_levels = kMaxGraphLevels;          // depth + 1 may not exceed it
  size_t max_classes = 200'000;
  size_t max_classes_per_symbol_depth = 64;
  size_t cache_entries = 4096;    // per thread; 0: no limit on entries
  size_t cache_bytes = 64u << 20; // per thread; 0: no limit on bytes
  size_t bounds_budget = 1u << 15; // nodes one child's exact-bounds unfolding may visit (see Bounds)
  size_t bounds_total = 1u << 22;  // nodes all the set-up's unfoldings may visit together (see Bounds)
  // The object's placement (graph frame -> world, any affine map): only for
  // world_bounds_lo() / hi(), the exact box of the placed primitives.
  csg::Affine world{{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}};
};

// A primitive of an expansion, in the node's local frame.
struct GraphPrimitive {
  ShapeKind shape;
  int32_t material;
  csg::Primitive prim;
};

struct GraphBox {
  csg::DVec3 lo, hi;             // lo > hi: empty
};

struct GraphChild {
  uint32_t cls;                  // node class of the child
  bool path_dependent;           // the child class's path_dependent
  csg::Affine to_parent;         // child frame -> parent frame (rigid)
  csg::Affine to_local;          // its inverse
  csg::DVec3 lo, hi;             // child bounds in the parent frame (exact subtree box, see Bounds)
};

// The traversal's view of an expansion. Small descendants (at most
// kGraphInlineItems primitives and children each, down to kGraphInlineDepth - 1
// steps below the node, at most kGraphInlineViewItems primitives and hops in
// all) are inlined: their primitives (boxes in the node's frame) are tested
// within the node's visit, and the children of the deepest inlined ones become
// the node's hops (up to kGraphInlineDepth steps down), so a cache entry is
// looked up and the queue of hops grows once per up to kGraphInlineDepth
// levels. The view is made when a ray first enters an expansion; a cache
// entry then holds the view only (children and prims_before are released;
// flatten() makes its own expansions). With inlining a miss costs the expansion of the node and of
// its inlined descendants (each ~1 us: primitives are made by
// trace_primitive, without face areas) and an entry holds several times the
// bytes, so with GraphOptions::cache_bytes below kGraphInlineMinCacheBytes
// views inline nothing (one visit per level).
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

// Frames: an inlined primitive is intersected in the view's frame (its
// transform composed with those of the inlined steps) and a hop's ray is
// mapped by the composed transform, so hits of an inlining view differ from
// those of the plain traversal (small caches, kGraphInlineMinCacheBytes) by
// rounding only (t within ~1e-14 relative, the normal within ~1e-11; which
// of two coincident primitives wins a tie in t may differ), as the flattened
// object (world transforms composed) does
// (LSystemGraph.SmallByteBudgetDegradesGracefully).

// A node below this one that the traversal enters.
struct GraphHop {
  csg::Affine to_local;          // this node's frame -> the target's frame (composed over the steps)
  bool path_dependent;           // the target class's path_dependent
  uint8_t steps;                 // derivation steps from this node to the target
  uint32_t path[kGraphInlineDepth];     // child index at each step
  uint32_t classes[kGraphInlineDepth];  // class at each step (classes[steps - 1]: the target's)
};

// A primitive the traversal tests (its box in this node's frame).
struct GraphTracePrim {
  const GraphPrimitive* gp;      // the node's own (prims) or an inlined descendant's (inlined_prims), in this node's frame
  uint32_t prim;                 // its index in its own node's expansion
  uint8_t steps;                 // derivation steps from this node to the primitive's node
  uint32_t path[kGraphInlineDepth - 1], classes[kGraphInlineDepth - 1];  // as GraphHop's, `steps` of them
};

// Four boxes as a structure of arrays of floats, rounded outward from the
// exact (double, padded) boxes; an unused lane is empty (lo = +inf, hi = -inf).
struct alignas(16) GraphBoxes4 {
  float lo[3][4], hi[3][4];      // [axis][box]
};

// Up to four items of a view (items: the tprims, then the hops), near each
// other: their boxes and, per lane, the item (an unused lane: an empty box and
// UINT32_MAX).
struct alignas(16) GraphCluster {
  GraphBoxes4 box;
  uint32_t item[4];
};

// One expanded instance: what the turtle drew and the child references.
struct GraphExpansion {
  std::vector<GraphPrimitive> prims;
  std::vector<GraphChild> children;
  std::vector<uint32_t> prims_before;  // per child: primitives drawn before it (successor order)
  uint32_t alt = 0;                    // the production expanded
  // children and prims_before are empty once the view is made (cache entries).
  // The traversal's view (see above; made when a ray first enters the
  // expansion, not by flatten()); boxes in the node frame, padded.
  bool has_view = false;
  std::vector<GraphPrimitive> inlined_prims;  // inlined descendants' primitives, placed in this node's frame
  std::vector<GraphTracePrim> tprims;
  std::vector<GraphHop> hops;
  // The items' boxes (a tprim's: the primitive's exact box; a hop's: the
  // target's subtree box; in this node's frame, rounded outward) in clusters
  // (SAH splits down to four items; an item with an empty box is in none),
  // and the clusters' boxes (cluster c: block c / 4, lane c % 4; none when
  // there is only one cluster).
  std::vector<GraphCluster> clusters;
  std::vector<GraphBoxes4> cluster_boxes;
  size_t bytes = 0;
};

struct GraphNodeClass {
  uint32_t symbol;        // UINT32_MAX for the root (the axiom)
  int depth;              // remaining derivation steps (root: D + 1)
  double width;           // turtle width on entry
  int32_t material;       // turtle material on entry
  std::vector<double> params;
  std::vector<std::pair<int32_t, double>> alternatives;  // (production, weight); weight < 0: deterministic
  double total_weight = 0;
  bool path_dependent = false;
  csg::DVec3 lo, hi;      // bounds in the node frame (lo > hi: empty)
  uint64_t max_primitives = 0;  // flattened count (max over productions; saturates at UINT64_MAX)
};

struct GraphHit {
  double t = 0;
  csg::DVec3 n;                  // unit world normal, outward from the primitive
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
  // Throws plm::Error (PLM_ERROR_INVALID_ARGUMENT) for what the graph cannot represent (see above).
  Graph(const LSystem& system, const GraphOptions& options = {});
  ~Graph();
  Graph(const Graph&) = delete;
  Graph& operator=(const Graph&) = delete;

  // Closest hit with t in [tnear, tfar); the direction need not be unit (t is
  // the world ray's parameter). False if none.
  bool first_hit(csg::DVec3 o, csg::DVec3 d, double tnear, double tfar, GraphHit* hit) const;
  bool occluded(csg::DVec3 o, csg::DVec3 d, double tnear, double tfar) const;

  csg::DVec3 bounds_lo() const;
  csg::DVec3 bounds_hi() const;
  // The box under GraphOptions::world of every primitive, unfolded once at
  // set-up like a child's bounds (exact up to bounds_budget nodes, then mapped
  // class boxes; padded by 1e-9 relative): tight for a rotated object, where
  // the 8 corners of bounds_lo() / hi() mapped by world are not. Empty (lo >
  // hi) when the plant draws nothing.
  csg::DVec3 world_bounds_lo() const;
  csg::DVec3 world_bounds_hi() const;
  const GraphNodeClass& node_class(uint32_t id) const;
  uint64_t root_key() const;
  static uint64_t child_key(uint64_t key, uint32_t index);
  // Path key of the hit's ancestor at `level` (0: root, hit.levels: the hit node).
  uint64_t ancestor_key(const GraphHit& hit, int level) const;

  GraphStats stats() const;
  void reset_cache() const;  // empties every thread's cache and zeroes the counters

  // All primitives in world space, at most max_primitives (then truncated).
  FlattenResult flatten(size_t max_primitives = 10'000'000) const;
  // The same, with FlattenResult::keys filled for level key_level >= 0
  // (e.g. to group primitives by the instance that holds them).
  FlattenResult flatten(size_t max_primitives, int key_level) const;

  // The last hit that the Embree intersect callback reported on this thread
  // (valid right after rtcIntersect1 when the hit's geomID is the graph's).
  const GraphHit& last_embree_hit() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// csg::make_primitive(desc) without the face areas (area[] is NaN), for a
// sphere, cylinder, cone or box that csg::check_primitive accepts: what the
// graph's expansions hold (the areas are numerical integrals and ~70 % of an
// expansion's cost; the traversal never reads them).
csg::Primitive trace_primitive(const csg::PrimitiveDesc& desc);

// Attaches the graph to scene as one user geometry (not yet committed; with
// a sentinel primitive, accel/user_geometry.h) and returns its geometry id.
// The hit carries tfar, a unit Ng, u = the ShapeKind, v = 0, primID = the
// material; the path key and the rest are in graph.last_embree_hit() on the
// calling thread. Filter functions are not called for this geometry. The
// graph must outlive the scene's use.
unsigned attach_graph(RTCDevice device, RTCScene scene, const Graph& graph);

}  // namespace plm::lsystem

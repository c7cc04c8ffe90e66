// An expanded graph node: what the turtle drew for one instance of a node
// class (primitives and child references, lsystem/graph/graph_classes.h) and, once
// a ray has entered it, its traversal view (lsystem/graph/graph_view.h).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "csg/primitive.h"
#include "lsystem/graph/graph.h"
#include "lsystem/language/turtle.h"

namespace plm::lsystem {

// A primitive of an expansion, in the node's local frame.
struct GraphPrimitive {
  ShapeKind shape;
  int32_t material;
  csg::Primitive prim;
};

struct GraphBox {
  Vec3d lo, hi;                  // lo > hi: empty
};

struct GraphChild {
  uint32_t cls;                  // node class of the child
  bool path_dependent;           // the child class's path_dependent
  Affine3d to_parent;            // child frame -> parent frame (rigid)
  Affine3d to_local;             // its inverse
  Vec3d lo, hi;                  // child bounds in the parent frame (exact subtree box, lsystem/graph/graph_bounds.h)
};

// A node below this one that the traversal enters.
struct GraphHop {
  Affine3d to_local;             // this node's frame -> the target's frame (composed over the steps)
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

struct GraphExpansion {
  std::vector<GraphPrimitive> prims;
  std::vector<GraphChild> children;
  std::vector<uint32_t> prims_before;  // per child: primitives drawn before it (successor order)
  uint32_t alt = 0;                    // the production expanded
  // The traversal's view (made when a ray first enters the expansion, not by
  // flatten(); children and prims_before are released then); boxes in the
  // node frame, padded.
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
  size_t bytes = 0;                    // what a cache entry holding it counts
};

inline size_t expansion_bytes(const GraphExpansion& e) {
  return sizeof(GraphExpansion) + e.prims.capacity() * sizeof(GraphPrimitive) +
         e.children.capacity() * sizeof(GraphChild) + e.prims_before.capacity() * sizeof(uint32_t) +
         e.inlined_prims.capacity() * sizeof(GraphPrimitive) +
         e.tprims.capacity() * sizeof(GraphTracePrim) + e.clusters.capacity() * sizeof(GraphCluster) +
         e.cluster_boxes.capacity() * sizeof(GraphBoxes4) +
         e.hops.capacity() * sizeof(GraphHop) + 64;
}

}  // namespace plm::lsystem

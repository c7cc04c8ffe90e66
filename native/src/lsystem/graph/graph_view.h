// The traversal view of an expanded graph node.
//
// A view inlines the node's small descendants (each at most kGraphInlineItems
// primitives and children, down to kGraphInlineDepth - 1 steps below the node,
// at most kGraphInlineViewItems primitives and hops in all), so one visit
// covers up to kGraphInlineDepth derivation steps. Inlined primitives are
// placed in the node's frame (their transforms composed) and the children of
// the deepest inlined descendants become the node's hops, each with the
// composed map from the node's frame into its target's, so a visit transforms
// nothing and entering a hop is one map whatever the steps. Every primitive
// and hop has its box in the node's frame (for inlined levels the set-up's
// DescBoxes, lsystem/graph/graph_bounds.h), rounded outward to float and grouped by
// SAH into clusters of four (GraphCluster). Hits through an inlining view
// differ from those of a view that inlines nothing by rounding only, as the
// flattened object's do (LSystemGraph.SmallByteBudgetDegradesGracefully).
#pragma once

#include <cstdint>
#include <vector>

#include "lsystem/graph/graph_classes.h"
#include "lsystem/graph/graph_expansion.h"

namespace plm::lsystem {

// A view item's box (double, padded) for the clusters; ref: its item index.
struct ViewItem {
  Vec3d lo, hi;
  double c[3];  // centroid
  uint32_t ref;
};

// build_view's scratch, kept per thread so that a view allocates only what it keeps.
struct ViewScratch {
  std::vector<GraphBox> prim_boxes, hop_boxes;
  std::vector<ViewItem> items;
  std::vector<double> areas;
  std::vector<GraphCluster> clusters;
  std::vector<GraphBoxes4> cluster_boxes;
};

// Makes the view of expansion e of (cls, key) (descendants inlined breadth
// first unless g.inline_views is off, their expansions made here and dropped
// after). Afterwards e holds only the view: children and prims_before are
// released, and e->bytes counts what is left.
void build_view(const GraphClasses& g, ViewScratch& scratch, GraphExpansion* e, uint32_t cls, uint64_t key);

}  // namespace plm::lsystem

// Bounds of an L-system graph's child references, found at set-up by
// unfolding the node classes below them.
//
// A child reference's box is the exact box, in the parent's frame, of every
// primitive of the child's subtree (each primitive's exact extent), found by
// unfolding the subtree under the composed transforms; a stochastic class
// unfolds every production, so bounds never depend on the path. The same
// unfolding gives the boxes of the descendants a traversal view may inline
// (lsystem/graph/graph_view.h). One reference's unfolding visits at most
// GraphOptions::bounds_budget nodes and the set-up's together at most
// bounds_total (a stochastic class's subtree grows as the sum of its
// productions' children to the power of the depth); where a budget runs out a
// box is the class's own box mapped by the transform (8 corners):
// conservative, looser only there. Descendants' boxes are kept only down to
// the step where they number at most kGraphInlineDescBoxes.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "lsystem/graph/graph.h"
#include "lsystem/graph/graph_expansion.h"
#include "util/math.h"

namespace plm::lsystem {

// A child reference's subtree box in the parent class's frame and, for
// inlining, the subtree boxes of its descendants down to kGraphInlineDepth - 1
// further steps, also in that frame: sub[production of the child][its child]
// (empty where the child is not small enough to be inlined, see
// kGraphInlineItems, or the set-up's allowance of such boxes ran out).
struct DescBoxes {
  GraphBox box;
  std::vector<std::vector<DescBoxes>> sub;
};

// The set-up's unfolding. It keeps, per class, the primitives and child
// references of all its productions (the skeleton the set-up's turtle walk
// records) and, per class, how many DescBoxes a reference's boxes down L steps
// would take. Classes begin in id order and are complete (end_class) before
// a reference to them is added.
class BoundsUnfolding {
 public:
  explicit BoundsUnfolding(const GraphOptions& options);

  void begin_class(uint32_t id, size_t productions);
  void add_primitive(uint32_t id, size_t production, ShapeKind shape, const Affine3d& m);
  // Records child class cls placed by t in production `production` of class
  // id and returns its boxes (the subtree box padded, descendants' boxes
  // unpadded until placed).
  DescBoxes add_child(const std::vector<GraphNodeClass>& classes, uint32_t id, size_t production, uint32_t cls,
                      const Affine3d& t);
  void end_class(uint32_t id);

  // The box under `world` of every primitive below the root (class 0), one
  // unfolding of at most bounds_budget nodes, padded.
  void world_box(const std::vector<GraphNodeClass>& classes, const Affine3d& world, Vec3d* lo,
                 Vec3d* hi) const;

  uint64_t visits() const { return uint64_t(visits_); }  // nodes the child references' unfoldings visited
  size_t desc_boxes_made() const { return desc_count_; }

 private:
  struct Prim {
    ShapeKind shape;
    Affine3d m;
  };
  struct Child {
    uint32_t cls;
    Affine3d t;
  };
  struct Skeleton {
    std::vector<Prim> prims;
    std::vector<Child> children;
  };

  bool inlinable(uint32_t cls) const;
  DescBoxes desc_boxes(const std::vector<GraphNodeClass>& classes, uint32_t cls, const Affine3d& a, int levels,
                       int64_t& budget);
  void subtree_box(const std::vector<GraphNodeClass>& classes, uint32_t cls, const Affine3d& a, int64_t& budget,
                   Vec3d& lo, Vec3d& hi) const;

  std::vector<std::vector<Skeleton>> skel_;  // [class][production]
  // Per class, the DescBoxes a reference's boxes down L steps would take (the
  // union over productions; saturating), for L < kGraphInlineDepth.
  std::vector<std::array<uint64_t, kGraphInlineDepth>> desc_nodes_;
  size_t desc_left_ = size_t(1) << 20;  // sub-level boxes the set-up may still make
  int64_t budget_ = 0;                  // GraphOptions::bounds_budget (capped to int64)
  int64_t total_ = 0;                   // GraphOptions::bounds_total (capped to int64)
  int64_t visits_ = 0;                  // nodes the unfoldings visited so far
  size_t desc_count_ = 0;               // DescBoxes made
};

}  // namespace plm::lsystem

// Set-up unfolding of an L-system graph's bounds (lsystem/graph/graph_bounds.h).
#include "lsystem/graph/graph_bounds.h"

#include <algorithm>
#include <cstdint>

#include "lsystem/graph/geometry.h"

namespace plm::lsystem {


BoundsUnfolding::BoundsUnfolding(const GraphOptions& o)
    : budget_(int64_t(std::min<size_t>(o.bounds_budget, size_t(INT64_MAX)))),
      total_(int64_t(std::min<size_t>(o.bounds_total, size_t(INT64_MAX)))) {}

void BoundsUnfolding::begin_class(uint32_t id, size_t productions) {
  if (skel_.size() <= id) {
    skel_.resize(size_t(id) + 1);
    desc_nodes_.resize(size_t(id) + 1);
  }
  skel_[id].assign(productions, {});
}

void BoundsUnfolding::add_primitive(uint32_t id, size_t production, ShapeKind shape, const Affine3d& m) {
  skel_[id][production].prims.push_back({shape, m});
}

DescBoxes BoundsUnfolding::add_child(const std::vector<GraphNodeClass>& classes, uint32_t id, size_t production,
                                     uint32_t cls, const Affine3d& t) {
  skel_[id][production].children.push_back({cls, t});
  const int64_t given = std::min(budget_, total_ - visits_);
  int64_t budget = given;
  int levels = kGraphInlineDepth - 1;  // as deep as kGraphInlineDescBoxes allow
  while (levels > 0 && desc_nodes_[cls][levels] > kGraphInlineDescBoxes) --levels;
  DescBoxes d = desc_boxes(classes, cls, t, levels, budget);
  visits_ += given - budget;
  pad_box(d.box.lo, d.box.hi);
  return d;
}

void BoundsUnfolding::end_class(uint32_t id) {
  std::array<uint64_t, kGraphInlineDepth>& dn = desc_nodes_[id];
  dn.fill(1);
  for (int l = 1; l < kGraphInlineDepth && inlinable(id); ++l)  // else no boxes below it
    for (const Skeleton& k : skel_[id])
      for (const Child& ch : k.children) dn[l] = std::min(dn[l] + desc_nodes_[ch.cls][l - 1], uint64_t(1) << 62);
}

void BoundsUnfolding::world_box(const std::vector<GraphNodeClass>& classes, const Affine3d& world, Vec3d* lo,
                                Vec3d* hi) const {
  int64_t budget = budget_;
  subtree_box(classes, 0, world, budget, *lo, *hi);
  pad_box(*lo, *hi);
}

// Can a view inline class cls (every production small enough)?
bool BoundsUnfolding::inlinable(uint32_t cls) const {
  for (const Skeleton& k : skel_[cls])
    if (k.prims.size() + k.children.size() > kGraphInlineItems) return false;
  return true;
}

// Class cls under a, with its descendants' boxes `levels` steps deep, all
// from one unfolding of at most `budget` nodes (see subtree_box). Boxes are
// left unpadded (the parent grows by them); a descendant's box is padded once
// it is placed.
DescBoxes BoundsUnfolding::desc_boxes(const std::vector<GraphNodeClass>& classes, uint32_t cls, const Affine3d& a,
                                      int levels, int64_t& budget) {
  DescBoxes d;
  ++desc_count_;
  d.box = {{kInf, kInf, kInf}, {-kInf, -kInf, -kInf}};
  size_t n = 0;
  for (const Skeleton& k : skel_[cls]) n += k.children.size();
  if (levels <= 0 || !inlinable(cls) || n > desc_left_) {
    subtree_box(classes, cls, a, budget, d.box.lo, d.box.hi);
    return d;
  }
  desc_left_ -= n;
  const bool exact = budget > 0;
  if (exact)
    --budget;
  else
    subtree_box(classes, cls, a, budget, d.box.lo, d.box.hi);  // budget spent: the class box mapped
  d.sub.resize(skel_[cls].size());
  for (size_t a2 = 0; a2 < skel_[cls].size(); ++a2) {
    if (exact)
      for (const Prim& p : skel_[cls][a2].prims) {
        Vec3d l, h;
        prim_box(p.shape, compose(a, p.m), &l, &h);
        grow(d.box.lo, d.box.hi, l, h);
      }
    for (const Child& gc : skel_[cls][a2].children) {
      DescBoxes c = desc_boxes(classes, gc.cls, compose(a, gc.t), levels - 1, budget);
      if (exact) grow(d.box.lo, d.box.hi, c.box.lo, c.box.hi);
      pad_box(c.box.lo, c.box.hi);
      d.sub[a2].push_back(std::move(c));
    }
  }
  return d;
}

// The box, under a, of every primitive below class cls; where budget runs
// out, the class box mapped by a.
void BoundsUnfolding::subtree_box(const std::vector<GraphNodeClass>& classes, uint32_t cls, const Affine3d& a,
                                  int64_t& budget, Vec3d& lo, Vec3d& hi) const {
  const GraphNodeClass& c = classes[cls];
  if (box_empty(c.lo, c.hi)) return;  // draws nothing
  if (budget <= 0) {
    Vec3d l, h;
    transform_box(a, c.lo, c.hi, &l, &h);
    grow(lo, hi, l, h);
    return;
  }
  --budget;
  for (const Skeleton& k : skel_[cls]) {
    for (const Prim& p : k.prims) {
      Vec3d l, h;
      prim_box(p.shape, compose(a, p.m), &l, &h);
      grow(lo, hi, l, h);
    }
    for (const Child& ch : k.children) subtree_box(classes, ch.cls, compose(a, ch.t), budget, lo, hi);
  }
}

}  // namespace plm::lsystem

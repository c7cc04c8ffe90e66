// Traversal views of expanded graph nodes (lsystem/graph/graph_view.h).
#include "lsystem/graph/graph_view.h"

#include <algorithm>
#include <limits>
#include <memory>

#include "lsystem/graph/geometry.h"

namespace plm::lsystem {
namespace {


double half_area(Vec3d lo, Vec3d hi) {
  const Vec3d e = hi - lo;
  return e.x * e.y + e.y * e.z + e.z * e.x;
}

// Reorders it[0, n) (n >= 2) along the axis and at the split of least
// surface area heuristic cost (centroid order); returns the size of the left part.
size_t sah_split(ViewItem* it, size_t n, std::vector<double>& right_area) {
  double best = kInf;
  int best_axis = 0;
  size_t best_m = n / 2;
  right_area.resize(n + 1);
  for (int a = 0; a < 3; ++a) {
    std::sort(it, it + n, [a](const ViewItem& x, const ViewItem& y) {
      return x.c[a] < y.c[a] || (x.c[a] == y.c[a] && x.ref < y.ref);
    });
    Vec3d lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
    for (size_t i = n; i > 0; --i) {
      grow(lo, hi, it[i - 1].lo, it[i - 1].hi);
      right_area[i - 1] = half_area(lo, hi);
    }
    lo = {kInf, kInf, kInf};
    hi = {-kInf, -kInf, -kInf};
    for (size_t m = 1; m < n; ++m) {
      grow(lo, hi, it[m - 1].lo, it[m - 1].hi);
      const double cost = half_area(lo, hi) * double(m) + right_area[m] * double(n - m);
      if (cost < best) {
        best = cost;
        best_axis = a;
        best_m = m;
      }
    }
  }
  if (best_axis != 2)
    std::sort(it, it + n, [best_axis](const ViewItem& x, const ViewItem& y) {
      return x.c[best_axis] < y.c[best_axis] || (x.c[best_axis] == y.c[best_axis] && x.ref < y.ref);
    });
  return best_m;
}

GraphBoxes4 empty_boxes4() {
  GraphBoxes4 b;
  for (int a = 0; a < 3; ++a)
    for (int l = 0; l < 4; ++l) {
      b.lo[a][l] = std::numeric_limits<float>::infinity();
      b.hi[a][l] = -std::numeric_limits<float>::infinity();
    }
  return b;
}

// Sets lane l of b to (lo, hi) rounded outward (lo > hi: left empty).
void set_lane(GraphBoxes4& b, int l, Vec3d lo, Vec3d hi) {
  if (box_empty(lo, hi)) return;
  for (int a = 0; a < 3; ++a) {
    b.lo[a][l] = float_down(lo[a]);
    b.hi[a][l] = float_up(hi[a]);
  }
}

// Splits it[0, n) by SAH until at most four items are left: each such part
// becomes a cluster and its box the cluster's lane in boxes (cluster c: block
// c / 4, lane c % 4).
void build_clusters(std::vector<GraphCluster>& clusters, std::vector<GraphBoxes4>& boxes, ViewItem* it, size_t n,
                    std::vector<double>& scratch) {
  if (n > 4) {
    const size_t m = sah_split(it, n, scratch);
    build_clusters(clusters, boxes, it, m, scratch);
    build_clusters(clusters, boxes, it + m, n - m, scratch);
    return;
  }
  GraphCluster c;
  c.box = empty_boxes4();
  Vec3d lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
  for (int l = 0; l < 4; ++l) {
    c.item[l] = std::numeric_limits<uint32_t>::max();
    if (size_t(l) >= n) continue;
    c.item[l] = it[l].ref;
    set_lane(c.box, l, it[l].lo, it[l].hi);
    grow(lo, hi, it[l].lo, it[l].hi);
  }
  if (clusters.size() % 4 == 0) boxes.push_back(empty_boxes4());
  set_lane(boxes.back(), int(clusters.size() % 4), lo, hi);
  clusters.push_back(c);
}

// A trace primitive's or hop's path below the view's node.
template <typename T>
void set_path(T& item, uint8_t steps, const uint32_t* path, const uint32_t* classes) {
  item.steps = steps;
  std::copy(path, path + steps, item.path);
  std::copy(classes, classes + steps, item.classes);
}

}  // namespace

void build_view(const GraphClasses& g, ViewScratch& scratch, GraphExpansion* e, uint32_t cls, uint64_t key) {
  std::vector<GraphBox>& prim_boxes = scratch.prim_boxes;  // per tprim / hop, in this node's frame
  std::vector<GraphBox>& hop_boxes = scratch.hop_boxes;
  prim_boxes.clear();
  hop_boxes.clear();
  e->tprims.reserve(e->prims.size());  // enough without inlining
  e->hops.reserve(e->children.size());
  for (size_t i = 0; i < e->prims.size(); ++i) {
    GraphTracePrim tp{};
    tp.prim = uint32_t(i);
    e->tprims.push_back(tp);
    GraphBox b;
    prim_box(e->prims[i].shape, e->prims[i].prim.to_world, &b.lo, &b.hi);
    pad_box(b.lo, b.hi);
    prim_boxes.push_back(b);
  }
  // This node and its inlined descendants, whose children are still to be
  // placed; a descendant's expansion is made here and dropped after (cached
  // entries hold views only).
  struct Node {
    const GraphExpansion* x;
    const std::vector<DescBoxes>* desc;  // x's children's boxes, in this node's frame
    Affine3d to_node;                    // x's frame -> this node's
    Affine3d from_node;                  // this node's frame -> x's
    uint64_t key;
    uint8_t steps;
    uint32_t path[kGraphInlineDepth], classes[kGraphInlineDepth];
  };
  std::vector<std::shared_ptr<GraphExpansion>> made;
  std::vector<Node> queue(1);
  queue[0].x = e;
  queue[0].desc = &g.child_desc[cls][e->alt];
  queue[0].to_node = Affine3d::identity();
  queue[0].from_node = Affine3d::identity();
  queue[0].key = key;
  queue[0].steps = 0;
  size_t planned = e->prims.size() + e->children.size();  // primitives and hops of the view so far
  for (size_t qi = 0; qi < queue.size(); ++qi) {
    const Node nd = queue[qi];  // a copy: the queue grows
    for (size_t k = 0; k < nd.x->children.size(); ++k) {
      const GraphChild& ch = nd.x->children[k];
      const DescBoxes& db = (*nd.desc)[k];
      const uint64_t ck = ch.path_dependent ? child_path_key(nd.key, uint32_t(k)) : 0;
      Node c = nd;
      c.steps = uint8_t(nd.steps + 1);
      c.path[nd.steps] = uint32_t(k);
      c.classes[nd.steps] = ch.cls;
      if (g.inline_views && c.steps < kGraphInlineDepth && !db.sub.empty()) {
        std::shared_ptr<GraphExpansion> ce = g.expand(ch.cls, ck);
        const size_t items = ce->prims.size() + ce->children.size();
        if (items <= kGraphInlineItems && planned + items - 1 <= kGraphInlineViewItems) {
          planned += items - 1;
          c.x = ce.get();
          c.desc = &db.sub[ce->alt];
          c.to_node = compose(nd.to_node, ch.to_parent);
          c.from_node = compose(ch.to_local, nd.from_node);
          c.key = ck;
          for (size_t j = 0; j < ce->prims.size(); ++j) {
            const GraphPrimitive& cp = ce->prims[j];
            const Affine3d w = compose(c.to_node, cp.prim.to_world);  // placed in this node's frame
            csg::PrimitiveDesc d;
            d.shape = csg_shape(cp.shape);
            std::copy(w.m, w.m + 12, d.to_world);
            e->inlined_prims.push_back(GraphPrimitive{cp.shape, cp.material, trace_primitive(d)});
            GraphTracePrim tp{};
            tp.prim = uint32_t(j);
            set_path(tp, c.steps, c.path, c.classes);
            e->tprims.push_back(tp);
            GraphBox b;  // in this node's frame
            prim_box(cp.shape, w, &b.lo, &b.hi);
            pad_box(b.lo, b.hi);
            prim_boxes.push_back(b);
          }
          made.push_back(std::move(ce));
          queue.push_back(c);
          continue;
        }
      }
      GraphHop h{};
      h.to_local = compose(ch.to_local, nd.from_node);
      h.path_dependent = ch.path_dependent;
      set_path(h, c.steps, c.path, c.classes);
      e->hops.push_back(h);
      hop_boxes.push_back(db.box);
    }
  }
  e->inlined_prims.shrink_to_fit();
  e->tprims.shrink_to_fit();
  e->hops.shrink_to_fit();
  // The clusters of items; an item with an empty box (a hop to a subtree
  // that draws nothing) is never met and left out.
  std::vector<ViewItem>& items = scratch.items;
  items.clear();
  auto add_item = [&](const GraphBox& b, size_t ref) {
    if (box_empty(b.lo, b.hi)) return;
    ViewItem it;
    it.lo = b.lo;
    it.hi = b.hi;
    for (int a = 0; a < 3; ++a) it.c[a] = 0.5 * (b.lo[a] + b.hi[a]);
    it.ref = uint32_t(ref);
    items.push_back(it);
  };
  for (size_t i = 0; i < prim_boxes.size(); ++i) add_item(prim_boxes[i], i);
  for (size_t i = 0; i < hop_boxes.size(); ++i) add_item(hop_boxes[i], prim_boxes.size() + i);
  scratch.clusters.clear();
  scratch.cluster_boxes.clear();
  if (!items.empty()) build_clusters(scratch.clusters, scratch.cluster_boxes, items.data(), items.size(), scratch.areas);
  e->clusters.assign(scratch.clusters.begin(), scratch.clusters.end());
  if (scratch.clusters.size() > 1)  // one cluster is tested without its box
    e->cluster_boxes.assign(scratch.cluster_boxes.begin(), scratch.cluster_boxes.end());
  std::vector<GraphChild>().swap(e->children);
  std::vector<uint32_t>().swap(e->prims_before);
  // The vectors are final: point the trace primitives at their primitives.
  const size_t own = e->prims.size();
  for (size_t i = 0; i < e->tprims.size(); ++i)
    e->tprims[i].gp = i < own ? &e->prims[e->tprims[i].prim] : &e->inlined_prims[i - own];
  e->has_view = true;
  e->bytes = expansion_bytes(*e);
}

}  // namespace plm::lsystem

// L-system scene graph traced without flattening (lsystem/graph/graph.h): the
// public face of the node classes (lsystem/graph/graph_classes.h) and of the
// per-thread traversal state (lsystem/graph/graph_impl.h); the traversal itself is
// in lsystem/graph/graph_trace.cpp.
#include "lsystem/graph/graph.h"

#include <algorithm>
#include <memory>
#include <vector>

#include "lsystem/graph/embree_callbacks.h"
#include "lsystem/graph/geometry.h"
#include "lsystem/graph/graph_impl.h"
#include "util/error.h"

namespace plm::lsystem {


namespace {

// Appends the primitives below class cls (path key `key`, placed by
// to_world) in successor order, at most cap. level: child steps from the
// root; key_level < 0: no keys; stub: the ancestor key at key_level inherited
// from above. memo: per class, its expansion where the class is not path
// dependent (flatten() keeps its own expansions: cache entries hold only the
// traversal view).
void flatten_class(const GraphClasses& g, uint32_t cls, uint64_t key, const Affine3d& to_world, size_t cap,
                   FlattenResult& out, std::vector<std::shared_ptr<const GraphExpansion>>& memo, int level,
                   int key_level, uint64_t stub) {
  if (out.truncated) return;
  if (level <= key_level) stub = key;
  std::shared_ptr<const GraphExpansion> e;
  if (g.classes[cls].path_dependent) {
    e = g.expand(cls, key);
  } else {
    if (!memo[cls]) memo[cls] = g.expand(cls, 0);
    e = memo[cls];
  }
  auto emit = [&](size_t from, size_t to) {
    for (size_t i = from; i < to; ++i) {
      if (out.primitives.size() >= cap) {
        out.truncated = true;
        return;
      }
      const GraphPrimitive& gp = e->prims[i];
      TurtlePrimitive p;
      p.shape = gp.shape;
      p.material = gp.material;
      const Affine3d w = compose(to_world, gp.prim.to_world);
      std::copy(w.m, w.m + 12, p.to_world);
      out.primitives.push_back(p);
      if (key_level >= 0) out.keys.push_back(stub);
    }
  };
  size_t done = 0;
  for (size_t i = 0; i < e->children.size() && !out.truncated; ++i) {
    emit(done, e->prims_before[i]);
    done = e->prims_before[i];
    if (out.truncated) return;
    flatten_class(g, e->children[i].cls, child_path_key(key, uint32_t(i)), compose(to_world, e->children[i].to_parent),
                  cap, out, memo, level + 1, key_level, stub);
  }
  if (!out.truncated) emit(done, e->prims.size());
}

}  // namespace

Graph::Graph(const LSystem& system, const GraphOptions& options)
    : impl_(std::make_unique<Impl>(system, options)) {}

Graph::~Graph() = default;

Vec3d Graph::bounds_lo() const { return impl_->g.classes[0].lo; }
Vec3d Graph::bounds_hi() const { return impl_->g.classes[0].hi; }
Vec3d Graph::world_bounds_lo() const { return impl_->g.world_lo; }
Vec3d Graph::world_bounds_hi() const { return impl_->g.world_hi; }
const GraphNodeClass& Graph::node_class(uint32_t id) const { return impl_->g.classes.at(id); }
uint64_t Graph::root_key() const { return impl_->g.root_key; }

uint64_t Graph::child_key(uint64_t key, uint32_t index) { return child_path_key(key, index); }

uint64_t Graph::ancestor_key(const GraphHit& hit, int level) const {
  return ancestor_path_key(impl_->g.root_key, hit, level);
}

GraphStats Graph::stats() const {
  const GraphClasses& g = impl_->g;
  GraphStats s;
  s.classes = g.classes.size();
  s.levels = g.levels;
  s.bounds_visits = g.bounds_visits;
  s.class_bytes = g.classes.size() * (sizeof(GraphNodeClass) + sizeof(TurtleState) + 96) +
                  g.desc_boxes * sizeof(DescBoxes);
  for (const GraphNodeClass& c : g.classes)
    s.class_bytes += c.params.capacity() * 8 * 2 + c.alternatives.capacity() * sizeof(c.alternatives[0]);
  for (const TraceThread& t : impl_->threads) {
    const ExpansionCache& c = t.cache;
    s.cache_hits += c.hits();
    s.cache_misses += c.misses();
    s.evictions += c.evictions();
    s.bypassed += c.bypassed();
    s.cached_entries += c.entries();
    s.cached_bytes += c.bytes();
    s.peak_cached_bytes += c.peak_bytes();
    s.truncated += t.truncated;
  }
  s.flattened_primitives = g.classes[0].max_primitives;
  return s;
}

void Graph::reset_cache() const {
  for (TraceThread& t : impl_->threads) {
    t.cache.reset();
    t.truncated = 0;
  }
}

FlattenResult Graph::flatten(size_t max_primitives) const {
  FlattenResult out;
  std::vector<std::shared_ptr<const GraphExpansion>> memo(impl_->g.classes.size());
  flatten_class(impl_->g, 0, root_key(), Affine3d::identity(), max_primitives, out, memo, 0, -1, 0);
  return out;
}

FlattenResult Graph::flatten(size_t max_primitives, int key_level) const {
  if (key_level < 0) fail(PLM_ERROR_INVALID_ARGUMENT, "lsystem graph: flatten key level must be >= 0, got ", key_level);
  FlattenResult out;
  std::vector<std::shared_ptr<const GraphExpansion>> memo(impl_->g.classes.size());
  flatten_class(impl_->g, 0, root_key(), Affine3d::identity(), max_primitives, out, memo, 0, key_level, 0);
  return out;
}

// ---- Embree ----

namespace {

void graph_bounds(const RTCBoundsFunctionArguments* args) {
  const Graph& g = *static_cast<const Graph*>(args->geometryUserPtr);
  write_bounds(g.bounds_lo(), g.bounds_hi(), 0.0, args->bounds_o);
}

}  // namespace

unsigned attach_graph(RTCDevice device, RTCScene scene, const Graph& graph) {
  return attach_user_geometry<graph_bounds, intersect_n<Graph>, occluded_n<Graph>>(device, scene, &graph);
}

}  // namespace plm::lsystem

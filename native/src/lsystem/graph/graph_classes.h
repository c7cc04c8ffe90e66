// The node classes of an L-system graph and the expansion of a node.
//
// A node class is (module symbol, constant parameters, remaining depth d,
// turtle width and material on entry). Expanding an instance of (X, d)
// rewrites X once and runs the turtle (lsystem/language/turtle_state.h) over the
// successor from a local frame at the origin: terminal modules draw primitives
// in that frame, every non-terminal module Y becomes a child reference
// (Y, d - 1) with the turtle's frame at that point as a rigid transform, and
// the child's net effect (end frame, width, material: part of its class) is
// composed into the turtle after the reference. A module is terminal at d = 0
// or when no production can rewrite it. The root is the axiom at the
// derivation depth D (class depth D + 1). The set-up interns every class
// reachable from the root, bottom-up, with its box and its child references'
// boxes (lsystem/graph/graph_bounds.h); afterwards the classes are immutable.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <tuple>
#include <utility>
#include <vector>

#include "lsystem/graph/graph.h"
#include "lsystem/graph/graph_bounds.h"
#include "lsystem/graph/graph_expansion.h"
#include "lsystem/language/lsystem.h"
#include "lsystem/language/turtle_state.h"
#include "util/math.h"
#include "util/rng.h"

namespace plm::lsystem {

constexpr uint32_t kRootSymbol = UINT32_MAX;  // GraphNodeClass::symbol of the root (the axiom)

// A class's identity: parameters and width by their bits with the mantissa
// rounded to 40 bits (values equal but for rounding are one state; the state
// keeps the value it was first met with).
struct ClassKey {
  uint32_t symbol;
  int depth;
  uint64_t width_bits;
  int32_t material;
  std::vector<uint64_t> params;
  bool operator<(const ClassKey& o) const {
    return std::tie(symbol, depth, width_bits, material, params) <
           std::tie(o.symbol, o.depth, o.width_bits, o.material, o.params);
  }
};

// Path keys: the root's is splitmix64(seed), the i-th child reference (in
// successor order) of an instance with key k has splitmix64(k ^
// splitmix64(i + 1)) (Graph::child_key).
inline uint64_t child_path_key(uint64_t key, uint32_t index) { return splitmix64(key ^ splitmix64(uint64_t(index) + 1)); }
// The path key of the hit's ancestor at `level` (Graph::ancestor_key).
inline uint64_t ancestor_path_key(uint64_t root_key, const GraphHit& hit, int level) {
  uint64_t k = root_key;
  for (int l = 0; l < std::min(level, hit.levels); ++l) k = child_path_key(k, hit.path[l]);
  return k;
}

struct GraphClasses {
  // The set-up: throws plm::Error for what the graph cannot represent (graph.h).
  GraphClasses(const LSystem& system, const GraphOptions& options);

  // What the turtle draws for the instance of class cls with path key `key`
  // (the production drawn from the key where the class is stochastic):
  // primitives and child references, no view.
  std::shared_ptr<GraphExpansion> expand(uint32_t cls, uint64_t key) const;

  LSystem sys;
  GraphOptions opt;
  double step = 1, angle = 90, width = 0.1;  // the options', or else the system's
  int32_t material = 0;
  int levels = 0;                     // depth + 1
  size_t vars = 0;                    // formal parameter slots of the largest production
  uint64_t root_key = 0;
  bool inline_views = true;           // see kGraphInlineMinCacheBytes
  std::vector<GraphNodeClass> classes;
  std::vector<TurtleState> end;       // per class: net turtle state at its end (first production's)
  std::vector<uint8_t> end_variable;  // per class: productions end in different states
  std::map<ClassKey, uint32_t> index;
  std::vector<std::vector<std::vector<DescBoxes>>> child_desc;  // [class][production][child]
  Vec3d world_lo, world_hi;           // Graph::world_bounds_lo() / hi()
  uint64_t bounds_visits = 0;         // GraphStats::bounds_visits
  size_t desc_boxes = 0;              // DescBoxes in child_desc (for GraphStats::class_bytes)
};

}  // namespace plm::lsystem

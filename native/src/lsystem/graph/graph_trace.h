// A thread's traversal state for tracing rays through an L-system graph
// (the traversal itself: lsystem/graph/graph_trace.cpp, Graph::first_hit and
// Graph::occluded).
#pragma once

#include <cstdint>
#include <vector>

#include "lsystem/graph/graph.h"
#include "lsystem/graph/graph_cache.h"
#include "lsystem/graph/graph_expansion.h"
#include "util/math.h"

namespace plm::lsystem {

// A level of the traversal: the node's expansion and the ray in its frame.
struct TraceFrame {
  const GraphExpansion* e = nullptr;
  Vec3d o, d;
  // The ray for the float box tests (boxes4 in graph_trace.cpp), per axis (x,
  // y, z, unused): 1 / d and the origin moved down or up so that the near and
  // the far slab distances err outward.
  alignas(16) float inv[4], on[4], of[4];
  uint8_t near[3], far[3];         // per axis: the float offset in a GraphBoxes4 of the side met first / last
  uint64_t key = 0;                // path key where the class is path dependent (and the root), else 0
  const GraphHop* via = nullptr;   // how the ray got here from the frame above (null at the root)
};

// A hop still to enter.
struct TracePending {
  double t;                        // box entry along the ray
  uint32_t level, hop;             // hop `hop` of the node at `level`
};

struct TraceThread {
  ExpansionCache cache;
  std::vector<TraceFrame> frames;     // kMaxGraphLevels + 1, one per level
  std::vector<TracePending> pending;  // hops still to enter, nearest at the back
  uint64_t truncated = 0;             // GraphStats::truncated
};

}  // namespace plm::lsystem

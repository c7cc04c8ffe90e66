// What a Graph holds: its immutable node classes and, per thread that
// traces, a traversal state with its own expansion cache (no lock and no
// shared atomic per ray).
#pragma once

#include <tbb/enumerable_thread_specific.h>

#include <atomic>
#include <cstdint>

#include "lsystem/graph/graph.h"
#include "lsystem/graph/graph_classes.h"
#include "lsystem/graph/graph_trace.h"

namespace plm::lsystem {

struct Graph::Impl {
  Impl(const LSystem& system, const GraphOptions& options) : g(system, options) {}

  GraphClasses g;
  mutable tbb::enumerable_thread_specific<TraceThread> threads;
  // Never reused, so a thread's remembered (id, state) can only be this graph's.
  const uint64_t id = next_id();

  static uint64_t next_id() {
    static std::atomic<uint64_t> counter{0};
    return ++counter;
  }
  // The calling thread's state: threads.local() (a hash lookup) once per thread and graph in a row.
  TraceThread& local() const {
    struct Last {
      uint64_t id = 0;
      TraceThread* state = nullptr;
    };
    static thread_local Last last;
    if (last.id != id) last = {id, &threads.local()};
    return *last.state;
  }
};

}  // namespace plm::lsystem

// What the C API's opaque handles hold. Only the API and in-tree tools and
// benchmarks that need the engine's internals include this.
#pragma once

#include "scene/scene.h"
#include "transport/control/bake.h"
#include "transport/control/live_preview.h"

struct plm_scene {
  plm::Scene scene;
};

struct plm_result {
  plm::BakeOutput output;
};

// Valid only during the host's preview callback (plm_bake_with_preview).
struct plm_preview {
  const plm::Snapshot& snapshot;
};

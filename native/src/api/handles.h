// What the C API's opaque handles hold. Only the API and in-tree tools and
// benchmarks that need the engine's internals include this.
#pragma once

#include "scene/scene.h"
#include "transport/bake.h"

struct plm_scene {
  plm::Scene scene;
};

struct plm_result {
  plm::BakeOutput output;
};

// The bake's context (docs/design/README.md, "The bake context"): what the
// set-up builds once and every stage reads. The scene, the engine's settings,
// the threads, the Embree scene, the texel space, the lights, the materials'
// lobes, the passage of straight rays through panes, the OL views the photons
// record into. Built by set_up (transport/control/stages.h); the passes'
// constructors take it whole.
#pragma once

#include <tbb/task_arena.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "accel/embree_scene.h"
#include "lsystem/lsystem_object.h"
#include "ol/octahedral.h"
#include "ol/orientation_lightmap.h"
#include "scene/scene.h"
#include "scene/texture.h"
#include "transport/context/texel_space.h"
#include "transport/context/split.h"
#include "transport/lights/emitters.h"
#include "transport/materials/material_table.h"
#include "transport/plan/settings.h"
#include "transport/rays/passage.h"
#include "transport/rays/tracing.h"

namespace plm {

constexpr uint32_t kNoBin = ~0u;

// A mesh as the photon tracer sees its OL group: group -1 for none, else
// where each triangle's hits go in the group's OL (Splat::nearest kNoBin for
// degenerate triangles).
struct OlMeshView {
  int32_t group = -1;
  const ol::Splat* splats = nullptr;
  bool backup = false;  // a backup OL: it records what the mesh's texels record (the indirect hits)
};

// L-system objects: each one's OL grid and its root and stub areas from the
// flattened object (transport/output/ol_film.h build_lsystem_ols).
struct LSystemOls {
  std::vector<ol::OctGrid> grids;          // per L-system object
  std::vector<lsystem::OlAreas> areas;     // per L-system object
};

struct BakeScene {
  BakeScene(const Scene& s, const BakeSettings& settings_in, unsigned thread_count)
      : scene(s), settings(settings_in), threads(thread_count), arena(static_cast<int>(thread_count)) {}
  BakeScene(const BakeScene&) = delete;
  BakeScene& operator=(const BakeScene&) = delete;

  const Scene& scene;
  BakeSettings settings;  // as requested, fitted to the scene (transport/plan/validate.h effective_settings)
  const unsigned threads;
  mutable tbb::task_arena arena;  // every parallel stage runs in it

  std::unique_ptr<EmbreeScene> accel;
  RTCScene rtc = nullptr;  // accel's
  float extent = 0.0f;     // the diagonal of the scene's bounds (ray offsets scale with it)

  TexelSpace space;                            // the texels; views carry contact and Burley arrays below
  std::vector<std::vector<uint8_t>> contact;   // per mesh: texels that may be pressed against another surface
  std::vector<std::vector<float>> burley;      // per mesh, per triangle: Burley roughness, < 0 for Lambert
  SurfaceMap surfaces;
  std::vector<OlMeshView> ol_views;  // per mesh (splats owned by the OL groups, transport/output/ol_film.h)
  LSystemOls ls_ols;

  std::unique_ptr<TextureSet> textures;  // null unless a material names an image
  std::vector<Emitter> emitters;
  double emitted = 0.0;  // W, all emitters together
  // Light groups (docs/design/light-groups.md): the group of each layer
  // (0: the default group); empty without groups.
  std::vector<uint32_t> layers;
  // What the texels keep of each sample's light besides their sums: the
  // layers, and with directional lightmaps the direction moment (transport/context/split.h).
  SplitLayout split;

  MaterialTable lobes;                     // empty in scenes without lobes or Burley surfaces
  bool caustics = false;                   // lobes.any_lobes(): caustic photons get sums of their own
  std::unique_ptr<PassageTracer> passage;  // null unless some material lets straight rays pass
};

}  // namespace plm

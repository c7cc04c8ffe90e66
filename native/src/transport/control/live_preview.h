// Live previews: the host looks at the lightmaps while the bake runs. At the
// bake's check points (after each round of the direct pass and after the
// pass, between groups of photon batches) a LivePreview decides whether a
// snapshot is due (at most every `interval` seconds) and hands the host a
// Snapshot: a read-only view of the film at that state. The host copies out the lightmaps it wants during the callback; each
// copy reconstructs that one lightmap from the sums without changing them, so
// previews never change the bake's result. Without a hook a check point costs
// one branch.
#pragma once

#include <tbb/task_arena.h>

#include <cstdint>
#include <functional>

#include "scene/scene.h"
#include "transport/output/film_estimate.h"
#include "transport/plan/scheduler.h"

namespace plm {

// The film at one state of the bake; valid only during the host's callback.
class Snapshot {
 public:
  Snapshot(tbb::task_arena& arena, const Scene& scene, const Estimator& est, uint64_t photons, uint32_t dilation)
      : arena_(arena), scene_(scene), est_(est), photons_(photons), dilation_(dilation) {}
  uint64_t photons() const { return photons_; }
  // Mesh `mesh`; throws PLM_ERROR_INVALID_ARGUMENT for a mesh out of range or without a lightmap.
  const Mesh& lightmap_mesh(uint32_t mesh) const;
  // Mesh `mesh`'s lightmap at this state into rgb (width * height * 3 floats,
  // rows bottom first): the estimate of every covered texel, dilated over the
  // island borders like the final image, but without seam stitching nor the
  // OL backup blend. Returns false, writing nothing, for a mesh whose texels
  // come from an OL group or a CSG solid (they are known only at the end).
  // Throws as lightmap_mesh does.
  bool copy_lightmap(uint32_t mesh, float* rgb) const;

 private:
  tbb::task_arena& arena_;
  const Scene& scene_;
  const Estimator& est_;
  uint64_t photons_;
  uint32_t dilation_;
};

// What the host asks for: a callback (false cancels the bake) and the least
// time between two snapshots.
struct PreviewHook {
  std::function<bool(const Snapshot&)> callback;
  double interval = 0.0;  // seconds; <= 0: no snapshots
};

// Decides at each check point whether a snapshot is due and takes it.
class LivePreview {
 public:
  // hook may be null (no previews).
  LivePreview(const PreviewHook* hook, Clock::time_point start) : hook_(hook), last_(start) {
    if (hook_ && !(hook_->interval > 0.0 && hook_->callback)) hook_ = nullptr;
  }
  bool active() const { return hook_ != nullptr; }
  // A check point: `photons` photons are merged into est. `first` forces a
  // snapshot (the end of the direct pass, the first state worth showing).
  // Throws PLM_ERROR_CANCELLED when the host's callback returns false.
  void check(tbb::task_arena& arena, const Scene& scene, const Estimator& est, uint64_t photons, uint32_t dilation,
             bool first = false) {
    if (hook_) take(arena, scene, est, photons, dilation, first);
  }

 private:
  void take(tbb::task_arena& arena, const Scene& scene, const Estimator& est, uint64_t photons, uint32_t dilation,
            bool first);
  const PreviewHook* hook_;
  Clock::time_point last_;
};

}  // namespace plm

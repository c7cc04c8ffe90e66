// The bakes as compositions of the stages (transport/control/stages.h): one
// machine's bake, and the parts of a bake split over machines (docs/farm.md,
// docs/design/sharding.md): a shard's photons, a texel range's direct pass or
// final gather, the merge. Each refines the scene's pending subdivision cages
// first (counted in the set-up time) and throws plm::Error on invalid input
// and PLM_ERROR_CANCELLED on cancel.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "scene/scene.h"
#include "transport/control/bake.h"
#include "transport/control/live_preview.h"
#include "transport/plan/settings.h"

namespace plm {

// The whole bake on one machine. preview (may be null): snapshots of the
// lightmaps while the bake runs.
BakeOutput bake(Scene& scene, const BakeSettings& settings, const ProgressFn& progress,
                const PreviewHook* preview = nullptr);

// Where a part of a split bake goes: the part file, and the scene file's
// path recorded in it (at most 255 bytes).
struct PartTarget {
  std::string scene_path, part_path;
};

// Shard `shard` of `count`: its photon batches into a photon part; no direct
// pass, no outputs. progress ends at 1 once the part is written.
void bake_shard(Scene& scene, const BakeSettings& settings, uint32_t shard, uint32_t count,
                const PartTarget& target, const ProgressFn& progress);

// The direct pass of texel range `range` of `count` into a direct part.
void bake_direct_range(Scene& scene, const BakeSettings& settings, uint32_t range, uint32_t count,
                       const PartTarget& target, const ProgressFn& progress);

// The final gather of texel range `range` of `count` over the photon and
// direct parts in `parts` into a gather part; the settings are the parts'
// with thread_count's threads.
void bake_gather_range(Scene& scene, uint32_t thread_count, uint32_t range, uint32_t count,
                       const std::vector<std::string>& parts, const PartTarget& target, const ProgressFn& progress);

// The bake from every shard's photon part (and any complete set of direct
// and gather parts, joined instead of run), as one machine bakes it.
BakeOutput bake_merge(Scene& scene, const std::vector<std::string>& parts, uint32_t thread_count,
                      const ProgressFn& progress);

}  // namespace plm

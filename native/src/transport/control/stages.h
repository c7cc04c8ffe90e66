// The stages of a bake (docs/design/README.md, "Stages and compositions"):
// functions over the context (transport/context/bake_scene.h), each handing
// on what it made in a BakeRun. The compositions (transport/jobs/) call them
// in turn: the one-machine bake, a shard's photons, the merge, the texel
// ranges' direct pass and gather. A stage does its own part over the range
// it is given and knows nothing of which composition runs it.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "scene/scene.h"
#include "transport/context/bake_scene.h"
#include "transport/control/bake.h"
#include "transport/control/live_preview.h"
#include "transport/direct/direct_rounds.h"
#include "transport/farm/shard.h"
#include "transport/film/film.h"
#include "transport/gather/final_gather.h"
#include "transport/output/film_estimate.h"
#include "transport/output/ol_film.h"
#include "transport/photons/photon_tracer.h"
#include "transport/plan/scheduler.h"
#include "transport/plan/settings.h"

namespace plm {

// Progress: set-up until kProgressSetup; the direct pass until
// kProgressDirect (kProgressPhotons without photons); photons and the final
// gather until kProgressPhotons; the outputs the rest.
constexpr double kProgressSetup = 0.05, kProgressDirect = 0.35, kProgressPhotons = 0.95;

// What a bake's stages hand on to each other: the outputs so far, the photon
// sums and OLs, the direct pass's and the gather's results, the latest estimate.
struct BakeRun {
  explicit BakeRun(const ProgressFn& progress, const PreviewHook* preview = nullptr);

  Clock::time_point t_start;
  BakeOutput out;
  Progress report;
  TimeBudget budget;  // the settings' (check_bake)
  LivePreview live;   // snapshots for the host at check points (live_preview.h)

  OlGroups ol_groups;                    // the OLs the photons fill
  Accumulators acc{0, 0};                // photon sums (empty until photons are added)
  std::unique_ptr<PhotonTracer> tracer;  // built by the first photon stage
  DirectResult direct;
  GatherResult gather;  // empty unless the final gather ran
  bool gathered = false;
  uint32_t gathers = 0;
  uint32_t gather_samples = 0;  // rays per texel of the last gather
  uint64_t gather_photons = 0;  // the photons whose estimate the last gather looked up
  uint64_t gather_rays = 0;     // rays the gathers traced (about: texels x samples)
  RegatherPlan next_gather;     // the gather after the last: the groups it refines (transport/plan/scheduler.h)
  OpenShares open_shares;  // the gathers' (transport/gather/final_gather.h), kept from one to the next
  uint64_t photons = 0;    // photons merged into acc
  Estimate last;           // the latest estimate
  double truncated_flux = 0.0;
  uint64_t ol_hits = 0;
  Clock::time_point t_trace;
};

// What runs when the photons reach the final gather: final_gather over a
// texel range, or gathers made elsewhere joined.
using GatherStep = std::function<void(const BakeScene&, BakeRun&)>;

// ---- Set-up ----------------------------------------------------------------
// Refines the scene's pending subdivision cages (counted in the set-up time),
// checks the settings, the scene and the memory; returns the settings fitted
// to the scene (transport/plan/validate.h effective_settings). Throws plm::Error.
BakeSettings check_bake(Scene& scene, const BakeSettings& requested, BakeRun& run);

// The context: the Embree scene, texel areas, OL groups (into run.ol_groups),
// L-system OLs (run.out.lsystems), textures, emitters, faces in contact,
// specular lobes, passages; run.acc shaped for the photon sums.
std::unique_ptr<BakeScene> set_up(const Scene& scene, const BakeSettings& settings, BakeRun& run);

// The estimator over run's sums, direct light and gather.
Estimator estimator(const BakeScene& ctx, const BakeRun& run);

// ---- Direct pass -------------------------------------------------------------
// The direct pass over the covered texels of `slice` (all by default) into
// run.direct, in rounds under the budget, with previews between them and of
// the direct light alone at the end.
void direct_pass(const BakeScene& ctx, BakeRun& run, CoveredSlice slice = {});

// ---- Photons -----------------------------------------------------------------
// Every photon batch of the bake, traced in groups in parallel and merged in
// batch order, steered by the target error and the time budget; `gather` runs
// at kCheckBatches batches (no target) or at the first check the photons alone
// do not pass.
void trace_photons(const BakeScene& ctx, BakeRun& run, const GatherStep& gather);

// Batches [first, last) as segments cut at kCheckBatches (transport/farm/shard.h),
// each summed on its own.
std::vector<PhotonSegment> trace_batches(const BakeScene& ctx, BakeRun& run, uint64_t first, uint64_t last);

// Sums traced elsewhere (segments tiling the batches in order) added to run.acc;
// `gather` runs where the one-machine bake would run it.
void add_photon_segments(const BakeScene& ctx, BakeRun& run, const std::vector<PhotonSegment>& segments,
                         const GatherStep& gather);

// ---- Final gather ------------------------------------------------------------
// Counts a gather; false where the budget leaves it no time.
bool start_gather(BakeRun& run);

// The final gather over the covered texels of `slice` from run.last, replacing
// run.gather.
void final_gather(const BakeScene& ctx, BakeRun& run, CoveredSlice slice = {});
// The texels' open shares a gather finds (final_gather.h, OpenShares), for
// gathers made elsewhere (the texel ranges'): the estimate counts texels by them.
void find_open_shares(const BakeScene& ctx, BakeRun& run);

// ---- Estimate and output -----------------------------------------------------
// The final estimate and its error figures (stats, a warning where the target
// was missed).
void estimate_result(const BakeScene& ctx, BakeRun& run);

// The OLs, the L-system objects and the lightmaps into run.out.
void write_outputs(const BakeScene& ctx, BakeRun& run);

}  // namespace plm

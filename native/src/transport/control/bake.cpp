// The bake from top to bottom: checks and set-up, the direct pass, the photon
// pass with the final gather, the final estimate, the outputs. Each stage
// lives in a file of its own; this one says in which order they run and what
// flows from one to the next.
#include "transport/control/bake.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <thread>

#include "accel/embree_scene.h"
#include "scene/texture.h"
#include "transport/control/live_preview.h"
#include "transport/direct/direct.h"
#include "transport/direct/direct_rounds.h"
#include "transport/farm/shard.h"
#include "transport/farm/texel_ranges.h"
#include "transport/film/film.h"
#include "transport/film/photon_batches.h"
#include "transport/gather/final_gather.h"
#include "transport/lights/emitters.h"
#include "transport/materials/material_table.h"
#include "transport/output/film_estimate.h"
#include "transport/output/film_output.h"
#include "transport/output/ol_film.h"
#include "transport/photons/photon_sampler.h"
#include "transport/photons/photon_tracer.h"
#include "transport/plan/scheduler.h"
#include "transport/plan/validate.h"
#include "transport/rays/passage.h"
#include "transport/rays/tracing.h"
#include "util/error.h"

namespace plm {
namespace {

// Progress: set-up until kProgressSetup; the direct pass until
// kProgressDirect (kProgressPhotons without photons); photons and the final
// gather until kProgressPhotons; the outputs the rest.
constexpr double kProgressSetup = 0.05, kProgressDirect = 0.35, kProgressPhotons = 0.95;
// Progress is reported at most this often (seconds) while photons are traced.
constexpr double kPhotonReportInterval = 0.1;
// The final gather runs only where max_bounces does not truncate light (the
// default is 1024): its lookups carry every bounce, so it would add one.
constexpr uint32_t kGatherMinBounces = 64;

}  // namespace

plm_bake_settings default_settings() {
  plm_bake_settings s;
  s.struct_size = uint32_t(sizeof s);
  s.photon_count = 1000000;
  s.max_bounces = 1024;
  s.seed = 0;
  s.thread_count = 0;
  s.dilation = 8;
  s.target_error = 0.0;
  s.time_budget = 0.0;
  s.direct_samples = 64;
  s.filter_radius = 2;
  s.texel_value = PLM_TEXEL_CYCLES;
  s.sampler = PLM_SAMPLER_DEFAULT;
  return s;
}

BakeOutput bake(Scene& pending_scene, const plm_bake_settings& requested, const ProgressFn& progress,
                const PreviewHook* preview, ShardJob* job) {
  const auto t_start = Clock::now();
  pending_scene.refine_cages(requested.thread_count);
  const Scene& scene = pending_scene;
  validate(scene, requested);
  BakeOutput out;
  out.stats.memory_estimate = check_memory(scene, out.warnings);  // before allocating anything
  const plm_bake_settings settings = effective_settings(scene, requested, out.warnings);
  if (job) check_shardable(scene, settings, job->mode);
  const bool tracing_shard = job && job->mode == ShardJob::kTrace;
  Progress report(progress);
  const TimeBudget budget(settings.time_budget, t_start);
  LivePreview live(preview, t_start);  // snapshots for the host at check points (live_preview.h)

  // ---- Set-up ------------------------------------------------------------------
  report(0.0, "building the ray-tracing scene");
  const unsigned threads = settings.thread_count ? settings.thread_count
                                                 : std::max(1u, std::thread::hardware_concurrency());
  EmbreeScene accel(scene, threads);
  tbb::task_arena arena(static_cast<int>(threads));
  const Vec3 lo = accel.bounds_min(), hi = accel.bounds_max();
  if (!is_finite(lo) || !is_finite(hi) || lo.x > hi.x)
    fail(PLM_ERROR_INVALID_SCENE, "the scene has no triangle with a non-zero area");
  const float extent = length(hi - lo);

  report(0.02, "computing texel areas");
  TexelSpace space;
  arena.execute([&] { space = build_texel_space(scene, out.warnings); });
  OlGroups ol_groups = build_ol_groups(scene, out.warnings);
  if (!scene.lsystems.empty()) report(0.03, "estimating L-system OL areas");
  const LSystemOls ls_ols = build_lsystem_ols(scene, arena, out.lsystems, out.warnings);

  // Image textures: a TextureSet only when a material names one.
  std::unique_ptr<TextureSet> textures;
  if (scene.has_textures()) {
    report(0.04, "loading textures");
    textures = std::make_unique<TextureSet>(scene);
    for (const std::string& w : textures->warnings) out.warnings.push_back(w);
  }
  const std::vector<Emitter> emitters = build_emitters(scene, photon_footprint(scene, lo, hi), textures.get());
  double emitted = 0.0;
  for (const Emitter& e : emitters) emitted += average(e.flux);
  if (!std::isfinite(emitted) || emitted > 1e30)
    fail(PLM_ERROR_INVALID_SCENE, "the lights emit ", emitted, " W together, beyond the engine's range "
         "(1e30 W): check light powers, colours and emission strengths");
  if (emitters.empty())
    fail(PLM_ERROR_INVALID_SCENE, "nothing lights the scene: it has no light with power, no emissive material and "
         "no world light, so every lightmap would be black");
  out.stats.emitted_power = emitted;

  // Faces pressed against other surfaces (transport/rays/tracing.h: in_contact).
  report(kProgressSetup, "finding faces in contact");
  std::vector<std::vector<uint8_t>> contact;  // per mesh: texels that may be pressed against another surface
  const SurfaceMap surfaces = surface_map(scene, space.views);
  arena.execute([&] { contact = contact_candidates(accel.handle(), scene, space.views, surfaces, 1e-6f * extent); });
  for (size_t i = 0; i < space.views.size(); ++i)
    if (!contact[i].empty()) space.views[i].contact = contact[i].data();
  // Specular lobes (docs/design/materials.md): flattened, and the passage
  // of straight rays through panes and transparent surfaces; nothing in
  // scenes without lobes.
  const MaterialTable lobes = scene.has_lobes() || scene.has_burley() ? MaterialTable(scene) : MaterialTable();
  // Burley surfaces (Cycles 3.4's Principled diffuse): each triangle's roughness, for what their texels record.
  std::vector<std::vector<float>> burley(scene.has_burley() ? space.views.size() : 0);
  for (size_t i = 0; i < burley.size(); ++i) {
    const Mesh& mesh = *space.views[i].mesh;
    bool any = false;
    burley[i].resize(mesh.triangle_count(), -1.0f);
    for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
      const uint32_t id = mesh.material_ids[t];
      if (id < scene.materials.size() && scene.materials[id].diffuse_model == PLM_DIFFUSE_BURLEY) {
        burley[i][t] = scene.materials[id].diffuse_roughness;
        any = true;
      }
    }
    if (any) space.views[i].burley = burley[i].data();
  }
  std::unique_ptr<PassageTracer> passage;
  if (lobes.any_passage()) passage = std::make_unique<PassageTracer>(scene, lobes, space.views, surfaces, extent);
  out.stats.seconds_setup = seconds_since(t_start);

  const bool two_pass = settings.direct_samples > 0;
  const bool photon_pass = !two_pass || settings.max_bounces > 0;
  const double direct_end = photon_pass ? kProgressDirect : kProgressPhotons;

  // ---- Direct pass ---------------------------------------------------------------
  Accumulators acc(space.texel_count, scene.meshes.size(), lobes.any_lobes(),
                   flux_quantum(emitted));  // photon sums (empty until then)
  if (job) job->layout = shard_layout(scene, settings, space, acc);  // sharded bakes (transport/farm/shard.h)
  DirectResult direct;
  const auto t_direct = Clock::now();
  if (two_pass && !tracing_shard && job && !job->direct.empty()) {  // the texel ranges' (transport/farm/texel_ranges.h)
    arena.execute([&] { direct = join_direct(job->direct, settings.sampler, space); });
    out.stats.direct_samples = direct.samples;
  } else if (two_pass && !tracing_shard) {
    const DirectPass pass(accel.handle(), surfaces, space.views, space.csg_views, space.areas, emitters, settings,
                          extent, textures.get(), passage.get());
    const double share = photon_pass ? kDirectBudgetShare : kDirectOnlyBudgetShare;
    DirectControl control{
        [&](double f) { report(kProgressSetup + (direct_end - kProgressSetup) * f, "direct light"); },
        [&] { return budget.spent(share); },
        nullptr};
    if (live.active())  // previews between rounds; the first shows the first round at once
      control.round_done = [&](uint32_t round, const DirectResult& sofar) {
        const Estimator est{space, sofar.values, acc, settings.filter_radius, nullptr};
        live.check(arena, scene, est, 0, settings.dilation, round == 0);
      };
    direct = run_direct_pass(arena, pass, space, settings, control,
                             job_slice(job, ShardJob::kDirect, space.covered.size()));
    out.stats.direct_samples = direct.samples;
  }
  out.stats.seconds_direct = seconds_since(t_direct);
  if (job && job->mode == ShardJob::kDirect) {  // a texel range's direct pass: its sums are the part
    job->direct.assign(1, std::move(direct));
    out.stats.seconds_total = seconds_since(t_start);
    return out;
  }

  // ---- Photon pass and final gather ------------------------------------------------
  GatherResult gather;  // empty unless the final gather ran
  // The final gather (transport/gather/final_gather.h) looks up radiosity on meshes: not in
  // scenes with CSG solids, L-systems or textures, nor with few bounces.
  const bool gather_wanted = photon_pass && two_pass && scene.csgs.empty() && scene.lsystems.empty() && !textures &&
                             settings.max_bounces >= kGatherMinBounces;
  const Estimator estimator{space, direct.values, acc, settings.filter_radius, &gather, gather_wanted};
  uint64_t photons = 0;
  Estimate last;  // the latest estimate
  if (two_pass) live.check(arena, scene, estimator, 0, settings.dilation);  // the direct light alone
  const auto t_trace = Clock::now();
  if (photon_pass) {
    const bool steered = settings.target_error > 0.0 || settings.time_budget > 0.0;
    const bool targeted = settings.target_error > 0.0;
    const uint64_t cap = settings.photon_count ? settings.photon_count : (uint64_t(1) << 40);
    const uint64_t batch_count = (cap + kBatchPhotons - 1) / kBatchPhotons;
    const PhotonTracer tracer(scene, accel.handle(), space.views, space.csg_views, ol_groups.views, emitters,
                              settings, extent, two_pass ? 1u : 0u, ls_ols.grids, textures.get(), &lobes);
    // ---- Sharded bakes (transport/farm/shard.h): trace one shard's batches and stop here.
    if (tracing_shard) {
      trace_shard(arena, tracer, threads, cap, acc, *job,
                  [&](double f) { report(kProgressSetup + (kProgressPhotons - kProgressSetup) * f, "tracing photons"); });
      out.stats.seconds_trace = seconds_since(t_trace);
      out.stats.seconds_total = seconds_since(t_start);
      report(kProgressPhotons, "writing the part file");  // the caller writes it, then reports the end
      return out;
    }
    bool gathered = false;
    uint32_t gathers = 0;
    // Runs from `now`, the estimate at a fixed batch count (so it is
    // deterministic), replacing the gather before; each texel then weighs
    // photons and gather by variance, so scenes where photons do better lose
    // only the gather's rays.
    OpenShares open_shares;  // the gathers' (transport/gather/final_gather.h), kept from one to the next
    auto run_gather = [&](const Estimate& now) {
      gathered = true;
      ++gathers;
      if (budget.spent(kGatherBudgetShare)) return;
      if (job && !job->gather.empty()) {  // the texel ranges' (transport/farm/texel_ranges.h)
        gather = join_gather(job->gather, space.covered.size());
        return;
      }
      const FinalGather final_gather(accel.handle(), surfaces, space.views, space.areas, settings, extent,
                                     passage.get(), lobes.any_lobes(), &lobes);
      gather = run_final_gather(arena, final_gather, space, now.values, now.lookup_local, now.lookup_wide,
                                tracer.triangle_albedos(), acc.back_lit.data(), open_shares,
                                gather_samples(settings.target_error, gathers - 1), [&] {
                                  report(direct_end, "final gather");
                                  return !budget.spent(kGatherBudgetShare);
                                },
                                job_slice(job, ShardJob::kGather, space.covered.size()));
    };
    double truncated_flux = 0.0;
    uint64_t ol_hits = 0, merged = 0;
    CheckSchedule checks(first_check(settings.target_error));
    bool done = false;
    auto last_report = t_trace - std::chrono::seconds(1);
    if (job && (job->mode == ShardJob::kMerge || job->mode == ShardJob::kGather)) {  // every shard's sums, in order
      check_segments(*job);
      for (const PhotonSegment& seg : job->segments) {
        acc.add(seg.acc);
        out.stats.rays_traced += seg.rays;
        out.stats.paths_truncated += seg.truncated;
        truncated_flux += seg.truncated_flux;
        photons = std::min(cap, seg.end * kBatchPhotons);
        if (gather_wanted && !gathered && !targeted && seg.end == kCheckBatches) {
          estimate(arena, estimator, photons, last);
          run_gather(last);
        }
      }
      if (const std::string w = inexact_sums(acc); !w.empty()) out.warnings.push_back(w);
    } else {
      PhotonBatches batches(tracer, acc, threads, cap);
      run_in_groups(
          arena, batch_count, threads, [&](uint64_t first, uint64_t n) { batches.trace(first, n); },
          [&](uint64_t end) {
            // The texel sums hold every batch before `end` (exact, in any
            // order); OL hits and counts are merged here in batch order.
            for (uint64_t b = merged; b < end; ++b) {
              const BatchOutput& bo = batches.kept(b - merged);
              ol_hits += merge_ol_hits(b, bo, ol_groups, ls_ols, out.lsystems);
              out.stats.rays_traced += bo.rays;
              out.stats.paths_truncated += bo.truncated;
              truncated_flux += acc.quantum.flux(bo.truncated_flux);
            }
            merged = end;
            photons = std::min(cap, end * kBatchPhotons);
            // Without a target the gather runs after kCheckBatches batches;
            // with one, the error is checked at fixed batch counts and the
            // gather runs at the first check the photons alone do not pass
            // (loose targets cost what photons alone do).
            double fraction = double(end) / double(batch_count);
            if (gather_wanted && !gathered && !targeted && end == kCheckBatches) {
              estimate(arena, estimator, photons, last);
              run_gather(last);
            }
            if (targeted && checks.due(end)) {
              estimate(arena, estimator, photons, last);
              done = target_reached(last.error, settings.target_error);
              if (!done && gather_wanted && !gathered) {
                // Again while the gather's own part is large: each gather looks up the estimate the one
                // before it improved (transport/plan/scheduler.h, regather).
                do {
                  run_gather(last);
                  estimate(arena, estimator, photons, last);
                } while (regather(gathers, last.error, settings.target_error));
                done = target_reached(last.error, settings.target_error);
              }
              fraction = std::max(fraction, target_progress(last.error.relative, settings.target_error));
            }
            if (!done) live.check(arena, scene, estimator, photons, settings.dilation);
            if (budget.seconds() > 0.0) fraction = std::max(fraction, budget.elapsed() / budget.seconds());
            done = done || budget.spent(kPhotonBudgetShare);
            if (seconds_since(last_report) >= kPhotonReportInterval) {
              last_report = Clock::now();
              report(direct_end + (kProgressPhotons - direct_end) * std::min(fraction, 1.0),
                     steered ? "tracing photons to the target" : "tracing photons");
            }
            return !done;
          },
          0,
          // Groups end at the gather's batch count and at every check.
          [&](uint64_t first) {
            uint64_t stop = first < kCheckBatches ? kCheckBatches : batch_count;
            return targeted ? std::min(stop, checks.next()) : stop;
          });
    }
    // Fewer photons than kCheckBatches batches, no target: the gather comes last.
    if (gather_wanted && !gathered && photons > 0 && !targeted) {
      estimate(arena, estimator, photons, last);
      run_gather(last);
    }
    if (job && job->mode == ShardJob::kGather) {  // a texel range's gather: its sums are the part
      job->gathered = gathered;
      job->gather.assign(1, std::move(gather));
      out.stats.seconds_total = seconds_since(t_start);
      return out;
    }
    out.stats.photons_emitted = photons;
    out.stats.photon_hits = acc.total_hits + acc.caustic.total_hits + ol_hits;
    if (truncated_flux > 1e-4 * emitted * double(photons))
      out.warnings.push_back(std::to_string(out.stats.paths_truncated) + " photon paths reached max_bounces (" +
                             std::to_string(settings.max_bounces) + ") and were stopped, losing " +
                             std::to_string(100.0 * truncated_flux / (emitted * double(photons))) +
                             "% of the emitted power; raise max_bounces for albedos near 1");
  }
  out.stats.seconds_trace = seconds_since(t_trace);

  // ---- Final estimate --------------------------------------------------------------
  if (!last.current(photons, gather)) estimate(arena, estimator, photons, last);
  const ErrorEstimate& err = last.error;
  out.stats.error_estimate = err.relative;
  out.stats.error_direct = err.direct;
  out.stats.error_median = err.median;
  out.stats.error_p95 = err.p95;
  out.stats.error_above = share_above(err, 2.0 * (settings.target_error > 0.0 ? settings.target_error : err.relative));
  if (settings.target_error > 0.0 && err.relative > settings.target_error)
    out.warnings.push_back("the target error " + std::to_string(100.0 * settings.target_error) +
                           "% was not reached (estimated " + std::to_string(100.0 * err.relative) + "% after " +
                           std::to_string(photons) + " photons" +
                           (budget.spent(kPhotonBudgetShare) ? ", time budget spent" : "") +
                           "); lower the lightmap resolution or allow more time");

  // ---- Outputs -----------------------------------------------------------------------
  finish_ol_groups(scene, photons, ol_groups, out.ols);
  finish_lsystems(photons, out.lsystems);
  report(kProgressPhotons, "writing lightmaps");
  write_lightmaps(arena, scene, estimator, photons, ol_groups.maps, last, settings.dilation, out.lightmaps,
                  out.warnings);

  out.stats.seconds_total = seconds_since(t_start);
  report(1.0, "done");
  return out;
}

}  // namespace plm

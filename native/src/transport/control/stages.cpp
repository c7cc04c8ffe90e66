#include "transport/control/stages.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <thread>

#include "transport/direct/direct.h"
#include "transport/film/photon_batches.h"
#include "transport/lights/footprint.h"
#include "transport/output/film_output.h"
#include "transport/output/layers.h"
#include "transport/photons/photon_sampler.h"
#include "transport/plan/validate.h"
#include "util/error.h"

namespace plm {
namespace {

// Progress is reported at most this often (seconds) while photons are traced.
constexpr double kPhotonReportInterval = 0.1;

// Where the direct pass's share of the progress ends.
double direct_end(const BakeSettings& s) { return s.photon_pass ? kProgressDirect : kProgressPhotons; }

// The scene's lights in one flat array, with the checks on their power.
void set_up_emitters(BakeScene& ctx, Vec3 lo, Vec3 hi, BakeRun& run) {
  const Scene& scene = ctx.scene;
  // Image textures: a TextureSet only when a material names one.
  if (scene.has_textures()) {
    run.report(0.04, "loading textures");
    ctx.textures = std::make_unique<TextureSet>(scene);
    for (const std::string& w : ctx.textures->warnings) run.out.warnings.push_back(w);
  }
  ctx.emitters = build_emitters(scene, photon_footprint(scene, lo, hi), ctx.textures.get());
  double emitted = 0.0;
  for (const Emitter& e : ctx.emitters) emitted += average(e.flux);
  if (!std::isfinite(emitted) || emitted > 1e30)
    fail(PLM_ERROR_INVALID_SCENE, "the lights emit ", emitted, " W together, beyond the engine's range "
         "(1e30 W): check light powers, colours and emission strengths");
  if (ctx.emitters.empty())
    fail(PLM_ERROR_INVALID_SCENE, "nothing lights the scene: it has no light with power, no emissive material and "
         "no world light, so every lightmap would be black");
  ctx.emitted = emitted;
  ctx.layers = assign_layers(scene, ctx.emitters);
  ctx.split = {uint32_t(ctx.layers.size()), ctx.settings.directional};
  run.out.stats.emitted_power = emitted;
}

// Faces in contact, specular lobes, Burley surfaces, passages.
void set_up_surfaces(BakeScene& ctx, BakeRun& run) {
  const Scene& scene = ctx.scene;
  TexelSpace& space = ctx.space;
  // Faces pressed against other surfaces (transport/rays/tracing.h: in_contact).
  run.report(kProgressSetup, "finding faces in contact");
  ctx.surfaces = surface_map(scene, space.views);
  ctx.arena.execute(
      [&] { ctx.contact = contact_candidates(ctx.rtc, scene, space.views, ctx.surfaces, 1e-6f * ctx.extent); });
  for (size_t i = 0; i < space.views.size(); ++i)
    if (!ctx.contact[i].empty()) space.views[i].contact = ctx.contact[i].data();
  // Specular lobes (docs/design/materials.md): flattened, and the passage
  // of straight rays through panes and transparent surfaces; nothing in
  // scenes without lobes.
  if (scene.has_lobes() || scene.has_burley()) ctx.lobes = MaterialTable(scene);
  ctx.caustics = ctx.lobes.any_lobes();
  // Burley surfaces (Cycles 3.4's Principled diffuse): each triangle's roughness, for what their texels record.
  ctx.burley.resize(scene.has_burley() ? space.views.size() : 0);
  for (size_t i = 0; i < ctx.burley.size(); ++i) {
    const Mesh& mesh = *space.views[i].mesh;
    bool any = false;
    ctx.burley[i].resize(mesh.triangle_count(), -1.0f);
    for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
      const uint32_t id = mesh.material_ids[t];
      if (id < scene.materials.size() && scene.materials[id].diffuse_model == PLM_DIFFUSE_BURLEY) {
        ctx.burley[i][t] = scene.materials[id].diffuse_roughness;
        any = true;
      }
    }
    if (any) space.views[i].burley = ctx.burley[i].data();
  }
  if (ctx.lobes.any_passage())
    ctx.passage = std::make_unique<PassageTracer>(scene, ctx.lobes, space.views, ctx.surfaces, ctx.extent);
}

const PhotonTracer& tracer(const BakeScene& ctx, BakeRun& run) {
  if (!run.tracer) run.tracer = std::make_unique<PhotonTracer>(ctx);
  return *run.tracer;
}

// Fewer photons than kCheckBatches batches, no target: the gather comes last.
// Then the photon figures and the warning for paths max_bounces cut.
void finish_photons(const BakeScene& ctx, BakeRun& run, const GatherStep& gather) {
  const BakeSettings& s = ctx.settings;
  if (s.gather && !run.gathered && run.photons > 0 && !s.targeted()) {
    estimate(ctx.arena, estimator(ctx, run), run.photons, run.last);
    gather(ctx, run);
  }
  plm_bake_stats& stats = run.out.stats;
  stats.photons_emitted = run.photons;
  stats.photon_hits = run.acc.total_hits + run.acc.caustic.total_hits + run.ol_hits;
  if (run.truncated_flux > 1e-4 * ctx.emitted * double(run.photons))
    run.out.warnings.push_back(std::to_string(stats.paths_truncated) + " photon paths reached max_bounces (" +
                               std::to_string(s.max_bounces) + ") and were stopped, losing " +
                               std::to_string(100.0 * run.truncated_flux / (ctx.emitted * double(run.photons))) +
                               "% of the emitted power; raise max_bounces for albedos near 1");
  stats.seconds_trace = seconds_since(run.t_trace);
}

// The one-machine photon pass between two groups of batches.
struct PhotonLoop {
  uint64_t batch_count = 0, merged = 0;
  CheckSchedule checks;
  bool done = false;
  Clock::time_point last_report;
};

// At a check: the judged groups whose direct part is above the direct pass's
// share of the target relative to their whole light (direct and indirect)
// get more direct samples (refine_direct), once that mean is known well
// enough to aim at: the rest of the group's error spread over its
// independent photon pools (kPoolTexels texels each) at most kKnownMean.
// Where the rest is far above the target (a dim object that the photon cap
// will leave at 14 %), the direct part aims at the share of kRestShare x the
// rest instead: it adds little to the whole there, and a 1 % target's
// direct part on the artist's room's dim objects cost 40x their samples for
// nothing the artist could see. Returns whether samples were added.
constexpr double kPoolTexels = 25.0, kKnownMean = 0.2, kRestShare = 0.25;
bool refine_direct_at_check(const BakeScene& ctx, BakeRun& run) {
  const BakeSettings& s = ctx.settings;
  if (!s.two_pass) return false;
  const std::vector<ErrorParts>& groups = run.last.error.groups;
  const std::vector<size_t> texels = ctx.space.group_texels();
  std::vector<double> mean(groups.size(), 0.0);
  bool any = false;
  for (size_t g = 0; g < groups.size() && g < texels.size(); ++g) {
    const ErrorParts& e = groups[g];
    const double rest = e.rest();
    const double aim = std::max(s.target_error, kRestShare * rest);
    if (!(e.direct > DirectSchedule::kDirectShareOfTarget * aim && e.mean > 0.0)) continue;
    if (rest / std::sqrt(std::max(1.0, double(texels[g]) / kPoolTexels)) > kKnownMean) continue;
    mean[g] = e.mean * aim / s.target_error;  // the schedule's allowance: its share of the aim
    any = true;
  }
  if (!any) return false;
  const DirectPass pass(ctx);
  const uint64_t added = refine_direct(ctx.arena, pass, ctx.space, s, mean, run.direct,
                                       [&] { return run.budget.spent(kPhotonBudgetShare); });
  run.out.stats.direct_samples = run.direct.samples;
  return added > 0;
}

// After the batches before `end` are in the sums: OL hits and counts merged
// in batch order, the gather and the checks where due, a preview, progress.
// Returns false once the target is met or the budget spent.
bool after_photon_group(const BakeScene& ctx, BakeRun& run, PhotonBatches& batches, uint64_t end,
                        const GatherStep& gather, PhotonLoop& loop) {
  const BakeSettings& s = ctx.settings;
  // The texel sums hold every batch before `end` (exact, in any order); OL
  // hits and counts are merged here in batch order.
  for (uint64_t b = loop.merged; b < end; ++b) {
    const BatchOutput& bo = batches.kept(b - loop.merged);
    run.ol_hits += merge_ol_hits(b, bo, run.ol_groups, ctx.ls_ols, run.out.lsystems);
    run.out.stats.rays_traced += bo.rays;
    run.out.stats.paths_truncated += bo.truncated;
    run.truncated_flux += run.acc.quantum.flux(bo.truncated_flux);
  }
  loop.merged = end;
  run.photons = std::min(s.photon_cap, end * kBatchPhotons);
  const Estimator est = estimator(ctx, run);
  // Without a target the gather runs after kCheckBatches batches; with one,
  // the error is checked at fixed batch counts and the gather runs at the
  // first check the photons alone do not pass (loose targets cost what
  // photons alone do).
  double fraction = double(end) / double(loop.batch_count);
  if (s.gather && !run.gathered && !s.targeted() && end == kCheckBatches) {
    estimate(ctx.arena, est, run.photons, run.last);
    gather(ctx, run);
  }
  if (s.targeted() && loop.checks.due(end)) {
    estimate(ctx.arena, est, run.photons, run.last);
    if (refine_direct_at_check(ctx, run)) {
      run.last.photon_part = PhotonPart();  // its guide, the direct light, changed
      estimate(ctx.arena, est, run.photons, run.last);
    }
    loop.done = target_reached(run.last.error.groups, s.target_error);
    // Once the photons have grown kRegatherPhotonGrowth-fold since the last
    // gather, the groups whose gather part is still large gather again: what
    // their rays look up is better now. Not while the gathers have traced
    // more rays than the photons: then photons are what the bake lacks.
    const bool fresh = run.gathered && run.photons >= kRegatherPhotonGrowth * run.gather_photons &&
                       run.gather_rays <= run.out.stats.rays_traced && !run.budget.spent(kRegatherBudgetShare);
    const std::vector<size_t> texels = ctx.space.group_texels();
    if (fresh && !loop.done)
      run.next_gather = plan_regather(0, run.gather_samples, run.last.error.groups, texels, s.target_error, true);
    if (!loop.done && s.gather && (!run.gathered || (fresh && run.next_gather.samples > 0))) {
      // Again while the gather's own part is large: each gather looks up the estimate the one
      // before it improved (transport/plan/scheduler.h, plan_regather).
      for (uint32_t gathers = 1;; ++gathers) {
        const std::vector<ErrorParts> before = run.last.error.groups;
        gather(ctx, run);
        estimate(ctx.arena, est, run.photons, run.last);
        run.next_gather =
            plan_regather(gathers, run.gather_samples, run.last.error.groups, texels, s.target_error, false, &before);
        if (run.next_gather.samples == 0 || run.budget.spent(kRegatherBudgetShare)) break;
      }
      loop.done = target_reached(run.last.error.groups, s.target_error);
    }
    fraction = std::max(fraction, target_progress(worst_relative(run.last.error), s.target_error));
  }
  if (!loop.done) run.live.check(ctx.arena, ctx.scene, est, run.photons, s.dilation);
  if (run.budget.seconds() > 0.0) fraction = std::max(fraction, run.budget.elapsed() / run.budget.seconds());
  loop.done = loop.done || run.budget.spent(kPhotonBudgetShare);
  if (seconds_since(loop.last_report) >= kPhotonReportInterval) {
    loop.last_report = Clock::now();
    const double start = direct_end(s);
    run.report(start + (kProgressPhotons - start) * std::min(fraction, 1.0),
               s.steered() ? "tracing photons to the target" : "tracing photons");
  }
  return !loop.done;
}

}  // namespace

BakeRun::BakeRun(const ProgressFn& progress, const PreviewHook* preview)
    : t_start(Clock::now()), report(progress), budget(0.0, t_start), live(preview, t_start) {}

BakeSettings check_bake(Scene& scene, const BakeSettings& requested, BakeRun& run) {
  scene.refine_cages(requested.thread_count);
  validate(scene, requested);
  run.out.stats.memory_estimate = check_memory(scene, requested, run.out.warnings);  // before allocating anything
  const BakeSettings settings = effective_settings(scene, requested, run.out.warnings);
  run.budget = TimeBudget(settings.time_budget, run.t_start);
  return settings;
}

std::unique_ptr<BakeScene> set_up(const Scene& scene, const BakeSettings& settings, BakeRun& run) {
  run.report(0.0, "building the ray-tracing scene");
  const unsigned threads =
      settings.thread_count ? settings.thread_count : std::max(1u, std::thread::hardware_concurrency());
  auto ctx = std::make_unique<BakeScene>(scene, settings, threads);
  ctx->accel = std::make_unique<EmbreeScene>(scene, threads);
  ctx->rtc = ctx->accel->handle();
  const Vec3 lo = ctx->accel->bounds_min(), hi = ctx->accel->bounds_max();
  if (!is_finite(lo) || !is_finite(hi) || lo.x > hi.x)
    fail(PLM_ERROR_INVALID_SCENE, "the scene has no triangle with a non-zero area");
  ctx->extent = length(hi - lo);

  run.report(0.02, "computing texel areas");
  ctx->arena.execute([&] { ctx->space = build_texel_space(scene, run.out.warnings); });
  run.ol_groups = build_ol_groups(scene, run.out.warnings);
  ctx->ol_views = run.ol_groups.views;
  if (!scene.lsystems.empty()) run.report(0.03, "estimating L-system OL areas");
  ctx->ls_ols = build_lsystem_ols(scene, ctx->arena, run.out.lsystems, run.out.warnings);
  set_up_emitters(*ctx, lo, hi, run);
  set_up_surfaces(*ctx, run);
  run.out.stats.seconds_setup = seconds_since(run.t_start);
  run.acc = Accumulators(ctx->space.texel_count, scene.meshes.size(), ctx->caustics, flux_quantum(ctx->emitted),
                         ctx->split);
  return ctx;
}

Estimator estimator(const BakeScene& ctx, const BakeRun& run) {
  return {ctx.space,           run.direct.values, run.acc, ctx.settings.filter_radius, &run.gather,
          ctx.settings.gather, &run.direct,      &run.open_shares.share, ctx.settings.cycles_window};
}

void direct_pass(const BakeScene& ctx, BakeRun& run, CoveredSlice slice) {
  const BakeSettings& s = ctx.settings;
  const auto t_direct = Clock::now();
  const DirectPass pass(ctx);
  const double share = s.photon_pass ? kDirectBudgetShare : kDirectOnlyBudgetShare;
  const double end = direct_end(s);
  DirectControl control{
      [&](double f) { run.report(kProgressSetup + (end - kProgressSetup) * f, "direct light"); },
      [&] { return run.budget.spent(share); },
      nullptr};
  if (run.live.active())  // previews between rounds; the first shows the first round at once
    control.round_done = [&](uint32_t round, const DirectResult& sofar) {
      const Estimator est{ctx.space, sofar.values, run.acc, s.filter_radius, nullptr};
      run.live.check(ctx.arena, ctx.scene, est, 0, s.dilation, round == 0);
    };
  run.direct = run_direct_pass(ctx.arena, pass, ctx.space, s, control, slice);
  run.out.stats.direct_samples = run.direct.samples;
  run.out.stats.seconds_direct = seconds_since(t_direct);
  run.live.check(ctx.arena, ctx.scene, estimator(ctx, run), 0, s.dilation);  // the direct light alone
}

void trace_photons(const BakeScene& ctx, BakeRun& run, const GatherStep& gather) {
  const BakeSettings& s = ctx.settings;
  run.t_trace = Clock::now();
  PhotonLoop loop{(s.photon_cap + kBatchPhotons - 1) / kBatchPhotons, 0, CheckSchedule(first_check(s.target_error)),
                  false, run.t_trace - std::chrono::seconds(1)};
  PhotonBatches batches(tracer(ctx, run), run.acc, ctx.threads, s.photon_cap);
  run_in_groups(
      ctx.arena, loop.batch_count, ctx.threads, [&](uint64_t first, uint64_t n) { batches.trace(first, n); },
      [&](uint64_t end) { return after_photon_group(ctx, run, batches, end, gather, loop); }, 0,
      // Groups end at the gather's batch count and at every check.
      [&](uint64_t first) {
        const uint64_t stop = first < kCheckBatches ? kCheckBatches : loop.batch_count;
        return s.targeted() ? std::min(stop, loop.checks.next()) : stop;
      });
  finish_photons(ctx, run, gather);
}

std::vector<PhotonSegment> trace_batches(const BakeScene& ctx, BakeRun& run, uint64_t first, uint64_t last) {
  run.t_trace = Clock::now();
  std::vector<PhotonSegment> segments =
      trace_segments(ctx.arena, tracer(ctx, run), ctx.threads, ctx.settings.photon_cap, run.acc, first, last,
                     [&](double f) {
                       run.report(kProgressSetup + (kProgressPhotons - kProgressSetup) * f, "tracing photons");
                     });
  run.out.stats.seconds_trace = seconds_since(run.t_trace);
  return segments;
}

void add_photon_segments(const BakeScene& ctx, BakeRun& run, const std::vector<PhotonSegment>& segments,
                         const GatherStep& gather) {
  const BakeSettings& s = ctx.settings;
  run.t_trace = Clock::now();
  tracer(ctx, run);  // the gather reads its albedos
  for (const PhotonSegment& seg : segments) {  // every shard's sums, in order
    run.acc.add(seg.acc);
    run.out.stats.rays_traced += seg.rays;
    run.out.stats.paths_truncated += seg.truncated;
    run.truncated_flux += seg.truncated_flux;
    run.photons = std::min(s.photon_cap, seg.end * kBatchPhotons);
    if (s.gather && !run.gathered && !s.targeted() && seg.end == kCheckBatches) {
      estimate(ctx.arena, estimator(ctx, run), run.photons, run.last);
      gather(ctx, run);
    }
  }
  if (const std::string w = inexact_sums(run.acc); !w.empty()) run.out.warnings.push_back(w);
  finish_photons(ctx, run, gather);
}

bool start_gather(BakeRun& run) {
  run.gathered = true;
  ++run.gathers;
  return !run.budget.spent(kGatherBudgetShare);
}

void find_open_shares(const BakeScene& ctx, BakeRun& run) {
  update_open_shares(ctx.arena, FinalGather(ctx), ctx.space, run.acc.back_lit.data(), run.open_shares);
}

// Runs from run.last, the estimate at a fixed batch count (so it is
// deterministic), replacing the gather before; each texel then weighs photons
// and gather by variance, so scenes where photons do better lose only the
// gather's rays.
void final_gather(const BakeScene& ctx, BakeRun& run, CoveredSlice slice) {
  if (!start_gather(run)) return;
  const FinalGather pass(ctx);
  const Estimate& now = run.last;
  // With light groups, each ray's light splits by the layers' shares of the texel it sees.
  std::vector<std::vector<float>> shares;
  if (!ctx.layers.empty()) shares = layer_shares(ctx.arena, estimator(ctx, run), run.photons, now.values);
  const GatherLookup lookup{now.values,
                            now.lookup_local,
                            now.lookup_wide,
                            run.tracer->triangle_albedos(),
                            run.acc.back_lit.data(),
                            shares.empty() ? nullptr : &shares};
  const double end = direct_end(ctx.settings);
  // A gather after the first: the groups it refines, the rest keep their rays.
  const RegatherPlan& plan = run.next_gather;
  const bool refine = plan.samples > 0 && !run.gather.sums.empty();
  const Regather again{refine ? &plan.groups : nullptr, &run.gather};
  run.gather_samples = plan.samples ? plan.samples : gather_samples(ctx.settings.target_error);
  run.gather_photons = run.photons;
  run.gather_rays += (refine ? plan.texels : ctx.space.covered.size()) * run.gather_samples;
  run.gather = run_final_gather(ctx, pass, lookup, run.open_shares, run.gather_samples,
                                [&] {
                                  run.report(end, "final gather");
                                  return !run.budget.spent(kGatherBudgetShare);
                                },
                                slice, again);
}

namespace {

// A fraction as a percentage for messages ("3%", "37.77%").
std::string percent(double fraction, const char* format = "%.2f%%") {
  char text[32];
  std::snprintf(text, sizeof text, format, 100.0 * fraction);
  return text;
}

// Judged group g in words, and the mesh that stands for it: its unit with the
// most covered texels (a CSG solid by its carrier).
std::string group_name(const BakeScene& ctx, uint32_t g, uint32_t& mesh) {
  const TexelSpace& space = ctx.space;
  const size_t meshes = ctx.scene.meshes.size();
  size_t best = 0, units = 0, most = 0;
  for (size_t u = 0; u < space.judged.size(); ++u) {
    if (space.judged[u] != g) continue;
    const size_t texels = space.covered_count(u);
    ++units;
    if (texels > most) most = texels, best = u;
  }
  mesh = best < meshes ? uint32_t(best) : uint32_t(ctx.scene.csgs[best - meshes].carrier);
  const std::string name = best < meshes ? "mesh '" + ctx.scene.meshes[best].name + "'"
                                         : "CSG solid '" + ctx.scene.csgs[best - meshes].object->name() + "'";
  if (units == 1) return name;
  return std::to_string(units) + " small objects judged together (" + name + " and its neighbours)";
}

}  // namespace

void estimate_result(const BakeScene& ctx, BakeRun& run) {
  const BakeSettings& s = ctx.settings;
  if (!run.last.current(run.photons, run.gather)) estimate(ctx.arena, estimator(ctx, run), run.photons, run.last);
  const ErrorEstimate& err = run.last.error;
  plm_bake_stats& stats = run.out.stats;
  stats.error_estimate = err.relative;
  stats.error_direct = err.direct;
  stats.error_median = err.median;
  stats.error_p95 = err.p95;
  stats.error_above = share_above(err, 2.0 * (s.targeted() ? s.target_error : err.relative));
  stats.error_worst = worst_relative(err);
  stats.error_worst_mesh = UINT32_MAX;
  std::string worst = "the lightmaps";
  if (err.worst != kNoGroup) worst = group_name(ctx, err.worst, stats.error_worst_mesh);
  if (s.targeted() && stats.error_worst > s.target_error)
    run.out.warnings.push_back("the target error " + percent(s.target_error, "%.3g%%") + " was not reached on " + worst +
                               " (estimated " + percent(stats.error_worst) + ", " + percent(err.relative) +
                               " over all texels, after " + std::to_string(run.photons) + " photons" +
                               (run.budget.spent(kPhotonBudgetShare) ? ", time budget spent" : "") +
                               "); lower its lightmap resolution or allow more time");
}

// The layers' names and their estimated errors, from the images.
void name_layers(const BakeScene& ctx, BakeOutput& out) {
  for (const uint32_t g : ctx.layers) {
    out.layer_names.push_back(g == 0 ? "default" : ctx.scene.light_groups[g - 1]);
    double value = 0.0, var = 0.0, count = 0.0;
    for (const LightmapImage& img : out.lightmaps) {
      const size_t l = out.layer_names.size() - 1;
      if (img.layer_rgb.size() <= l) continue;
      for (size_t t = 0; t < img.coverage.size(); ++t) {
        if (!(img.coverage[t] > 0.0f)) continue;
        const float* v = &img.layer_rgb[l][3 * t];
        value += (double(v[0]) + v[1] + v[2]) / 3.0;
        var += double(img.layer_error[l][t]) * img.layer_error[l][t];
        count += 1.0;
      }
    }
    out.layer_errors.push_back(value > 0.0 ? std::sqrt(var / count) / (value / count) : 0.0);
  }
}

void write_outputs(const BakeScene& ctx, BakeRun& run) {
  finish_ol_groups(ctx.scene, run.photons, run.ol_groups, run.out.ols);
  finish_lsystems(run.photons, run.out.lsystems);
  run.report(kProgressPhotons, "writing lightmaps");
  write_lightmaps(ctx.arena, ctx.scene, estimator(ctx, run), run.photons, run.ol_groups.maps, run.last,
                  ctx.settings.dilation, run.out.lightmaps, run.out.warnings);
  name_layers(ctx, run.out);
  run.out.directional = ctx.split.directional;
  run.out.stats.seconds_total = seconds_since(run.t_start);
  run.report(1.0, "done");
}

}  // namespace plm

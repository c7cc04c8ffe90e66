#include "transport/jobs/bake_jobs.h"

#include <utility>

#include "transport/control/stages.h"
#include "transport/direct/direct.h"
#include "transport/farm/partial_file.h"
#include "transport/farm/shard.h"
#include "transport/farm/texel_ranges.h"

namespace plm {
namespace {

// A part's header: engine, scene, settings without the thread count, layout,
// scene path.
PartHeader part_header(const BakeSettings& requested, const ShardJob& job, const PartTarget& target) {
  PartHeader h;
  h.engine_version = plm_version();
  h.scene_hash = job.layout.scene_hash;
  h.settings = requested;
  h.settings.thread_count = 0;
  h.shard_index = job.index;
  h.shard_count = job.count;
  h.layout = job.layout;
  h.scene_path = target.scene_path;
  return h;
}

// A texel range's part header.
PartHeader range_header(const BakeSettings& requested, const ShardJob& job, const PartTarget& target,
                        PartKind kind, double direct_target) {
  PartHeader h = part_header(requested, job, target);
  h.settings.target_error = 0.0;
  const CoveredSlice slice = texel_range(job.layout.covered, job.index, job.count);
  h.range_begin = slice.begin;
  h.range_end = slice.end;
  h.direct_target = direct_target;
  h.kind = kind;
  return h;
}

// The bake's settings from a part's header, with the caller's thread count.
BakeSettings settings_of(const PartHeader& h, uint32_t thread_count, const Scene& scene) {
  BakeSettings s;
  s.photon_count = h.settings.photon_count;
  s.max_bounces = h.settings.max_bounces;
  s.seed = h.settings.seed;
  s.direct_samples = h.settings.direct_samples;
  s.filter_radius = h.settings.filter_radius;
  s.dilation = h.settings.dilation;
  s.texel_value = h.settings.texel_value;
  s.sampler = h.settings.sampler;
  s.directional = h.settings.directional;
  s.thread_count = thread_count;
  s.decide(scene);
  return s;
}

// The checks and the set-up of a part of a split bake; job.layout becomes the
// bake's (the parts' segments are checked against it).
std::unique_ptr<BakeScene> set_up_part(Scene& scene, const BakeSettings& requested, ShardJob& job, BakeRun& run) {
  const BakeSettings settings = check_bake(scene, requested, run);
  check_shardable(scene, settings, job.mode);
  std::unique_ptr<BakeScene> ctx = set_up(scene, settings, run);
  job.layout = shard_layout(scene, settings, ctx->space, run.acc);
  return ctx;
}

// The direct light: the texel ranges' parts joined, or the pass itself.
void direct_or_parts(const BakeScene& ctx, BakeRun& run, std::vector<DirectResult>& parts) {
  if (parts.empty()) return direct_pass(ctx, run);
  const auto t_direct = Clock::now();
  ctx.arena.execute([&] { run.direct = join_direct(parts, ctx.settings.sampler, ctx.space); });
  run.direct.chooses_lights = DirectPass::chooses_lights(ctx.emitters.size());
  run.out.stats.direct_samples = run.direct.samples;
  run.out.stats.seconds_direct = seconds_since(t_direct);
  run.live.check(ctx.arena, ctx.scene, estimator(ctx, run), 0, ctx.settings.dilation);
}

}  // namespace

BakeOutput bake(Scene& scene, const BakeSettings& requested, const ProgressFn& progress,
                const PreviewHook* preview) {
  BakeRun run(progress, preview);
  const BakeSettings settings = check_bake(scene, requested, run);
  const std::unique_ptr<BakeScene> ctx = set_up(scene, settings, run);
  if (settings.two_pass) direct_pass(*ctx, run);
  if (settings.photon_pass) trace_photons(*ctx, run, [](const BakeScene& c, BakeRun& r) { final_gather(c, r); });
  estimate_result(*ctx, run);
  write_outputs(*ctx, run);
  return std::move(run.out);
}

void bake_shard(Scene& scene, const BakeSettings& settings, uint32_t shard, uint32_t count,
                const PartTarget& target, const ProgressFn& progress) {
  ShardJob job;
  job.mode = ShardJob::kTrace;
  job.index = shard;
  job.count = count;
  BakeRun run(progress);
  const std::unique_ptr<BakeScene> ctx = set_up_part(scene, settings, job, run);
  const auto [first, last] = shard_batches(job.layout.batch_count, shard, count);
  const std::vector<PhotonSegment> segments = trace_batches(*ctx, run, first, last);
  run.report(kProgressPhotons, "writing the part file");
  write_part_file(target.part_path, part_header(settings, job, target), segments);
  if (progress) progress(1.0, "done");  // the part is written
}

void bake_direct_range(Scene& scene, const BakeSettings& settings, uint32_t range, uint32_t count,
                       const PartTarget& target, const ProgressFn& progress) {
  ShardJob job;
  job.mode = ShardJob::kDirect;
  job.index = range;
  job.count = count;
  BakeRun run(progress);
  const std::unique_ptr<BakeScene> ctx = set_up_part(scene, settings, job, run);
  direct_pass(*ctx, run, texel_range(ctx->space.covered.size(), range, count));
  write_direct_part(target.part_path, range_header(settings, job, target, PartKind::kDirect, settings.target_error),
                    run.direct);
  if (progress) progress(1.0, "done");  // the part is written
}

void bake_gather_range(Scene& scene, uint32_t thread_count, uint32_t range, uint32_t count,
                       const std::vector<std::string>& parts, const PartTarget& target, const ProgressFn& progress) {
  ShardJob job;
  job.mode = ShardJob::kGather;
  job.index = range;
  job.count = count;
  const PartHeader first = load_parts(parts, plm_version(), scene_hash(scene), job);
  const BakeSettings settings = settings_of(first, thread_count, scene);
  BakeRun run(progress);
  const std::unique_ptr<BakeScene> ctx = set_up_part(scene, settings, job, run);
  direct_or_parts(*ctx, run, job.direct);
  const CoveredSlice slice = texel_range(ctx->space.covered.size(), range, count);
  check_segments(job);
  add_photon_segments(*ctx, run, job.segments, [slice](const BakeScene& c, BakeRun& r) { final_gather(c, r, slice); });
  PartHeader h = range_header(settings, job, target, PartKind::kGather, job.direct_target);
  h.gathered = run.gathered;
  write_gather_part(target.part_path, h, run.gather);
  if (progress) progress(1.0, "done");  // the part is written
}

BakeOutput bake_merge(Scene& scene, const std::vector<std::string>& parts, uint32_t thread_count,
                      const ProgressFn& progress) {
  ShardJob job;
  scene.refine_cages(thread_count);  // the hash is of the refined triangles, as the shards' were
  const PartHeader first = load_parts(parts, plm_version(), scene_hash(scene), job);
  const BakeSettings settings = settings_of(first, thread_count, scene);
  BakeRun run(progress);
  const std::unique_ptr<BakeScene> ctx = set_up_part(scene, settings, job, run);
  if (settings.two_pass) direct_or_parts(*ctx, run, job.direct);
  GatherStep gather = [](const BakeScene& c, BakeRun& r) { final_gather(c, r); };
  if (!job.gather.empty())  // the texel ranges' gathers, joined
    gather = [&job](const BakeScene& c, BakeRun& r) {
      if (!start_gather(r)) return;
      r.gather = join_gather(job.gather, c.space.covered.size());
      find_open_shares(c, r);
    };
  check_segments(job);
  add_photon_segments(*ctx, run, job.segments, gather);
  estimate_result(*ctx, run);
  write_outputs(*ctx, run);
  return std::move(run.out);
}

}  // namespace plm

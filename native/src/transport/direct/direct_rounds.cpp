#include "transport/direct/direct_rounds.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "transport/plan/scheduler.h"

namespace plm {
namespace {

// Sobol points make the direct pass's pair-difference variance conservative
// (a pair straddles the strata of the light choice). The true variance is
// measured on a quarter of the texels (at most 1024) spread over all lightmaps by one more,
// independent round (a Sobol key of its own): for two independent means a, b,
// E[(a - b)^2] = Var a + Var b (calibrate). The calibration texels are
// every step-th of the whole covered order; those in the slice (direct[0] is
// covered texel `first`) are measured here, and the extra samples join their sums.
std::vector<DirectCalibration> calibrate_direct(tbb::task_arena& arena, const DirectPass& pass,
                                                const std::vector<CoveredTexel>& covered, size_t first,
                                                DirectResult& result, uint32_t samples) {
  std::vector<DirectSums>& direct = result.sums;
  constexpr uint32_t kCalibrationRound = 0xFF;  // a key no refinement round uses
  const size_t step = std::max<size_t>(4, covered.size() / 1024);
  const size_t m = covered.size() / step;
  const size_t k0 = (first + step - 1) / step, k1 = std::min(m, (first + direct.size() + step - 1) / step);
  std::vector<DirectSums> extra(k1 > k0 ? k1 - k0 : 0);
  const size_t split_floats = 3 * size_t(result.slots);
  std::vector<float> extra_split(extra.size() * split_floats, 0.0f);
  arena.execute([&] {
    tbb::parallel_for(size_t(0), extra.size(), [&](size_t j) {
      const CoveredTexel& c = covered[(k0 + j) * step];
      pass.sample_texel(c.mesh, c.texel, kCalibrationRound, samples, extra[j],
                        split_floats ? &extra_split[j * split_floats] : nullptr);
    });
  });
  std::vector<DirectCalibration> out(extra.size());
  for (size_t j = 0; j < extra.size(); ++j) {
    DirectCalibration& r = out[j];
    r.texel = (k0 + j) * step;
    DirectSums& a = direct[r.texel - first];
    const DirectSums& b = extra[j];
    r.count_before = a.count;
    r.sum_sq_before = a.sum_sq;
    if (a.paired && b.paired) {
      const double d = a.mean() - b.mean();
      r.measured = d * d;
      r.estimated = a.pair_variance_of_mean() + b.pair_variance_of_mean();
      r.used = 1;
      if (a.sky_rays && b.sky_rays) {
        const double ds = a.sky_mean() - b.sky_mean(), dother = d - ds;
        r.sky_measured = ds * ds;
        r.sky_estimated = a.sky_pair_variance_of_mean() + b.sky_pair_variance_of_mean();
        r.other_measured = dother * dother;
        r.other_estimated = a.other_pair_variance_of_mean() + b.other_pair_variance_of_mean();
        r.used_split = 1;
      }
    }
    a.merge(b);
    for (size_t f = 0; f < split_floats; ++f) result.split_sums(r.texel - first)[f] += extra_split[j * split_floats + f];
  }
  return out;
}

// The mean texel value and the phantom sample (typical_sample) of all
// covered texels, estimated from every step-th (those the calibration picks)
// with `samples` samples of a round of their own: what a texel range's rounds
// aim at under a target. Its own texels' would let a range keep an error that
// is under the target for it but not for the whole: the target is relative
// to the whole's mean, and the merge gives every texel the whole's phantom
// sample. Every range draws the same estimate. Mean negative where the scene
// has too few texels.
struct WholeEstimate {
  double mean = -1.0, typical = 0.0;
  std::vector<double> group_mean;  // per judged group, -1 where none of its texels was sampled
};

WholeEstimate estimate_whole(tbb::task_arena& arena, const DirectPass& pass, const TexelSpace& space,
                             uint32_t samples) {
  constexpr uint32_t kMeanRound = 0xFE;  // a key neither refinement rounds nor the calibration use
  const std::vector<CoveredTexel>& covered = space.covered;
  const size_t step = std::max<size_t>(4, covered.size() / 1024);
  const size_t m = covered.size() / step;
  if (m == 0) return {};
  std::vector<DirectSums> sums(m);
  arena.execute([&] {
    tbb::parallel_for(size_t(0), m, [&](size_t k) {
      const CoveredTexel& c = covered[k * step];
      pass.sample_texel(c.mesh, c.texel, kMeanRound, samples, sums[k]);
    });
  });
  WholeEstimate out{0.0, typical_sample(sums), std::vector<double>(space.judged_groups, 0.0)};
  std::vector<double> count(space.judged_groups, 0.0);
  for (size_t k = 0; k < m; ++k) {
    out.mean += sums[k].mean();
    if (space.judged_groups == 0) continue;
    const uint32_t g = space.group_of(k * step);
    out.group_mean[g] += sums[k].mean(), count[g] += 1.0;
  }
  out.mean /= double(m);
  for (size_t g = 0; g < count.size(); ++g) out.group_mean[g] = count[g] > 0.0 ? out.group_mean[g] / count[g] : -1.0;
  return out;
}

// The judged groups of the slice's texels and their means: each group's own
// texels' mean (the whole's estimate where it has one: a texel range judges
// an object by all of it), floored at kDirectJudgedFloor x the whole's mean.
DirectGroups direct_groups(const TexelSpace& space, size_t first, const std::vector<DirectSums>& direct,
                           const WholeEstimate& aim) {
  std::vector<double> mean(std::max(space.judged_groups, 1u), 0.0), count(mean.size(), 0.0);
  std::vector<uint32_t> of(direct.size(), 0);
  double whole = 0.0;
  for (size_t i = 0; i < direct.size(); ++i) {
    if (space.judged_groups > 0) of[i] = space.group_of(first + i);
    mean[of[i]] += direct[i].mean(), count[of[i]] += 1.0;
    whole += direct[i].mean();
  }
  whole = aim.mean >= 0.0 ? aim.mean : whole / double(std::max<size_t>(direct.size(), 1));
  for (size_t g = 0; g < mean.size(); ++g) {
    const double own = g < aim.group_mean.size() && aim.group_mean[g] >= 0.0 ? aim.group_mean[g]
                       : count[g] > 0.0                                     ? mean[g] / count[g]
                                                                            : 0.0;
    mean[g] = std::max(own, DirectSchedule::kDirectJudgedFloor * whole);
  }
  return {std::move(mean), std::move(of)};
}

// Round `round` of the texels `todo` (indices into texels and out's sums),
// want[i] samples each; after each group of texels, more(share done) says
// whether to go on.
template <typename More>
void sample_round(tbb::task_arena& arena, const DirectPass& pass, const CoveredTexel* texels,
                  const std::vector<uint32_t>& todo, const std::vector<uint32_t>& want, uint32_t round,
                  DirectResult& out, More&& more) {
  run_in_groups(
      arena, todo.size(), 64,
      [&](uint64_t first_texel, uint64_t n) {
        tbb::parallel_for(tbb::blocked_range<uint64_t>(first_texel, first_texel + n, 16), [&](const auto& r) {
          for (uint64_t k = r.begin(); k < r.end(); ++k) {
            const CoveredTexel& c = texels[todo[k]];
            pass.sample_texel(c.mesh, c.texel, round, want[todo[k]], out.sums[todo[k]], out.split_sums(todo[k]));
          }
        });
      },
      [&](uint64_t done) { return more(double(done) / double(todo.size())); });
}

}  // namespace

void calibrate(const std::vector<DirectCalibration>& records, DirectNoise& noise) {
  double m = 0.0, e = 0.0, sky_m = 0.0, sky_e = 0.0, other_m = 0.0, other_e = 0.0;
  size_t used = 0, split = 0;
  for (const DirectCalibration& r : records) {
    if (!r.used) continue;
    m += r.measured, e += r.estimated, ++used;
    if (!r.used_split) continue;
    sky_m += r.sky_measured, sky_e += r.sky_estimated, other_m += r.other_measured, other_e += r.other_estimated;
    ++split;
  }
  noise.scale = calibration_ratio(m, e, used);
  noise.sky_scale = calibration_ratio(sky_m, sky_e, split);
  noise.other_scale = calibration_ratio(other_m, other_e, split);
}

DirectResult run_direct_pass(tbb::task_arena& arena, const DirectPass& pass, const TexelSpace& space,
                             const BakeSettings& settings, const DirectControl& control, CoveredSlice slice) {
  const std::vector<CoveredTexel>& covered = space.covered;
  DirectResult out;
  std::vector<DirectSums>& direct = out.sums;
  slice = slice.clamped(covered.size());
  const CoveredTexel* const texels = covered.data() + slice.begin;
  direct.resize(slice.size());
  out.slots = pass.split().slots();
  out.chooses_lights = pass.chooses_lights();
  out.split_rgb.assign(3 * size_t(out.slots) * direct.size(), 0.0f);
  const DirectSchedule schedule(settings.target_error, settings.direct_samples);
  const uint32_t rounds = DirectSchedule::kMaxRounds;
  std::vector<uint32_t> todo(direct.size());
  for (uint32_t i = 0; i < todo.size(); ++i) todo[i] = i;
  // A loose target's round 0 first runs as a probe (DirectSchedule::probe):
  // kept if it meets the target, dropped if not.
  bool probing = schedule.probe() > 0;
  uint64_t dropped = 0;
  std::vector<uint32_t> want(direct.size(), probing ? schedule.probe() : schedule.first());
  std::vector<DirectTexelNoise> noise(direct.size());
  const bool whole = slice.begin == 0 && slice.end == covered.size();
  const WholeEstimate aim =
      settings.targeted() && !whole ? estimate_whole(arena, pass, space, schedule.first()) : WholeEstimate();
  for (uint32_t round = 0; round < rounds && !todo.empty(); ++round) {
    sample_round(arena, pass, texels, todo, want, round, out, [&](double done) {
      control.progress((double(round) + done) / rounds);
      return !control.stop();
    });
    out.noise.typical = typical_sample(direct);
    if (round == 0 && settings.sobol) {
      out.calibration = calibrate_direct(arena, pass, covered, slice.begin, out,
                                         probing ? schedule.probe() : schedule.first());
      calibrate(out.calibration, out.noise);
    }
    out.rounds = round + 1;
    DirectNoise aim_noise = out.noise;
    if (aim.mean >= 0.0) aim_noise.typical = aim.typical;
    // The variances the estimate will use, the sky light pooled (direct_pool.h).
    arena.execute([&] { out.values = pool_direct(space, direct, slice.begin, aim_noise); });
    for (size_t i = 0; i < direct.size(); ++i) {
      const DirectSums& d = direct[i];
      noise[i] = {d.count, out.values.variance[i], out.values.phantom[i]};
    }
    const DirectGroups groups = direct_groups(space, slice.begin, direct, aim);
    if (probing) {
      probing = false;
      if (schedule.refines(groups, noise) && !control.stop()) {  // round 0 again, with first() samples
        for (DirectSums& d : direct) dropped += d.count, d = DirectSums();
        std::fill(out.split_rgb.begin(), out.split_rgb.end(), 0.0f);
        out.calibration.clear();
        std::fill(want.begin(), want.end(), schedule.first());
        --round;  // the loop's ++round runs round 0 again
        continue;
      }
    }
    todo = schedule.next_round(round, groups, noise, want);
    if (control.round_done) control.round_done(round, out);
    if (control.stop()) break;
  }
  out.samples = dropped;  // a dropped probe's samples were traced too
  for (const DirectSums& d : direct) out.samples += d.count;
  return out;
}

uint64_t refine_direct(tbb::task_arena& arena, const DirectPass& pass, const TexelSpace& space,
                       const BakeSettings& settings, const std::vector<double>& group_mean, DirectResult& out,
                       const std::function<bool()>& stop) {
  const size_t n = out.sums.size();
  if (n != space.covered.size() || n == 0) return 0;
  const DirectSchedule schedule(settings.target_error, settings.direct_samples);
  // Groups left alone are judged against an infinite mean: next_round gives them nothing.
  std::vector<double> mean(std::max<size_t>(group_mean.size(), 1), std::numeric_limits<double>::infinity());
  for (size_t g = 0; g < group_mean.size(); ++g)
    if (group_mean[g] > 0.0) mean[g] = group_mean[g];
  std::vector<uint32_t> of(n, 0);
  if (space.judged_groups > 0)
    for (size_t i = 0; i < n; ++i) of[i] = space.group_of(i);
  const DirectGroups groups{std::move(mean), std::move(of)};
  std::vector<DirectTexelNoise> noise(n);
  std::vector<uint32_t> want(n, 0);
  uint64_t added = 0;
  while (out.rounds > 0 && out.rounds < DirectSchedule::kMaxRefinedRounds && !stop()) {
    for (size_t i = 0; i < n; ++i) noise[i] = {out.sums[i].count, out.values.variance[i], out.values.phantom[i]};
    std::vector<uint32_t> todo = schedule.next_round(out.rounds - 1, groups, noise, want);
    // Only the groups asked for (next_round also tops up texels without two samples anywhere).
    todo.erase(std::remove_if(todo.begin(), todo.end(),
                              [&](uint32_t i) { return std::isinf(groups.mean[groups.of(i)]); }),
               todo.end());
    if (todo.empty()) break;
    for (uint32_t i : todo) added += want[i];
    sample_round(arena, pass, space.covered.data(), todo, want, out.rounds, out, [&](double) { return !stop(); });
    ++out.rounds;
    out.noise.typical = typical_sample(out.sums);
    arena.execute([&] { out.values = pool_direct(space, out.sums, 0, out.noise); });
  }
  out.samples += added;
  return added;
}

}  // namespace plm

#include "transport/direct_rounds.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>

#include "transport/scheduler.h"

namespace plm {
namespace {

// Sobol points make the direct pass's pair-difference variance conservative
// (a pair straddles the strata of the light choice). The true variance is
// measured on a quarter of the texels (at most 1024) spread over all lightmaps by one more,
// independent round (a Sobol key of its own): for two independent means a, b,
// E[(a - b)^2] = Var a + Var b. Returns true / pair-difference variance; the
// extra samples join those texels' sums.
double calibrate_direct(tbb::task_arena& arena, const DirectPass& pass, const std::vector<CoveredTexel>& covered,
                        std::vector<DirectSums>& direct, uint32_t samples) {
  constexpr uint32_t kCalibrationRound = 0xFF;  // a key no refinement round uses
  const size_t step = std::max<size_t>(4, covered.size() / 1024);
  const size_t m = covered.size() / step;
  std::vector<DirectSums> extra(m);
  arena.execute([&] {
    tbb::parallel_for(size_t(0), m, [&](size_t k) {
      const CoveredTexel& c = covered[k * step];
      pass.sample_texel(c.mesh, c.texel, kCalibrationRound, samples, extra[k]);
    });
  });
  double measured = 0.0, estimated = 0.0;
  size_t used = 0;
  for (size_t k = 0; k < m; ++k) {
    DirectSums& a = direct[k * step];
    const DirectSums& b = extra[k];
    if (a.paired && b.paired) {
      const double d = a.mean() - b.mean();
      measured += d * d;
      estimated += a.pair_variance_of_mean() + b.pair_variance_of_mean();
      ++used;
    }
    a.merge(b);
  }
  if (used < 32 || !(estimated > 0.0)) return 1.0;
  return std::clamp(measured / estimated, 1e-4, 4.0);
}

}  // namespace

DirectResult run_direct_pass(tbb::task_arena& arena, const DirectPass& pass, const std::vector<CoveredTexel>& covered,
                             const plm_bake_settings& settings, const DirectControl& control) {
  DirectResult out;
  std::vector<DirectSums>& direct = out.sums;
  direct.resize(covered.size());
  const DirectSchedule schedule(settings.target_error, settings.direct_samples);
  const uint32_t rounds = DirectSchedule::kMaxRounds;
  std::vector<uint32_t> todo(covered.size());
  for (uint32_t i = 0; i < todo.size(); ++i) todo[i] = i;
  std::vector<uint32_t> want(covered.size(), schedule.first());
  std::vector<DirectTexelNoise> noise(covered.size());
  for (uint32_t round = 0; round < rounds && !todo.empty(); ++round) {
    run_in_groups(
        arena, todo.size(), 64,
        [&](uint64_t first_texel, uint64_t n) {
          tbb::parallel_for(tbb::blocked_range<uint64_t>(first_texel, first_texel + n, 16), [&](const auto& r) {
            for (uint64_t k = r.begin(); k < r.end(); ++k) {
              const CoveredTexel& c = covered[todo[k]];
              pass.sample_texel(c.mesh, c.texel, round, want[todo[k]], direct[todo[k]]);
            }
          });
        },
        [&](uint64_t done) {
          control.progress((double(round) + double(done) / double(todo.size())) / rounds);
          return !control.stop();
        });
    double mean = 0.0;
    for (const DirectSums& d : direct) mean += d.mean();
    mean /= double(std::max<size_t>(direct.size(), 1));
    out.noise.typical = typical_sample(direct);
    if (round == 0 && settings.sampler != PLM_SAMPLER_RANDOM)
      out.noise.scale = calibrate_direct(arena, pass, covered, direct, schedule.first());
    for (size_t i = 0; i < direct.size(); ++i) {
      const DirectSums& d = direct[i];
      noise[i] = {d.count, d.variance_of_mean(out.noise), d.phantom_variance_of_mean(out.noise)};
    }
    todo = schedule.next_round(round, mean, noise, want);
    if (control.round_done) control.round_done(round, out);
    if (control.stop()) break;
  }
  for (const DirectSums& d : direct) out.samples += d.count;
  return out;
}

}  // namespace plm

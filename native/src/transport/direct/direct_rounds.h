// The direct pass over every covered texel, in rounds: DirectSchedule
// (transport/plan/scheduler.h) says how many samples each texel gets next, the texels'
// noise after each round says what it reads. After round 0 the variance
// estimate of Sobol points is calibrated against independent replicates.
#pragma once

#include <tbb/task_arena.h>

#include <cstdint>
#include <functional>
#include <vector>

#include "photonlm/photonlm.h"
#include "transport/direct/direct.h"
#include "transport/direct/direct_pool.h"
#include "transport/film/film.h"

namespace plm {

// Round 0's calibration at one of its texels (calibrate_direct): the squared
// difference of the two independent means and the sum of their
// pair-difference variances (used: both had pairs), and the texel's count and
// squared sum before the extra samples joined it.
struct DirectCalibration {
  uint64_t texel = 0;  // in the covered order
  double measured = 0.0, estimated = 0.0;
  // The same for the world's part and for the rest of split samples
  // (DirectSums::sky_rgb): each calibrated on its own (used_split).
  double sky_measured = 0.0, sky_estimated = 0.0, other_measured = 0.0, other_estimated = 0.0;
  uint32_t used = 0, used_split = 0;
  uint32_t count_before = 0;
  double sum_sq_before = 0.0;
};

struct DirectResult {
  std::vector<DirectSums> sums;  // per covered texel of the slice, from its first
  // With light groups or directional lightmaps: per covered texel of the
  // slice, the split of sums.rgb (transport/context/split.h: 3 floats per slot;
  // texel k's slot l at 3 * (k * slots + l)).
  std::vector<float> split_rgb;
  uint32_t slots = 0;
  bool chooses_lights = false;  // each sample's shadow ray goes to one light chosen at random (DirectPass)
  float* split_sums(size_t k) { return slots ? &split_rgb[3 * k * slots] : nullptr; }
  DirectNoise noise;
  DirectValues values;  // the estimate's direct light (pool_direct) after the last round
  uint64_t samples = 0;  // in all
  // What a texel range's direct pass hands to the merge (transport/farm/texel_ranges.h):
  // round 0's calibration texels in order, and the rounds that ran.
  std::vector<DirectCalibration> calibration;
  uint32_t rounds = 0;
};

// progress(f) runs on the calling thread between groups of texels, f the
// share of the rounds done; once stop() is true the pass ends (between
// groups, texels of the round left unsampled keep what they have).
// round_done (may be empty) sees the sums after each whole round.
struct DirectControl {
  std::function<void(double)> progress;
  std::function<bool()> stop;
  std::function<void(uint32_t round, const DirectResult& sofar)> round_done;
};

// Over the covered texels of `slice` (all by default): a texel's sums depend
// on it alone (its own random numbers, its own sample counts) without a
// target; the calibration texels are picked in the whole covered order. Under
// a target a slice's rounds read its own texels' noise and aim at the target
// relative to an estimate of the whole's mean (whole_mean in the .cpp), so
// that slices each under it put the whole under it.
DirectResult run_direct_pass(tbb::task_arena& arena, const DirectPass& pass, const TexelSpace& space,
                             const BakeSettings& settings, const DirectControl& control,
                             CoveredSlice slice = {});

// More rounds of a whole direct pass (`out`, from run_direct_pass over every
// covered texel) for the texels of the judged groups with group_mean[g] > 0,
// each held to the direct pass's share of the target relative to that mean
// (DirectSchedule): the group's mean texel value with its indirect light,
// which the first rounds could not know. A dim object lit mostly by bounce
// light needs its direct light far more precise than its share of the
// whole's direct light says. Rounds go on while some of those texels need
// samples, up to DirectSchedule::kMaxRefinedRounds in all, and end between
// groups of texels once stop() is true. Updates out's sums, values and
// samples; returns the samples added (0 for a slice's pass).
uint64_t refine_direct(tbb::task_arena& arena, const DirectPass& pass, const TexelSpace& space,
                       const BakeSettings& settings, const std::vector<double>& group_mean, DirectResult& out,
                       const std::function<bool()>& stop);

// true / pair-difference variance from calibration records in order (1 with
// fewer than 32 used): noise.scale, and sky_scale and other_scale for the
// parts of split samples.
void calibrate(const std::vector<DirectCalibration>& records, DirectNoise& noise);

}  // namespace plm

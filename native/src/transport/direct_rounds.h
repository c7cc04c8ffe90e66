// The direct pass over every covered texel, in rounds: DirectSchedule
// (scheduler.h) says how many samples each texel gets next, the texels'
// noise after each round says what it reads. After round 0 the variance
// estimate of Sobol points is calibrated against independent replicates.
#pragma once

#include <tbb/task_arena.h>

#include <cstdint>
#include <functional>
#include <vector>

#include "photonlm/photonlm.h"
#include "transport/direct.h"
#include "transport/film.h"

namespace plm {

struct DirectResult {
  std::vector<DirectSums> sums;  // per covered texel
  DirectNoise noise;
  uint64_t samples = 0;  // in all
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

DirectResult run_direct_pass(tbb::task_arena& arena, const DirectPass& pass, const std::vector<CoveredTexel>& covered,
                             const plm_bake_settings& settings, const DirectControl& control);

}  // namespace plm

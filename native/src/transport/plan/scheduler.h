// How much work a bake does next and when it stops: groups of work sized by
// the clock (progress and cancel stay prompt), the photon pass's checks at
// fixed batch counts (where a bake stops depends on the seed, never on
// timing), the target and time-budget rules, and the direct pass's share of
// samples per texel. Rules are plain functions of their inputs, so they are
// unit-tested without a bake (native/tests/scheduler_test.cpp).
#pragma once

#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <utility>
#include <vector>

namespace plm {

using Clock = std::chrono::steady_clock;

inline double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// ---- Time budget ------------------------------------------------------------
// Each stage ends once this share of the time budget is spent, leaving the
// rest to the stages after it.
constexpr double kDirectBudgetShare = 0.5;       // the direct pass, photons to follow
constexpr double kDirectOnlyBudgetShare = 0.95;  // the direct pass as the whole bake
constexpr double kGatherBudgetShare = 0.9;       // the final gather: texels without rays keep the photons'
constexpr double kPhotonBudgetShare = 0.97;      // the photon pass: estimates and outputs follow
// Gathers after the first start only before this share (the rest is the photons'): a 4 s bake of a
// scene with a 512 x 512 sphere spent it all gathering again and ended at 65 k photons.
constexpr double kRegatherBudgetShare = 0.5;

// True once `share` of a budget of `budget` seconds has passed after
// `elapsed` seconds; never without a budget (0).
inline bool budget_spent(double elapsed, double budget, double share) {
  return budget > 0.0 && elapsed >= share * budget;
}

// The bake's clock against its time budget (settings.time_budget).
class TimeBudget {
 public:
  TimeBudget(double budget_seconds, Clock::time_point start) : budget_(budget_seconds), start_(start) {}
  bool spent(double share) const { return budget_spent(elapsed(), budget_, share); }
  double elapsed() const { return seconds_since(start_); }
  double seconds() const { return budget_; }  // 0: no budget

 private:
  double budget_;
  Clock::time_point start_;
};

// ---- Progress ---------------------------------------------------------------
// Forwards progress to the caller's callback (held by reference), never going
// back; a callback that returns false cancels the bake (plm::Error
// PLM_ERROR_CANCELLED).
class Progress {
 public:
  explicit Progress(const std::function<bool(double, const char*)>& callback) : callback_(callback) {}
  void operator()(double fraction, const char* stage);

 private:
  const std::function<bool(double, const char*)>& callback_;
  double reported_ = 0.0;
};

// ---- Groups of work ---------------------------------------------------------
// Group sizes that take between kGroupSecondsLow and kGroupSecondsHigh: a
// group twice as large after a quick one, half as large after a slow one,
// between `granule` and `limit` (0: granule x 1024) units.
class GroupSizer {
 public:
  static constexpr double kGroupSecondsLow = 0.1, kGroupSecondsHigh = 0.4;
  GroupSizer(uint64_t granule, uint64_t limit)
      : granule_(granule), limit_(limit ? std::max(limit, granule) : granule * 1024), size_(granule) {}
  uint64_t size() const { return size_; }
  // The last group took `seconds`.
  void finished(double seconds) {
    if (seconds < kGroupSecondsLow) size_ = std::min<uint64_t>(size_ * 2, limit_);
    else if (seconds > kGroupSecondsHigh && size_ > granule_) size_ = std::max<uint64_t>(granule_, size_ / 2);
  }

 private:
  uint64_t granule_, limit_, size_;
};

// Runs work(first, count) over [0, total) in groups sized by GroupSizer, so
// that after(done) -- progress, cancel, steering -- runs several times a
// second on the calling thread. after returns false to stop early. No group
// crosses boundary(first), the first count after `first` at which after must
// run (the photon pass's checks).
template <typename Work, typename After, typename Boundary>
void run_in_groups(tbb::task_arena& arena, uint64_t total, uint64_t granule, Work&& work, After&& after,
                   uint64_t max_group, Boundary&& boundary) {
  GroupSizer sizer(granule, max_group);
  for (uint64_t first = 0; first < total;) {
    const uint64_t n = std::min({sizer.size(), total - first, std::max<uint64_t>(boundary(first), first + 1) - first});
    const auto t0 = Clock::now();
    arena.execute([&] { work(first, n); });
    first += n;
    sizer.finished(seconds_since(t0));
    if (!after(first)) return;
  }
}

template <typename Work, typename After>
void run_in_groups(tbb::task_arena& arena, uint64_t total, uint64_t granule, Work&& work, After&& after,
                   uint64_t max_group = 0) {
  run_in_groups(arena, total, granule, work, after, max_group, [total](uint64_t) { return total; });
}

// ---- Loose targets ----------------------------------------------------------
// The smallest bake's photons before the first check and final gather rays
// are sized for a kBaseTarget target; a
// looser target T does loose_share(T) = (kBaseTarget / T)^2 of it (the error
// falls as 1 / sqrt(work)), down to kLeastShare; tighter targets and bakes
// without a target do it all. Each part keeps a floor of its own.
constexpr double kBaseTarget = 0.02, kLeastShare = 0.25;
double loose_share(double target_error);

// ---- Photon pass --------------------------------------------------------------
// The error target is checked after kCheckBatches batches (for a loose target
// after first_check(T): kCheckBatches x loose_share(T), at least
// kLeastCheckBatches), then at kCheckBatches and at fixed batch counts growing
// by a quarter (multiples of kCheckBatches); the final gather runs at the
// first check, or without a target after kCheckBatches.
constexpr uint64_t kCheckBatches = 16, kLeastCheckBatches = 4;
uint64_t first_check(double target_error);
// The photon pass stops when all but the direct part of the error is under
// this share of the target: photons do not lower the direct part, but they
// do lower the gather's (each texel weighs photons and gather by variance).
constexpr double kPhotonShareOfTarget = 0.5;

// The check after the one at `check` batches.
inline uint64_t next_check(uint64_t check) {
  if (check < kCheckBatches) return kCheckBatches;
  return std::max(check + kCheckBatches, (check * 5 / 4) / kCheckBatches * kCheckBatches);
}

// The parts of the estimated relative error (transport/output/film_estimate.h, ErrorEstimate).
struct ErrorParts {
  double relative = 0.0;     // all of it
  double direct = 0.0;       // the direct pass's part
  double gather = 0.0;       // the final gather's part
  double gather_rays = 0.0;  // of that, its rays' own noise (more rays lower it; not what they looked up)
  double mean = 0.0;         // the mean texel value (irradiance / pi) the parts are relative to
  // All but the direct part (photons and gather).
  double rest() const { return std::sqrt(std::max(0.0, relative * relative - direct * direct)); }
};

// Whether the photon pass stops at a check: the target is reached, the
// direct part alone misses it, or all but the direct part is under
// kPhotonShareOfTarget x the target.
bool target_reached(const ErrorParts& e, double target);
// The same for every group the target judges apart (each object, small ones
// with their neighbours: transport/context/texel_space.h, judge_groups).
inline bool target_reached(const std::vector<ErrorParts>& groups, double target) {
  return std::all_of(groups.begin(), groups.end(), [&](const ErrorParts& e) { return target_reached(e, target); });
}

// Progress towards the target at a check: (target / error)^2 (the error falls
// as 1 / sqrt(photons)), at most 1.
double target_progress(double relative, double target);

// When the photon pass checks its error: at fixed batch counts only.
class CheckSchedule {
 public:
  explicit CheckSchedule(uint64_t first = kCheckBatches) : next_(first) {}
  // Whether the error is checked once `batches` batches are merged; moves on
  // to the next check when it is. Merges stop at each check (next()).
  bool due(uint64_t batches) {
    if (batches != next_) return false;
    next_ = next_check(next_);
    return true;
  }
  uint64_t next() const { return next_; }

 private:
  uint64_t next_;
};

// ---- Final gather -------------------------------------------------------------
// Rays per texel of the first gather: kGatherSamples, 4x as many for half
// the target error under a target below 2 % (at most kMaxGatherSamples),
// kGatherSamples x loose_share above it (at least kLeastGatherSamples).
constexpr uint32_t kGatherSamples = 16, kMaxGatherSamples = 256, kLeastGatherSamples = 4;
uint32_t gather_samples(double target_error);
// Under a target the gather runs at the first check the photons alone do not
// pass, and at once again while the target is not met and the gather's part
// of the error is above kPhotonShareOfTarget x the target and falling. That
// part is the spread of its rays, which 4x the rays quarter, and the error
// of the texels they look up (other objects, the ground), which a gather
// lowers only as the gathers before it improved what it looks up (bounce
// light between gathered surfaces) and otherwise waits for more photons: a
// dim object at the first check looks up a few thousand photon hits, and
// five gathers of ever more rays there cost 100 M rays and left its error as
// it was. So from the third gather at a check on, a group goes on only while
// its part fell by kGatherProgress with the gather before, or while its
// rays' own part is above kPhotonShareOfTarget x the target and a real share
// of the gather part (kRaysProgress). Each gather looks up the estimate the
// one before improved.
// Judged per group (each object, small ones with their neighbours): a gather
// after the first gathers again only the texels of the groups that need it
// (the rest keep their rays), with 4x the rays of the one before, at most
// kMaxGatherSamples where every texel is gathered again and as many more as
// the share of the texels gathered is smaller (the same rays in all), up to
// kMaxGroupGatherSamples: a dim object lit by bounce light from a small bright
// patch needs thousands of rays a texel, the walls around it a few dozen.
// At most kMaxGathers gathers at a check, and only while the rays grow. At
// a later check, once the photons have grown kRegatherPhotonGrowth-fold since
// the last gather (their error halved), the groups whose gather part, lookups
// included, is still above kPhotonShareOfTarget x the target gather again
// with as many rays as before, or as many as kMaxGatherSamples over every
// texel allow where more groups need them now: what they look up is better
// (while the gathers have traced no more rays than the photons).
constexpr uint32_t kMaxGathers = 6, kMaxGroupGatherSamples = 4096, kRegatherPhotonGrowth = 4;
struct RegatherPlan {
  std::vector<uint8_t> groups;  // per group: its texels are gathered again
  uint64_t texels = 0;          // their covered texels
  uint32_t samples = 0;         // rays per texel; 0: no gather
};
// After `gathers` gathers at this check, the last of `last_samples` rays: the
// next one, if any. `texels`: covered texels per group. `fresh`: the photons
// have grown since the last gather (as many rays as before will do, or fewer
// where the budget allows no more).
// `before`: the groups' parts before the last gather (after the second
// gather at a check, a group whose gather part fell by less than
// kGatherProgress goes on only where its rays' own part is above
// kPhotonShareOfTarget x the target and quartering its variance would lower
// the gather part below kRaysProgress of it).
constexpr double kGatherProgress = 0.8, kRaysProgress = 0.95;
RegatherPlan plan_regather(uint32_t gathers, uint32_t last_samples, const std::vector<ErrorParts>& groups,
                           const std::vector<size_t>& texels, double target, bool fresh = false,
                           const std::vector<ErrorParts>* before = nullptr);

// ---- Direct pass --------------------------------------------------------------
// What the allocation of a texel's next samples reads: its sample count, its
// variance of the mean and the phantom sample's part of it (transport/direct/direct.h).
struct DirectTexelNoise {
  uint32_t count = 0;
  double variance = 0.0, phantom = 0.0;
};

// The groups the direct pass's target judges apart (each object, small ones
// with their neighbours: TexelSpace::judged): each group's mean texel value
// and each texel's group. One group of mean `mean` holding every texel by default.
struct DirectGroups {
  std::vector<double> mean;        // per group
  std::vector<uint32_t> of_texel;  // per texel (empty: all in group 0)
  DirectGroups(double whole_mean) : mean{whole_mean} {}  // NOLINT: one group is the plain case
  DirectGroups(std::vector<double> means, std::vector<uint32_t> groups)
      : mean(std::move(means)), of_texel(std::move(groups)) {}
  uint32_t of(size_t texel) const { return of_texel.empty() ? 0u : of_texel[texel]; }
};

// How many direct samples each texel gets in each round. Round 0 gives every
// texel direct_samples (with a target at most kFirstTargetSamples: loose
// targets keep them, since the calibration of the variance estimate depends on
// the count -- Sobol pairs of 8 samples overstate their variance 1.35x, of 16
// samples 2.6x on the 21-monkey courtyard -- and a first round of 8 took it
// 2.2x the samples to 3 %). Then, with a target, while a group's direct
// part's RMS error is above kDirectShareOfTarget x target relative to the
// group's mean (the rest is the photons'), each of its texels gets its share
// of the fewest samples that reach it, re-estimated after each round: a texel's variance v_i
// after n_i samples is taken to fall as n^-a (a = kDirectConvergence), so
// sum_i v_i (n_i / m_i)^a = budget is met with the fewest samples by
// m_i = c w_i, w_i = (v_i n_i^a)^(1 / (a + 1)), c = (sum_j w_j / budget)^(1 / a)
// (for a = 1: m_i ~ the per-sample deviation). Where the noise is plainer, the
// next round adds the rest. After round 0, if the phantom sample is most of
// the estimate, every texel is first topped up to kTopUpGrowth x its first
// samples (at most direct_samples), which cuts the phantom's part fourfold. Texels
// without two samples get direct_samples x 2^round (texels that see a light
// rarely, the sky through a window, need thousands).
class DirectSchedule {
 public:
  static constexpr uint32_t kMaxRounds = 16;
  // Rounds in all with the later ones of refine_direct (a round's number keys
  // its samples' random stream: below the calibration's and the mean's keys).
  static constexpr uint32_t kMaxRefinedRounds = 0xF0;
  static constexpr uint32_t kFirstTargetSamples = 16, kProbeSamples = 9;
  static constexpr uint32_t kTopUpGrowth = 2;
  // Stratified samples over a shadow edge: n^-1.5; plain noise: n^-1.
  static constexpr double kDirectConvergence = 1.5;
  static constexpr double kDirectShareOfTarget = 0.7;
  // A group is judged relative to at least this share of the whole's mean
  // direct light: one the direct light hardly reaches (lit by bounces, or not
  // at all) would otherwise be held to a tiny allowance its phantom sample
  // alone exceeds; its noise there is small beside its indirect light.
  static constexpr double kDirectJudgedFloor = 0.1;
  // A texel gets at most this many times max(first, direct_samples) in all
  // (a target far out of reach ends) ...
  static constexpr double kMaxDirectGrowth = 2048.0;
  // ... and at most kMaxRoundGrowth times its samples more in one round
  // (rounds stay short: the time budget and cancel are checked often).
  static constexpr double kMaxRoundGrowth = 4.0;

  DirectSchedule(double target_error, uint32_t direct_samples);
  // Samples per texel of round 0.
  uint32_t first() const { return first_; }
  // A loose target's probe: for targets of 4 % and looser (loose_share at
  // its least), round 0 first runs with fewer samples (0: no probe): 9 a
  // texel at 4 %, looser targets as many fewer as keep the probe's error the
  // same share of the target (its variance falling as n^-a,
  // kDirectConvergence), rounded up to a square (the strata): 4 from 7.4 %,
  // no fewer (a texel's noise is estimated from pairs of strata). At 8 % the
  // fine sphere scene's bake takes 0.27 s instead of 0.33 s. If the probe meets the target the pass goes on from there; if not, its
  // samples are dropped and round 0 runs with first() -- topped up instead,
  // the calibration and the allocation that follows read two Sobol sets of 8
  // as one of 16, and a courtyard of 21 subdivided monkeys took 1.45x the
  // time to 3 %. The dropped probe costs that courtyard about 15 % at 5 %.
  uint32_t probe() const { return probe_; }
  // Whether the noise of some group's texels after a round is above the
  // direct pass's share of the target (next_round then refines).
  bool refines(const DirectGroups& groups, const std::vector<DirectTexelNoise>& texels) const;
  // After round `round`: `groups` holds the groups' mean texel values,
  // `texels` every covered texel's noise. Sets want[i] for the texels that
  // get more samples and returns them in order.
  std::vector<uint32_t> next_round(uint32_t round, const DirectGroups& groups,
                                   const std::vector<DirectTexelNoise>& texels, std::vector<uint32_t>& want) const;

 private:
  // Whether a mean texel variance mean_var is above the direct pass's share of the target.
  bool above_share(double mean, double mean_var) const {
    return target_ > 0.0 && std::sqrt(mean_var) > kDirectShareOfTarget * target_ * mean;
  }

  double target_;
  uint32_t direct_samples_, first_, probe_;
};

}  // namespace plm

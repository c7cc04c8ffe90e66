// The bake's scheduling rules (transport/plan/scheduler.h) as functions of their
// inputs: group sizes, the check schedule, the stopping rule, the time-budget
// shares and the direct pass's allocation of samples.
#include "transport/plan/scheduler.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace plm {
namespace {

TEST(Scheduler, GroupsGrowWhenQuickAndShrinkWhenSlowWithinBounds) {
  GroupSizer sizer(64, 0);
  EXPECT_EQ(sizer.size(), 64u);
  for (int i = 0; i < 20; ++i) sizer.finished(0.01);
  EXPECT_EQ(sizer.size(), 64u * 1024);  // at most granule x 1024 by default
  sizer.finished(0.2);                  // between the bounds: unchanged
  EXPECT_EQ(sizer.size(), 64u * 1024);
  sizer.finished(1.0);
  EXPECT_EQ(sizer.size(), 32u * 1024);
  for (int i = 0; i < 20; ++i) sizer.finished(1.0);
  EXPECT_EQ(sizer.size(), 64u);  // never below the granule

  GroupSizer capped(2, 8);
  for (int i = 0; i < 10; ++i) capped.finished(0.0);
  EXPECT_EQ(capped.size(), 8u);
  GroupSizer below(16, 4);  // a cap under the granule is the granule
  below.finished(0.0);
  EXPECT_EQ(below.size(), 16u);
}

TEST(Scheduler, RunInGroupsCoversEverythingInOrderAndStopsWhenAsked) {
  tbb::task_arena arena(1);
  std::vector<int> seen(1000, 0);
  uint64_t next = 0, calls = 0, last_done = 0;
  run_in_groups(
      arena, seen.size(), 3,
      [&](uint64_t first, uint64_t n) {
        EXPECT_EQ(first, next);
        for (uint64_t i = first; i < first + n; ++i) ++seen[i];
        next = first + n;
      },
      [&](uint64_t done) {
        EXPECT_GT(done, last_done);
        last_done = done;
        ++calls;
        return true;
      });
  EXPECT_EQ(last_done, seen.size());
  for (int s : seen) EXPECT_EQ(s, 1);

  uint64_t done_at_stop = 0;
  run_in_groups(
      arena, 1000, 3, [](uint64_t, uint64_t) {},
      [&](uint64_t done) {
        done_at_stop = done;
        return false;
      });
  EXPECT_EQ(done_at_stop, 3u);  // one group, then stopped
}

TEST(Scheduler, ChecksAreAtFixedBatchCountsWhateverTheGroups) {
  // The checks come at the same batch counts however the batches are grouped
  // (group sizes follow the clock): no group crosses the next check.
  tbb::task_arena arena(1);
  auto checks_with_groups = [&](uint64_t granule, uint64_t max_group) {
    CheckSchedule schedule;
    std::vector<uint64_t> at;
    run_in_groups(
        arena, 400, granule, [](uint64_t, uint64_t) {},
        [&](uint64_t end) {
          if (schedule.due(end)) at.push_back(end);
          return true;
        },
        max_group, [&](uint64_t) { return schedule.next(); });
    return at;
  };
  const std::vector<uint64_t> a = checks_with_groups(1, 1), b = checks_with_groups(7, 0);
  EXPECT_EQ(a, b);
  const std::vector<uint64_t> expected = {16, 32, 48, 64, 80, 96, 112, 128, 160, 192, 240, 288, 352};
  EXPECT_EQ(a, expected);
  // Without the boundary, groups of 7 pass over the checks.
  CheckSchedule schedule;
  uint64_t checked = 0;
  run_in_groups(arena, 400, 7, [](uint64_t, uint64_t) {}, [&](uint64_t end) {
    checked += schedule.due(end);
    return true;
  }, 7);
  EXPECT_LT(checked, expected.size());
  // Multiples of kCheckBatches, each at most a quarter (plus one step) after the last.
  uint64_t check = kCheckBatches;
  for (int i = 0; i < 60; ++i) {
    const uint64_t next = next_check(check);
    EXPECT_EQ(next % kCheckBatches, 0u);
    EXPECT_GE(next, check + kCheckBatches);
    EXPECT_LE(next, std::max(check + kCheckBatches, check * 5 / 4));
    check = next;
  }
}

TEST(Scheduler, StopsAtTheTargetAndNotOnALooseEstimate) {
  const double target = 0.02;
  EXPECT_TRUE(target_reached({0.02, 0.0, 0.0}, target));
  EXPECT_TRUE(target_reached({0.015, 0.01, 0.0}, target));
  EXPECT_FALSE(target_reached({0.0201, 0.0, 0.0}, target));
  // Above the target, but the direct part alone misses it: photons cannot
  // lower that part.
  EXPECT_TRUE(target_reached({0.03, 0.025, 0.014}, target));
  // Above the target with all but the direct part under half of it.
  EXPECT_TRUE(target_reached({0.021, 0.0185, 0.009}, target));
  // Above the target, most of it the gather's: more photons take weight
  // from the gather (each texel weighs the two by variance), so go on
  // (the Cornell box at 0.7 % stopped after 65,536 photons at 1.06 %).
  EXPECT_FALSE(target_reached({0.0106 * 2 / 0.7, 0.0026 * 2 / 0.7, 0.0099 * 2 / 0.7}, target));
  // Above the target with the photons' part above half of it: go on.
  EXPECT_FALSE(target_reached({0.03, 0.01, 0.0}, target));
  EXPECT_FALSE(target_reached({0.5, 0.0, 0.0}, target));
  // Parts larger than the whole (rounding): the photons' part is 0, not NaN.
  EXPECT_TRUE(target_reached({0.03, 0.04, 0.0}, target));
  EXPECT_DOUBLE_EQ(target_progress(0.04, target), 0.25);
  EXPECT_DOUBLE_EQ(target_progress(0.01, target), 1.0);
  EXPECT_DOUBLE_EQ(target_progress(0.0, target), 1.0);
}

TEST(Scheduler, BudgetSharesAreRespected) {
  EXPECT_FALSE(budget_spent(1e9, 0.0, 0.5));  // no budget: never spent
  EXPECT_FALSE(budget_spent(4.99, 10.0, kDirectBudgetShare));
  EXPECT_TRUE(budget_spent(5.0, 10.0, kDirectBudgetShare));
  // The stages end in order and leave time for what follows them.
  EXPECT_LT(kDirectBudgetShare, kGatherBudgetShare);
  EXPECT_LT(kGatherBudgetShare, kPhotonBudgetShare);
  EXPECT_LT(kPhotonBudgetShare, 1.0);
  EXPECT_LT(kDirectOnlyBudgetShare, 1.0);
  for (double share : {kDirectBudgetShare, kGatherBudgetShare, kPhotonBudgetShare, kDirectOnlyBudgetShare}) {
    EXPECT_FALSE(budget_spent(share * 100.0 - 1e-9, 100.0, share));
    EXPECT_TRUE(budget_spent(share * 100.0, 100.0, share));
  }
  const TimeBudget none(0.0, Clock::now());
  EXPECT_FALSE(none.spent(0.0));
  const TimeBudget past(1.0, Clock::now() - std::chrono::seconds(2));
  EXPECT_TRUE(past.spent(kPhotonBudgetShare));
}

TEST(Scheduler, GatherRaysGrowWithTheSquareOfTheTarget) {
  EXPECT_EQ(gather_samples(0.0), kGatherSamples);
  EXPECT_EQ(gather_samples(0.05), kLeastGatherSamples);  // (2 / 5)^2 of 16, at least 4
  EXPECT_EQ(gather_samples(0.03), 7u);                   // (2 / 3)^2 of 16
  EXPECT_EQ(gather_samples(0.02), kGatherSamples);
  EXPECT_EQ(gather_samples(0.01), 4 * kGatherSamples);
  EXPECT_EQ(gather_samples(0.001), kMaxGatherSamples);
}

// A further gather has 4x the rays of the one before and runs while the
// target is not met and its rays' own part of the error is above half the
// target, at most kMaxGathers at a check and only while the rays grow.
TEST(Scheduler, FurtherGathersHaveMoreRaysWhileTheirPartIsLarge) {
  ErrorParts e;
  e.relative = 0.06, e.direct = 0.02, e.gather = 0.03, e.gather_rays = 0.03;
  const std::vector<size_t> one{1000};
  EXPECT_EQ(plan_regather(1, 4, {e}, one, 0.05).samples, 16u);  // 3 % > half of 5 %
  EXPECT_EQ(plan_regather(2, 64, {e}, one, 0.05).samples, kMaxGatherSamples);
  EXPECT_EQ(plan_regather(3, kMaxGatherSamples, {e}, one, 0.05).samples, 0u);  // the rays no longer grow
  // ... unless the photons have grown since: the same rays look up a better estimate.
  EXPECT_EQ(plan_regather(0, kMaxGatherSamples, {e}, one, 0.05, true).samples, kMaxGatherSamples);
  EXPECT_EQ(plan_regather(kMaxGathers, 4, {e}, one, 0.05).samples, 0u);
  e.gather = e.gather_rays = 0.02;
  EXPECT_EQ(plan_regather(1, 4, {e}, one, 0.05).samples, 0u);
  e.relative = 0.045, e.gather = e.gather_rays = 0.03;  // the target is met: no further gather
  EXPECT_EQ(plan_regather(1, 4, {e}, one, 0.05).samples, 0u);
}

// A gather part made of what the rays looked up (the photon estimate of the
// surfaces they meet) falls with more rays at the same photons only while the
// gathers before improve what they look up (bounce light between gathered
// surfaces): after the second gather at a check, a group whose gather part
// fell by less than kGatherProgress waits for photons unless its rays' own
// part is above half the target and a real share of the gather part. (A dim
// object of the artist's room at its first check: 0.24 of its mean from
// lookups, 0.011 from its rays; five gathers there traced 100 M rays for
// nothing.)
TEST(Scheduler, LookupErrorWaitsForPhotons) {
  ErrorParts before, e;
  before.relative = 0.3, before.direct = 0.02, before.gather = 0.25, before.gather_rays = 0.02;
  e = before;
  e.gather = 0.24, e.gather_rays = 0.011;
  const std::vector<size_t> one{1000};
  const std::vector<ErrorParts> was{before};
  EXPECT_EQ(plan_regather(1, 16, {e}, one, 0.03, false, &was).samples, 64u);  // the first at a check: yes
  EXPECT_EQ(plan_regather(2, 64, {e}, one, 0.03, false, &was).samples, 0u);   // no progress: wait
  EXPECT_EQ(plan_regather(0, 64, {e}, one, 0.03, true).samples, 256u);        // the photons have grown
  e.gather = 0.15;  // the lookups improved: gather on
  EXPECT_EQ(plan_regather(2, 64, {e}, one, 0.03, false, &was).samples, 256u);
  e.gather = 0.24, e.gather_rays = 0.05;  // above half the target, but 4x the rays lower it by 2 %: no
  EXPECT_EQ(plan_regather(2, 64, {e}, one, 0.03, false, &was).samples, 0u);
  e.gather = 0.05, e.gather_rays = 0.045;  // the rays' own noise is most of it: 4x the rays lower it by 37 %
  EXPECT_EQ(plan_regather(2, 64, {e}, one, 0.03, false, &was).samples, 256u);
  e.gather = 0.02, e.gather_rays = 0.012;  // most of it, but under half the target
  before.gather = 0.021;
  const std::vector<ErrorParts> was_close{before};
  EXPECT_EQ(plan_regather(2, 64, {e}, one, 0.03, false, &was_close).samples, 0u);
}

// Judged per object: one object that needs it is enough, and only its texels
// are gathered again, with as many more rays as it has fewer texels than the
// whole (the rays of one gather of every texel at kMaxGatherSamples), up to
// kMaxGroupGatherSamples.
TEST(Scheduler, RegatherRefinesTheGroupsThatNeedIt) {
  ErrorParts met, needs;
  met.relative = 0.045, met.gather = met.gather_rays = 0.03;
  needs.relative = 0.3, needs.gather = needs.gather_rays = 0.25;
  EXPECT_EQ(plan_regather(1, 16, {met, met}, {100, 100}, 0.05).samples, 0u);
  const RegatherPlan p = plan_regather(3, kMaxGatherSamples, {met, needs}, {900, 100}, 0.05);
  EXPECT_EQ(p.groups, (std::vector<uint8_t>{0, 1}));
  EXPECT_EQ(p.samples, 4 * kMaxGatherSamples);  // 10x fewer texels allow 2560 rays: 4x the last
  EXPECT_EQ(plan_regather(4, 4 * kMaxGatherSamples, {met, needs}, {900, 100}, 0.05).samples,
            10 * kMaxGatherSamples);
  EXPECT_EQ(plan_regather(4, 1024, {met, needs}, {99900, 100}, 0.05).samples, kMaxGroupGatherSamples);
}

// The target holds for every judged group: a bright object under the target
// does not hide a dim one above it.
TEST(Scheduler, TargetJudgesEveryGroup) {
  const double target = 0.02;
  const ErrorParts met{0.015, 0.01, 0.0}, missed{0.03, 0.01, 0.0}, direct_misses{0.03, 0.04, 0.0};
  EXPECT_TRUE(target_reached(std::vector<ErrorParts>{met, met}, target));
  EXPECT_FALSE(target_reached(std::vector<ErrorParts>{met, missed}, target));
  EXPECT_TRUE(target_reached(std::vector<ErrorParts>{met, direct_misses}, target));
}

// Texels after a round: n samples each, variance of the mean v.
std::vector<DirectTexelNoise> texels(const std::vector<double>& variances, uint32_t n, double phantom = 0.0) {
  std::vector<DirectTexelNoise> out;
  for (double v : variances) out.push_back({n, v, phantom * v});
  return out;
}

TEST(Scheduler, DirectRoundsWithoutTargetOnlyFillTexelsWithoutPairs) {
  const DirectSchedule s(0.0, 64);
  EXPECT_EQ(s.first(), 64u);
  std::vector<DirectTexelNoise> t = texels({1.0, 1.0, 1.0}, 64);
  t[1].count = 1;  // a texel whose samples mostly missed its islands
  t[2].count = 0;
  std::vector<uint32_t> want(3, 0);
  EXPECT_EQ(s.next_round(0, 1.0, t, want), (std::vector<uint32_t>{1, 2}));
  EXPECT_EQ(want[1], 128u);  // direct_samples x 2^(round + 1)
  EXPECT_EQ(s.next_round(5, 1.0, t, want), (std::vector<uint32_t>{1, 2}));
  EXPECT_EQ(want[2], 64u * 64);
  EXPECT_EQ(s.next_round(12, 1.0, t, want), (std::vector<uint32_t>{1, 2}));
  EXPECT_EQ(want[2], 64u * 256);  // at most 2^8
}

// A loose target does (2 % / T)^2 of the smallest bake, down to a quarter,
// each part above a floor of its own: the first check (after 4 batches at
// 4 % and looser, then the usual 16, 32, ...) and the gather's rays (4); 2 %
// and tighter, and no target, do it all.
TEST(Scheduler, LooseTargetsDoLessOfTheSmallestBake) {
  EXPECT_EQ(loose_share(0.0), 1.0);
  EXPECT_EQ(loose_share(0.01), 1.0);
  EXPECT_EQ(loose_share(0.02), 1.0);
  EXPECT_NEAR(loose_share(0.03), 4.0 / 9.0, 1e-12);
  EXPECT_EQ(loose_share(0.08), kLeastShare);
  EXPECT_EQ(first_check(0.0), kCheckBatches);
  EXPECT_EQ(first_check(0.02), kCheckBatches);
  EXPECT_EQ(first_check(0.03), 7u);
  EXPECT_EQ(first_check(0.05), kLeastCheckBatches);
  CheckSchedule checks(first_check(0.05));
  std::vector<uint64_t> at;
  for (uint64_t b = 1; b <= 64; ++b)
    if (checks.due(b)) at.push_back(b);
  EXPECT_EQ(at, (std::vector<uint64_t>{4, 16, 32, 48, 64}));
}

// Targets of 4 % and looser first probe round 0 with 9 samples a texel at
// 4 %, fewer for looser targets (the error per sample count falling as
// n^-0.75: 4 from 7.4 %, squares for the strata); refines() tells whether a round's noise is above the direct share of the
// target (a probe that is, is dropped).
TEST(Scheduler, LooseTargetsProbeRoundZero) {
  EXPECT_EQ(DirectSchedule(0.0, 64).probe(), 0u);
  EXPECT_EQ(DirectSchedule(0.02, 64).probe(), 0u);
  EXPECT_EQ(DirectSchedule(0.03, 64).probe(), 0u);
  EXPECT_EQ(DirectSchedule(0.04, 64).probe(), 9u);
  EXPECT_EQ(DirectSchedule(0.07, 64).probe(), 9u);
  EXPECT_EQ(DirectSchedule(0.075, 64).probe(), 4u);
  EXPECT_EQ(DirectSchedule(0.5, 64).probe(), 4u);  // pairs of strata
  EXPECT_EQ(DirectSchedule(0.05, 9).probe(), 0u);  // no fewer than round 0's own
  EXPECT_EQ(DirectSchedule(0.08, 9).probe(), 4u);
  const DirectSchedule s(0.05, 64);
  const double a2 = std::pow(DirectSchedule::kDirectShareOfTarget * 0.05, 2.0);
  EXPECT_FALSE(s.refines(1.0, texels({0.5 * a2, 0.9 * a2, 1.5 * a2}, 8)));
  EXPECT_TRUE(s.refines(1.0, texels({0.5 * a2, 1.5 * a2, 2.0 * a2}, 8)));
  EXPECT_TRUE(s.refines(0.5, texels({0.5 * a2, 0.9 * a2, 1.5 * a2}, 8)));  // a darker mean: relatively noisier
}

TEST(Scheduler, DirectRoundsStopAtTheTarget) {
  const DirectSchedule s(0.02, 64);
  EXPECT_EQ(s.first(), DirectSchedule::kFirstTargetSamples);
  // RMS error under 0.7 x target of a mean of 1: met, nothing more.
  const double a2 = std::pow(DirectSchedule::kDirectShareOfTarget * 0.02, 2.0);
  std::vector<uint32_t> want(4, 0);
  EXPECT_TRUE(s.next_round(1, 1.0, texels({0.9 * a2, 0.5 * a2, 0.8 * a2, 1.5 * a2}, 16), want).empty());
  // The same noise over a mean half as bright is twice the relative error: more samples.
  EXPECT_EQ(s.next_round(1, 0.5, texels({0.9 * a2, 0.5 * a2, 0.8 * a2, 1.5 * a2}, 16), want).size(), 4u);
}

TEST(Scheduler, DirectRoundsMeetTheBudgetWithSamplesWhereTheNoiseIs) {
  const DirectSchedule s(0.02, 16);
  const double allowed = DirectSchedule::kDirectShareOfTarget * 0.02;
  // Mean variance 2 x allowed^2 (near the target: the round aims at the target itself).
  const std::vector<double> v = {1.0 * allowed * allowed, 1.0 * allowed * allowed, 3.0 * allowed * allowed,
                                 3.0 * allowed * allowed};
  const std::vector<DirectTexelNoise> t = texels(v, 16);
  std::vector<uint32_t> want(4, 0);
  const std::vector<uint32_t> more = s.next_round(1, 1.0, t, want);
  ASSERT_EQ(more.size(), 4u);
  EXPECT_EQ(want[0], want[1]);
  EXPECT_GT(want[2], want[0]);  // noisier texels get more
  // The model's variance after the round meets the budget (within the
  // rounding up of each texel's samples).
  const double a = DirectSchedule::kDirectConvergence;
  double after = 0.0;
  for (size_t i = 0; i < v.size(); ++i) after += v[i] * std::pow(16.0 / (16.0 + want[i]), a);
  EXPECT_LE(after / 4.0, allowed * allowed * 1.0001);
  EXPECT_GT(after / 4.0, 0.9 * allowed * allowed);
  // Deterministic: the same inputs give the same samples.
  std::vector<uint32_t> again(4, 0);
  EXPECT_EQ(s.next_round(1, 1.0, t, again), more);
  EXPECT_EQ(again, want);
}

TEST(Scheduler, DirectRoundsGrowBoundedPerRoundAndInAll) {
  const DirectSchedule s(0.001, 16);
  std::vector<uint32_t> want(2, 0);
  // Far from the target: at most kMaxRoundGrowth x a texel's samples in a round.
  s.next_round(1, 1.0, texels({1.0, 1.0}, 16), want);
  EXPECT_EQ(want[0], uint32_t(DirectSchedule::kMaxRoundGrowth * 16));
  // ... and at most kMaxDirectGrowth x direct_samples in all.
  const uint32_t most = uint32_t(16 * DirectSchedule::kMaxDirectGrowth);
  s.next_round(9, 1.0, texels({1.0, 1.0}, most - 10), want);
  EXPECT_EQ(want[0], 10u);
  EXPECT_TRUE(s.next_round(10, 1.0, texels({1.0, 1.0}, most), want).empty());
}

TEST(Scheduler, DirectRoundZeroTopsUpWhereThePhantomDominates) {
  const DirectSchedule s(0.02, 64);
  const double a2 = std::pow(DirectSchedule::kDirectShareOfTarget * 0.02, 2.0);
  std::vector<uint32_t> want(3, 0);
  // Most of the variance is the phantom sample's: every texel gets as many
  // samples again (kTopUpGrowth), whatever its own variance ...
  const std::vector<DirectTexelNoise> t = texels({0.5 * a2, 1.0 * a2, 2.0 * a2}, 16, 0.9);
  EXPECT_EQ(s.next_round(0, 1.0, t, want).size(), 3u);
  EXPECT_EQ(want, (std::vector<uint32_t>{16, 16, 16}));
  // ... at most up to direct_samples.
  const DirectSchedule few(0.02, 24);
  EXPECT_EQ(few.next_round(0, 1.0, t, want).size(), 3u);
  EXPECT_EQ(want, (std::vector<uint32_t>{8, 8, 8}));
  // Only in round 0; later rounds follow the texels' noise.
  std::vector<uint32_t> later(3, 0);
  EXPECT_EQ(s.next_round(1, 1.0, t, later), (std::vector<uint32_t>{2}));
  EXPECT_GT(later[2], 0u);
}

}  // namespace
}  // namespace plm

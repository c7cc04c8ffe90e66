#include "transport/plan/scheduler.h"

#include <algorithm>
#include <cmath>

#include "photonlm/photonlm.h"
#include "util/error.h"

namespace plm {

void Progress::operator()(double fraction, const char* stage) {
  reported_ = std::max(reported_, std::min(1.0, fraction));
  if (callback_ && !callback_(reported_, stage)) fail(PLM_ERROR_CANCELLED, "the bake was cancelled");
}

bool target_reached(const ErrorParts& e, double target) {
  return e.relative <= target || e.direct >= target || e.rest() <= kPhotonShareOfTarget * target;
}

double target_progress(double relative, double target) {
  return std::min(1.0, std::pow(target / std::max(relative, 1e-12), 2.0));
}

double loose_share(double target_error) {
  if (!(target_error > kBaseTarget)) return 1.0;
  return std::max(kLeastShare, std::pow(kBaseTarget / target_error, 2.0));
}

uint64_t first_check(double target_error) {
  return std::max(kLeastCheckBatches, uint64_t(std::lround(double(kCheckBatches) * loose_share(target_error))));
}

uint32_t gather_samples(double target_error) {
  const double least = std::max(double(kLeastGatherSamples), std::round(kGatherSamples * loose_share(target_error)));
  if (!(target_error > 0.0)) return kGatherSamples;
  return uint32_t(
      std::clamp(kGatherSamples * std::pow(kBaseTarget / target_error, 2.0), least, double(kMaxGatherSamples)));
}

RegatherPlan plan_regather(uint32_t gathers, uint32_t last_samples, const std::vector<ErrorParts>& groups,
                           const std::vector<size_t>& texels, double target, bool fresh,
                           const std::vector<ErrorParts>* before) {
  RegatherPlan plan;
  if (gathers >= kMaxGathers) return plan;
  plan.groups.assign(groups.size(), 0);
  double refined = 0.0, total = 0.0;
  for (size_t g = 0; g < groups.size(); ++g) {
    const ErrorParts& e = groups[g];
    // At the same photons 4x the rays quarter the rays' own variance; what
    // they look up gets better as the gathers before improve it (bounce light
    // between gathered surfaces) while the gather part keeps falling, and
    // otherwise only with more photons (fresh).
    const double share = kPhotonShareOfTarget * target;
    const bool falling = gathers <= 1 || fresh || !before || g >= before->size() ||
                         e.gather < kGatherProgress * (*before)[g].gather;
    const double with_rays = std::sqrt(std::max(0.0, e.gather * e.gather - 0.75 * e.gather_rays * e.gather_rays));
    const bool rays_help = e.gather_rays > share && with_rays < kRaysProgress * e.gather;
    plan.groups[g] = e.relative > target && e.gather > share && (falling || rays_help);
    const double n = g < texels.size() ? double(texels[g]) : 1.0;
    total += n;
    if (plan.groups[g]) refined += n;
  }
  if (!(refined > 0.0)) return plan;
  plan.texels = uint64_t(refined);
  const double most = std::clamp(double(kMaxGatherSamples) * total / refined, double(kMaxGatherSamples),
                                 double(kMaxGroupGatherSamples));
  const uint32_t samples = uint32_t(std::min(4.0 * double(last_samples), most));
  // Fresh lookups: as many rays as before, or as many as the gather's ray
  // budget allows where more groups need them now than then.
  if (samples > last_samples || fresh) plan.samples = samples;
  return plan;
}

DirectSchedule::DirectSchedule(double target_error, uint32_t direct_samples)
    : target_(target_error),
      direct_samples_(direct_samples),
      first_(target_error > 0.0 ? std::min(direct_samples, kFirstTargetSamples) : direct_samples),
      probe_(0) {
  if (loose_share(target_error) > kLeastShare) return;
  const double loosest = kBaseTarget / std::sqrt(kLeastShare);  // where the probe starts
  const double n = double(kProbeSamples) * std::pow(loosest / target_error, 2.0 / kDirectConvergence);
  // At least 2 x 2: a texel's noise is estimated from pairs of strata.
  const uint32_t side = std::max(2u, uint32_t(std::ceil(std::sqrt(n) - 1e-9)));
  probe_ = side * side < first_ ? side * side : 0;
}

namespace {

// Per group: its texels, their mean variance, mean phantom variance and
// allocation weights' sum (DirectSchedule::next_round).
struct GroupNoise {
  double count = 0.0, mean_var = 0.0, phantom_var = 0.0, sum_weight = 0.0;
};

std::vector<GroupNoise> group_noise(const DirectGroups& groups, const std::vector<DirectTexelNoise>& texels,
                                    const std::vector<double>* weight) {
  std::vector<GroupNoise> out(groups.mean.size());
  for (size_t i = 0; i < texels.size(); ++i) {
    GroupNoise& g = out[groups.of(i)];
    g.count += 1.0;
    g.mean_var += texels[i].variance;
    g.phantom_var += texels[i].phantom;
    if (weight) g.sum_weight += (*weight)[i];
  }
  for (GroupNoise& g : out) {
    g.mean_var /= std::max(g.count, 1.0);
    g.phantom_var /= std::max(g.count, 1.0);
  }
  return out;
}

}  // namespace

bool DirectSchedule::refines(const DirectGroups& groups, const std::vector<DirectTexelNoise>& texels) const {
  const std::vector<GroupNoise> noise = group_noise(groups, texels, nullptr);
  for (size_t g = 0; g < noise.size(); ++g)
    if (noise[g].count > 0.0 && above_share(groups.mean[g], noise[g].mean_var)) return true;
  return false;
}

std::vector<uint32_t> DirectSchedule::next_round(uint32_t round, const DirectGroups& groups,
                                                 const std::vector<DirectTexelNoise>& texels,
                                                 std::vector<uint32_t>& want) const {
  constexpr double a = kDirectConvergence;
  std::vector<double> weight(texels.size());
  for (size_t i = 0; i < texels.size(); ++i) {
    const DirectTexelNoise& d = texels[i];
    weight[i] = std::pow(d.variance * std::pow(double(std::max(d.count, 1u)), a), 1.0 / (a + 1.0));
  }
  // Each group's share of the fewest samples that bring it to the target.
  struct Plan {
    bool refine = false, top_up = false;
    double scale = 0.0;  // texel i gets weight[i] x scale samples in all
  };
  const std::vector<GroupNoise> noise = group_noise(groups, texels, &weight);
  std::vector<Plan> plans(noise.size());
  // First up to kTopUpGrowth x first (at most direct_samples) everywhere
  // where the phantom sample is most of the estimate: it is no measure of a
  // texel's own noise to allocate by (dark texels of an interior), and it
  // falls as 1 / n^2. All the way to direct_samples at once cost open scenes
  // 1.6x the time to a 2 % target once the sky light was pooled.
  const uint32_t top_up_to = std::min(direct_samples_, kTopUpGrowth * first_);
  for (size_t g = 0; g < noise.size(); ++g) {
    const GroupNoise& n = noise[g];
    Plan& p = plans[g];
    const double allowed = kDirectShareOfTarget * target_ * groups.mean[g];
    p.refine = n.count > 0.0 && above_share(groups.mean[g], n.mean_var);
    // Far from the target a round aims at twice the allowed variance (the rest
    // is left to the next round's new estimate).
    const double aim = n.mean_var > 4.0 * allowed * allowed ? 2.0 : 1.0;
    const double budget = aim * allowed * allowed * n.count;
    p.top_up = p.refine && round == 0 && first_ < top_up_to && n.phantom_var > 0.5 * n.mean_var;
    if (p.refine && budget > 0.0) p.scale = std::pow(n.sum_weight / budget, 1.0 / a);
  }
  const double max_total = double(std::max(first_, direct_samples_)) * kMaxDirectGrowth;
  std::vector<uint32_t> next;
  for (uint32_t i = 0; i < texels.size(); ++i) {
    const DirectTexelNoise& d = texels[i];
    const Plan& p = plans[groups.of(i)];
    double extra = 0.0;
    if (p.top_up) {
      extra = double(top_up_to - first_);
    } else if (p.refine) {
      extra = weight[i] * p.scale - double(d.count);
      extra = std::min({extra, kMaxRoundGrowth * std::max(d.count, first_), max_total - double(d.count)});
      if (extra < 1.0) extra = 0.0;
    }
    if (d.count < 2) extra = std::max(extra, double(direct_samples_) * double(1u << std::min(round + 1, 8u)));
    if (extra > 0.0) {
      want[i] = uint32_t(std::min(std::ceil(extra), 65536.0));
      next.push_back(i);
    }
  }
  return next;
}

}  // namespace plm

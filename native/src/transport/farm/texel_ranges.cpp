#include "transport/farm/texel_ranges.h"

#include <cmath>

#include "util/error.h"

namespace plm {

CoveredSlice texel_range(size_t covered, uint32_t k, uint32_t n) {
  if (n == 0 || k >= n)
    fail(PLM_ERROR_INVALID_ARGUMENT, "texel range ", k, " of ", n, ": expected 0 <= range < count");
  const auto at = [&](uint64_t i) { return size_t((unsigned __int128)covered * i / n); };
  return {at(k), at(uint64_t(k) + 1)};
}

DirectResult join_direct(std::vector<DirectResult>& ranges, uint32_t sampler, const TexelSpace& space) {
  const size_t covered = space.covered.size();
  DirectResult out;
  for (DirectResult& r : ranges) {
    if (out.sums.empty()) out.sums = std::move(r.sums);
    else out.sums.insert(out.sums.end(), r.sums.begin(), r.sums.end());
    out.calibration.insert(out.calibration.end(), r.calibration.begin(), r.calibration.end());
    out.split_rgb.insert(out.split_rgb.end(), r.split_rgb.begin(), r.split_rgb.end());
    out.slots = r.slots;
    out.rounds = std::max(out.rounds, r.rounds);
    r.sums.clear();
    r.split_rgb.clear();
  }
  if (out.sums.size() != covered)
    fail(PLM_ERROR_INVALID_ARGUMENT, "the direct parts hold ", out.sums.size(), " texels where the scene covers ",
         covered);
  for (const DirectSums& d : out.sums) out.samples += d.count;
  if (sampler != PLM_SAMPLER_RANDOM) calibrate(out.calibration, out.noise);
  // typical_sample's sum, with the calibration texels' squared sums and counts
  // before their extra samples where round 0 was the last.
  const bool before = out.rounds == 1;
  size_t next = 0;  // the next calibration record
  double texel_sq = 0.0, sampled = 0.0;
  for (size_t i = 0; i < out.sums.size(); ++i) {
    double sum_sq = out.sums[i].sum_sq;
    uint32_t count = out.sums[i].count;
    if (next < out.calibration.size() && out.calibration[next].texel == i) {
      if (before) {
        sum_sq = out.calibration[next].sum_sq_before;
        count = out.calibration[next].count_before;
      }
      ++next;
    }
    if (count) texel_sq += sum_sq / count, sampled += 1.0;
  }
  out.noise.typical = sampled > 0.0 ? std::sqrt(texel_sq / sampled) : 0.0;
  out.values = pool_direct(space, out.sums, 0, out.noise);
  return out;
}

GatherResult join_gather(std::vector<GatherResult>& ranges, size_t covered) {
  GatherResult out;
  for (GatherResult& r : ranges) {
    out.sums.insert(out.sums.end(), r.sums.begin(), r.sums.end());
    out.info.insert(out.info.end(), r.info.begin(), r.info.end());
    out.split_rgb.insert(out.split_rgb.end(), r.split_rgb.begin(), r.split_rgb.end());
    out.slots = r.slots;
    r = GatherResult();
  }
  if (out.sums.size() != covered)
    fail(PLM_ERROR_INVALID_ARGUMENT, "the gather parts hold ", out.sums.size(), " texels where the scene covers ",
         covered);
  out.typical = typical_sample(out.sums);
  out.scale = gather_scale(out.info);
  return out;
}

}  // namespace plm

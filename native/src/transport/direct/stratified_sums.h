// Sums of a texel's stratified samples (irradiance / pi), kept per covered
// texel by the direct pass and the final gather. Stratified samples make the
// plain sample variance count the texel's smooth variation as noise, so the
// variance of the mean comes from pairs of samples instead (neighbouring
// strata differ by noise plus a little gradient: a slightly conservative bound).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "util/math.h"

namespace plm {

struct StratifiedSums {
  double rgb[3] = {0, 0, 0};
  double sum_sq = 0;    // sum of squared mean-RGB samples
  double pair_sq = 0;   // sum over sample pairs of squared mean-RGB differences
  uint32_t paired = 0;  // samples in those pairs
  uint32_t count = 0;

  double mean() const { return count ? (rgb[0] + rgb[1] + rgb[2]) / (3.0 * count) : 0.0; }
  // Adds sample e; returns its mean RGB.
  double add(Vec3 e) {
    for (int c = 0; c < 3; ++c) rgb[c] += e[c];
    const double a = (double(e.x) + e.y + e.z) / 3.0;
    sum_sq += a * a;
    ++count;
    return a;
  }
  void add_pair(double a, double b) {
    pair_sq += (a - b) * (a - b);
    paired += 2;
  }
  // The variance of the mean from pair differences summing to pair_sum over
  // the paired samples, with `extra` (n^2 x a variance of the mean) added; 0
  // without pairs.
  double pairs_of_mean(double pair_sum, double extra = 0.0) const {
    if (paired == 0) return 0.0;
    const double n = double(count);
    return (pair_sum * (n / double(paired)) + extra) / (n * n);
  }
  // Squared standard error of the mean, scaled by `scale`, with `extra` (n^2
  // x a variance of the mean from elsewhere) added. `typical` enters as one
  // phantom sample, so that a texel whose samples all missed a rarely
  // visible light (the sky through a window) does not look exact. With no
  // pair yet, 100% uncertain.
  double variance_of_mean(double typical, double extra = 0.0, double scale = 1.0) const {
    if (count == 0) return typical * typical;
    const double m = mean();
    if (paired == 0) return std::max(m * m, typical * typical);
    const double n = double(count);
    return scale * (pair_sq * (n / double(paired)) + extra + (typical - m) * (typical - m)) / (n * n);
  }
};

// Pairs neighbouring strata 2i and 2i + 1 of one texel when both hold a sample.
class StratumPairs {
 public:
  void add(uint32_t stratum, double value, StratifiedSums& sums) {
    if (completes(stratum)) sums.add_pair(value, previous_value_);
    previous_value_ = value;
  }
  // Notes a sample in `stratum`; whether it completes a pair with the last one.
  bool completes(uint32_t stratum) {
    const bool pair = stratum % 2 == 1 && previous_ == stratum - 1;
    previous_ = stratum;
    return pair;
  }

 private:
  uint32_t previous_ = ~0u;  // the last stratum with a sample, and its value
  double previous_value_ = 0.0;
};

// The phantom sample's size: a sample's RMS in a typical texel, each texel
// weighing the same however many samples it has.
template <typename Sums>
double typical_sample(const std::vector<Sums>& sums) {
  double texel_sq = 0.0, sampled = 0.0;
  for (const StratifiedSums& s : sums)
    if (s.count) texel_sq += s.sum_sq / s.count, sampled += 1.0;
  return sampled > 0.0 ? std::sqrt(texel_sq / sampled) : 0.0;
}

// The scale that makes pair estimates of the variance honest, from
// calibration texels: for two independent means a, b of a texel, E[(a - b)^2]
// = Var a + Var b, so the sum of the measured squared differences over the sum
// of the estimated variances. 1 with fewer than 32 texels.
inline double calibration_ratio(double measured, double estimated, size_t used) {
  if (used < 32 || !(estimated > 0.0)) return 1.0;
  return std::clamp(measured / estimated, 1e-4, 4.0);
}

}  // namespace plm

#include "transport/film/film.h"

#include <algorithm>
#include <cmath>

namespace plm {

FluxQuantum flux_quantum(double emitted) {
  const int e = int(std::ceil(std::log2(std::max(emitted, 1e-30))));
  FluxQuantum fq;
  fq.q = std::ldexp(1.0, e - 26);
  fq.inv_q = 1.0 / fq.q;
  fq.q2 = std::ldexp(1.0, 2 * e - 26);
  fq.inv_q2 = 1.0 / fq.q2;
  return fq;
}

void Accumulators::add(const Accumulators& o) {
  auto add_sums = [](std::vector<double>& a, const std::vector<double>& b) {
    for (size_t i = 0; i < a.size(); ++i) a[i] += b[i];
  };
  auto add_counts = [](std::vector<uint32_t>& a, const std::vector<uint32_t>& b) {
    for (size_t i = 0; i < a.size(); ++i) a[i] += b[i];
  };
  add_sums(sum, o.sum);
  add_sums(sum_sq, o.sum_sq);
  add_sums(split_sum, o.split_sum);
  add_counts(hits, o.hits);
  for (size_t m = 0; m < back_lit.size(); ++m) back_lit[m] |= o.back_lit[m];
  add_group_hits(o.group_hits, o.group_hits_sq);
  total_sq_q += o.total_sq_q;
  total_sq = double(total_sq_q) * quantum.q2;
  total_hits += o.total_hits;
  if (!caustic.empty()) {
    add_sums(caustic.sum, o.caustic.sum);
    add_sums(caustic.sum_sq, o.caustic.sum_sq);
    add_counts(caustic.hits, o.caustic.hits);
    caustic.total_sq_q += o.caustic.total_sq_q;
    caustic.total_sq = double(caustic.total_sq_q) * quantum.q2;
    caustic.total_hits += o.caustic.total_hits;
  }
}

}  // namespace plm

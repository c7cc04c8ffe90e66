#include "transport/film/photon_batches.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>

#include "transport/photons/photon_sampler.h"

namespace plm {
namespace {

// Blocks per thread: enough that two threads rarely wait for the same lock.
constexpr uint64_t kBlocksPerThread = 16;
// At least this many texels a block, so a batch's share of a block is a run
// of hits, not one.
constexpr uint32_t kMinBlockShift = 8;

}  // namespace

PhotonBatches::PhotonBatches(const PhotonTracer& tracer, Accumulators& acc, unsigned threads, uint64_t cap)
    : tracer_(tracer), acc_(acc), cap_(cap) {
  const uint64_t texels = std::max<uint64_t>(acc.hits.size(), 1);
  if (threads > 1) {
    shift_ = kMinBlockShift;
    while ((texels >> shift_) > kBlocksPerThread * threads) ++shift_;
    blocks_ = uint32_t(((texels - 1) >> shift_) + 1);
  }
  locks_ = std::make_unique<tbb::spin_mutex[]>(blocks_);
}

uint64_t PhotonBatches::add_hits(const std::vector<Hit>& hits, const std::vector<uint32_t>& layers,
                                 const std::vector<float>& u, bool caustic, Scratch& s) {
  if (hits.empty()) return 0;
  const Hit* first = hits.data();
  const bool layered = acc_.split.layers > 0, directional = acc_.split.directional;
  if (blocks_ == 1) {  // one thread: nothing to sort or wait for
    tbb::spin_mutex::scoped_lock lock(locks_[0]);
    return acc_.add_hits(first, first + hits.size(), caustic, layered ? layers.data() : nullptr,
                         directional ? u.data() : nullptr);
  }
  // Counting sort by block, then each block's run under its lock.
  s.start.assign(blocks_ + 1, 0);
  for (const Hit& h : hits) ++s.start[(h.texel >> shift_) + 1];
  for (uint32_t b = 0; b < blocks_; ++b) s.start[b + 1] += s.start[b];
  s.sorted.resize(hits.size());
  if (layered || directional) {
    if (layered) s.sorted_layers.resize(hits.size());
    if (directional) s.sorted_u.resize(3 * hits.size());
    for (size_t i = 0; i < hits.size(); ++i) {
      const uint32_t at = s.start[hits[i].texel >> shift_]++;
      s.sorted[at] = hits[i];
      if (layered) s.sorted_layers[at] = layers[i];
      if (directional) std::copy_n(&u[3 * i], 3, &s.sorted_u[3 * size_t(at)]);
    }
  } else {
    for (const Hit& h : hits) s.sorted[s.start[h.texel >> shift_]++] = h;  // start[b] moves to block b's end
  }
  uint64_t sq_q = 0;
  uint32_t begin = 0;
  for (uint32_t b = 0; b < blocks_; ++b) {
    const uint32_t end = s.start[b];
    if (end == begin) continue;
    tbb::spin_mutex::scoped_lock lock(locks_[b]);
    sq_q += acc_.add_hits(s.sorted.data() + begin, s.sorted.data() + end, caustic,
                          layered ? s.sorted_layers.data() + begin : nullptr,
                          directional ? s.sorted_u.data() + 3 * size_t(begin) : nullptr);
    begin = end;
  }
  return sq_q;
}

void PhotonBatches::trace(uint64_t first, uint64_t n) {
  if (kept_.size() < n) kept_.resize(n);
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, 1), [&](const tbb::blocked_range<uint64_t>& r) {
    Scratch& s = scratch_.local();
    BatchOutput& bo = s.batch;
    for (uint64_t i = r.begin(); i < r.end(); ++i) {
      const uint64_t p0 = (first + i) * kBatchPhotons;
      tracer_.trace_batch(p0, std::min<uint64_t>(kBatchPhotons, cap_ - p0), bo);
      const uint64_t sq = add_hits(bo.hits, bo.hit_layers, bo.hit_u, false, s);
      const uint64_t caustic_sq = add_hits(bo.caustic_hits, bo.caustic_layers, bo.caustic_u, true, s);
      {
        tbb::spin_mutex::scoped_lock lock(totals_);
        acc_.add_totals(bo.hits.size(), sq, false);
        acc_.add_group_hits(bo.group_hits, bo.group_hits_sq);
        if (!acc_.caustic.empty()) acc_.add_totals(bo.caustic_hits.size(), caustic_sq, true);
        for (const uint32_t m : bo.back_meshes) acc_.back_lit[m] = 1;
      }
      // What the caller merges in batch order; the vectors swap, keeping
      // their capacity for the next batches.
      BatchOutput& keep = kept_[i];
      keep.ol_hits.swap(bo.ol_hits);
      keep.ls_hits.swap(bo.ls_hits);
      keep.rays = bo.rays;
      keep.truncated = bo.truncated;
      keep.truncated_flux = bo.truncated_flux;
    }
  });
}

}  // namespace plm

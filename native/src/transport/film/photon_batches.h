// Photon batches traced in parallel with their texel hits added to the bake's
// sums by the thread that traced them, while the hits are still in its cache.
// The texels are split into blocks, each with a lock: a batch's hits are
// sorted by block and each block's share is added under its lock. The sums
// are whole quanta (film.h, FluxQuantum), so the order in which batches
// arrive does not matter and the sums are the same for any thread count.
// What does depend on the order (OL and L-system hits) stays with the batch
// for the caller to merge in batch order.
#pragma once

#include <tbb/enumerable_thread_specific.h>
#include <tbb/spin_mutex.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "transport/film/film.h"
#include "transport/photons/photon_tracer.h"

namespace plm {

class PhotonBatches {
 public:
  // Batches of `tracer` up to photon `cap`, adding into `acc`.
  PhotonBatches(const PhotonTracer& tracer, Accumulators& acc, unsigned threads, uint64_t cap);

  // Traces batches [first, first + n) in parallel (call inside the bake's
  // arena) and adds their texel and caustic hits, hit totals and back-lit
  // meshes to the sums.
  void trace(uint64_t first, uint64_t n);
  // Batch first + i of the last trace: its OL and L-system hits, rays,
  // truncated paths (its texel hits are already in the sums).
  const BatchOutput& kept(uint64_t i) const { return kept_[i]; }

 private:
  struct Scratch {
    BatchOutput batch;
    std::vector<uint32_t> start;  // per block: first of its hits in `sorted`, then the end
    std::vector<Hit> sorted;
    std::vector<uint32_t> sorted_layers;  // with light groups: the sorted hits' layers
    std::vector<float> sorted_u;          // with directional lightmaps: their direction weights
  };
  // Adds hits (caustic ones to the caustic sums) block by block, with light
  // groups each into its layer (layers[i]: hit i's), with directional
  // lightmaps with its direction weight (u[3 i ..]); returns their squared
  // fluxes in quanta.
  uint64_t add_hits(const std::vector<Hit>& hits, const std::vector<uint32_t>& layers, const std::vector<float>& u,
                    bool caustic, Scratch& s);

  const PhotonTracer& tracer_;
  Accumulators& acc_;
  uint64_t cap_;
  uint32_t shift_ = 0, blocks_ = 1;  // block of texel t: t >> shift_
  std::unique_ptr<tbb::spin_mutex[]> locks_;  // per block
  tbb::spin_mutex totals_;                    // hit totals and back-lit meshes
  tbb::enumerable_thread_specific<Scratch> scratch_;
  std::vector<BatchOutput> kept_;
};

}  // namespace plm

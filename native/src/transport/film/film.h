// The bake's film: the photon sums per texel of the global texel index
// (transport/context/texel_space.h), exact in any order of addition so that
// they never depend on the thread count.
#pragma once

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "lightmap/texel_area.h"
#include "scene/scene.h"
#include "transport/context/texel_space.h"
#include "transport/context/split.h"
#include "transport/photons/photon_tracer.h"
#include "transport/rays/tracing.h"

namespace plm {

// Runs each(i) for i < count (the meshes), where texels(i) is mesh i's
// lightmap size: lightmaps of up to kParallelTexels texels in parallel, the
// larger ones after them, one at a time (their own work runs in parallel).
// Each call holds working buffers the size of its lightmap: more large ones
// at once would multiply a bake's peak memory by the thread count. Call it
// inside the bake's arena.
constexpr size_t kParallelTexels = size_t(1) << 16;
template <typename Texels, typename Each>
void for_lightmaps(size_t count, Texels&& texels, Each&& each) {
  tbb::parallel_for(size_t(0), count, [&](size_t i) {
    if (texels(i) <= kParallelTexels) each(i);
  });
  for (size_t i = 0; i < count; ++i)
    if (texels(i) > kParallelTexels) each(i);
}

// Photon fluxes are added as whole multiples of a power-of-two quantum
// (docs/design/sharding.md, "Why the merge is exact"): each hit is rounded to
// the quantum once, and sums of such multiples are exact in double precision
// while below 2^53 quanta, so the sums do not depend on the order of addition.
// Shards of a bake (transport/farm/shard.h) then add up to the single-machine sums
// bit for bit.
struct FluxQuantum {
  double q = 1.0, inv_q = 1.0;    // of a flux
  double q2 = 1.0, inv_q2 = 1.0;  // of a squared flux
  // x rounded to the nearest multiple of quantum (|x| < 2^51 quanta) by the
  // 1.5 x 2^52 trick; inv and quantum are powers of two, so the products are
  // exact (an FMA gives the same) and only the addition rounds. IEEE
  // arithmetic (no -ffast-math) keeps (y + k) - k from being folded.
  static double round_to(double x, double inv, double quantum) {
    constexpr double kMagic = 0x1.8p52;
    return ((x * inv + kMagic) - kMagic) * quantum;
  }
  double flux(double x) const { return round_to(x, inv_q, q); }
  double squared(double x) const { return round_to(x, inv_q2, q2); }
};
// The quantum for a bake whose lights emit `emitted` W: with S the power of
// two at or above it (a photon carries about that flux before the division by
// the photon count), q = S / 2^26 and q2 = S^2 / 2^26. A float flux of S/4 or
// more is a whole multiple of q (no rounding at all), a smaller one is off by
// at most q / 2; a texel's sums stay exact up to 2^27 photons' worth of S, and
// the squared-flux total (an integer) up to 2^37 hits of S.
FluxQuantum flux_quantum(double emitted);

// Photon sums per texel over all lightmaps.
class Accumulators {
 public:
  // caustics: the scene has lobes, and caustic photons (BatchOutput::caustic_hits) get sums of their own.
  // split: the light-group layers and direction moment the photons' fluxes
  // are split into (transport/context/split.h; split_sum).
  Accumulators(uint64_t texels, size_t meshes, bool caustics = false, FluxQuantum quantum_in = {},
               SplitLayout split_in = {})
      : sum(3 * texels, 0.0), sum_sq(texels, 0.0), hits(texels, 0), back_lit(meshes, 0), quantum(quantum_in),
        split(split_in), split_sum(size_t(3) * split_in.slots() * texels, 0.0) {
    if (caustics) caustic.resize(texels);
  }
  std::vector<double> sum, sum_sq;  // flux / pick probability (not yet divided by the photon count)
  std::vector<uint32_t> hits;
  std::vector<uint8_t> back_lit;  // per mesh: a photon reached its back
  double total_sq = 0.0;  // total_sq_q quanta of FluxQuantum::q2
  uint64_t total_sq_q = 0;
  uint64_t total_hits = 0;
  FluxQuantum quantum;
  // With light groups (docs/design/light-groups.md) or directional
  // lightmaps (docs/design/directional.md): per slot of the split, the hits'
  // flux split, ordinary and caustic together, 3 per texel; slot l's texel t
  // at 3 * (l * texels + t). Each hit's rounded flux (times its rounded
  // direction weight), so that the layers add up to sum + caustic.sum exactly
  // and the sums do not depend on the order of addition.
  SplitLayout split;
  std::vector<double> split_sum;
  // Per judged group (TexelSpace::judged): the sums over photons of the hits
  // k each left there and of k^2 (BatchOutput::group_hits; empty until added).
  std::vector<uint64_t> group_hits, group_hits_sq;
  void add_group_hits(const std::vector<uint64_t>& k, const std::vector<uint64_t>& k_sq) {
    group_hits.resize(std::max(group_hits.size(), k.size()), 0);
    group_hits_sq.resize(group_hits.size(), 0);
    for (size_t g = 0; g < k.size(); ++g) group_hits[g] += k[g], group_hits_sq[g] += k_sq[g];
  }
  uint32_t slots() const { return split.slots(); }
  const double* slot_flux(uint32_t slot, uint64_t texel) const {
    return &split_sum[3 * (size_t(slot) * hits.size() + texel)];
  }
  // Caustic photons' sums (empty without lobes): their own reconstruction
  // and variance (transport/output/film_estimate.h), added to the texel.
  struct CausticSums {
    std::vector<double> sum, sum_sq;
    std::vector<uint32_t> hits;
    double total_sq = 0.0;
    uint64_t total_sq_q = 0;
    uint64_t total_hits = 0;
    void resize(uint64_t texels) {
      sum.assign(3 * texels, 0.0);
      sum_sq.assign(texels, 0.0);
      hits.assign(texels, 0);
    }
    bool empty() const { return hits.empty(); }
    double phantom_sq() const { return total_hits ? total_sq / double(total_hits) : 0.0; }
  } caustic;

  // The squared flux of one average hit: the phantom hit that keeps texels
  // with few hits from looking exact.
  double phantom_sq() const { return total_hits ? total_sq / double(total_hits) : 0.0; }

  // Adds the sums of other (the same texels, meshes and quantum): exact, so
  // the order in which accumulators are added does not matter.
  void add(const Accumulators& other);

  // Adds hits [h, end) to the texel sums (caustic: the caustic sums), each
  // flux and squared flux rounded to the quantum; returns the squared fluxes
  // in quanta of q2, for add_totals (transport/film/photon_batches.h calls both
  // from several threads, one texel block at a time). With layers, layer[i]
  // is hit i's layer; with directional lightmaps, u[3 i ..] its direction weight.
  uint64_t add_hits(const Hit* h, const Hit* end, bool caustic_hits, const uint32_t* layer = nullptr,
                    const float* u = nullptr) {
    if (!slots()) return add_hits_to<false>(h, end, caustic_hits, nullptr, nullptr);
    return add_hits_to<true>(h, end, caustic_hits, layer, u);
  }
  // Counts `count` hits whose squared fluxes sum to sq_q quanta.
  void add_totals(uint64_t count, uint64_t sq_q, bool caustic_hits) {
    if (caustic_hits) {
      caustic.total_sq_q += sq_q;
      caustic.total_sq = double(caustic.total_sq_q) * quantum.q2;
      caustic.total_hits += count;
    } else {
      total_sq_q += sq_q;
      total_sq = double(total_sq_q) * quantum.q2;
      total_hits += count;
    }
  }

 private:
  // add_hits, with or without a split (kSplit: a loop of its own, so that a
  // bake without light groups or directions runs the loop it always ran).
  template <bool kSplit>
  uint64_t add_hits_to(const Hit* h, const Hit* end, bool caustic_hits, const uint32_t* layer, const float* u) {
    double* s = caustic_hits ? caustic.sum.data() : sum.data();
    double* s2 = caustic_hits ? caustic.sum_sq.data() : sum_sq.data();
    uint32_t* n = caustic_hits ? caustic.hits.data() : hits.data();
    uint64_t total = 0;  // a local: the stores through the arrays could otherwise alias it
    for (; h != end; ++h) {
      const size_t t = h->texel;
      const double f[3] = {quantum.flux(h->r), quantum.flux(h->g), quantum.flux(h->b)};
      for (int c = 0; c < 3; ++c) s[3 * t + c] += f[c];
      if constexpr (kSplit) {
        if (layer) {
          double* ls = &split_sum[3 * (size_t(*layer++) * hits.size() + t)];
          for (int c = 0; c < 3; ++c) ls[c] += f[c];
        }
        if (u) {
          for (uint32_t a = 0; a < 3; ++a) {
            double* ds = &split_sum[3 * (size_t(split.axis_slot(a)) * hits.size() + t)];
            for (int c = 0; c < 3; ++c) ds[c] += quantum.flux(f[c] * double(u[a]));
          }
          u += 3;
        }
      }
      const double a = (double(h->r) + h->g + h->b) / 3.0;
      const double sq = quantum.squared(a * a);
      s2[t] += sq;
      total += uint64_t(sq * quantum.inv_q2);
      ++n[t];
    }
    return total;
  }
};

}  // namespace plm

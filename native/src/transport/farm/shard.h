// Bakes split over machines (docs/farm.md): shard k of n traces a contiguous
// share of the photon batches and keeps their sums (transport/film/film.h, exact
// and order-free); the merge adds every shard's sums and runs what needs the
// whole photon solution (direct pass, final gather, estimate, outputs). The
// sums are exact, so the merge equals the single-machine bake bit for bit
// whatever the shard count. The final gather reads the estimate after
// kCheckBatches batches, so a shard's range is cut there into two segments.
#pragma once

#include <tbb/task_arena.h>

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "photonlm/photonlm.h"
#include "scene/scene.h"
#include "transport/direct/direct_rounds.h"
#include "transport/film/film.h"
#include "transport/gather/final_gather.h"
#include "transport/plan/settings.h"

namespace plm {

// Photon sums over batches [begin, end).
struct PhotonSegment {
  uint64_t begin = 0, end = 0;
  Accumulators acc{0, 0};
  uint64_t rays = 0, truncated = 0;
  double truncated_flux = 0.0;  // whole quanta (FluxQuantum::flux)
};

// What fixes a shard's sums besides the seed and settings: the bake fills it
// in both modes, the merge checks the parts' against its own.
struct ShardLayout {
  uint64_t scene_hash = 0;
  uint64_t batch_count = 0;  // batches of the whole bake
  uint64_t texel_count = 0;
  uint64_t covered = 0;      // covered texels (what texel ranges split)
  uint32_t mesh_count = 0;
  bool caustics = false;
  FluxQuantum quantum;
  SplitLayout split;  // light-group layers and directional lightmaps' moments (transport/context/split.h)
  uint32_t judged_groups = 0;  // TexelSpace::judged_groups: Accumulators::group_hits' size
};

// One part of a sharded bake (transport/jobs/bake_jobs.h): kTrace traces a
// shard's photons; kDirect runs the direct pass of a texel range, kGather the
// final gather of one over the photon and direct parts
// (transport/farm/texel_ranges.h); kMerge bakes the rest from every part.
struct ShardJob {
  enum Mode { kTrace, kMerge, kDirect, kGather } mode = kTrace;
  uint32_t index = 0, count = 1;        // kTrace: this shard of count; kDirect, kGather: this texel range of count
  std::vector<PhotonSegment> segments;  // kTrace: what it traced; kMerge, kGather: every shard's, in batch order
  std::vector<std::string> sources;     // kMerge, kGather: the part each segment came from (for messages)
  // kDirect: its range's direct pass; kMerge, kGather: every range's, in
  // order, from the direct parts (empty: the bake runs the direct pass).
  std::vector<DirectResult> direct;
  // kGather: its range's gather; kMerge: every range's from the gather parts
  // (empty: the merge gathers, if the bake has a final gather).
  std::vector<GatherResult> gather;
  bool gathered = false;                // kGather: the bake has a final gather (else its part holds no texels)
  double direct_target = 0.0;           // kMerge, kGather: the direct parts' target error (0: none)
  ShardLayout layout;                   // the bake's (shard_layout); the parts' (load_parts)
};

class PhotonTracer;

// Traces batches [first, last) (of photons [0, cap)) as shard_segments cuts
// them, each summed into accumulators shaped as `shape` (texels, meshes,
// caustics, quantum). progress(fraction) is called on this thread after each
// group of batches.
std::vector<PhotonSegment> trace_segments(tbb::task_arena& arena, const PhotonTracer& tracer, unsigned threads,
                                          uint64_t cap, const Accumulators& shape, uint64_t first, uint64_t last,
                                          const std::function<void(double)>& progress);

// Batches [first, last) of shard k of n over `batches` batches (contiguous,
// sizes differing by at most one, in shard order).
std::pair<uint64_t, uint64_t> shard_batches(uint64_t batches, uint32_t k, uint32_t n);

// A shard's ranges: [first, last), cut at kCheckBatches when it crosses it.
std::vector<std::pair<uint64_t, uint64_t>> shard_segments(uint64_t first, uint64_t last);

// Throws PLM_ERROR_INVALID_ARGUMENT (naming the setting or feature) where a
// bake cannot be split: no photon pass, a time budget or a target error (the photon count
// then depends on timing or on the estimate; a texel range's direct pass may
// have a target), OL groups and L-system objects; texel ranges without a direct pass.
void check_shardable(const Scene& scene, const BakeSettings& settings, ShardJob::Mode mode = ShardJob::kTrace);

// The layout of a bake of `scene` with these settings, texels and sums.
ShardLayout shard_layout(const Scene& scene, const BakeSettings& settings, const TexelSpace& space,
                         const Accumulators& acc);

// A 64-bit hash of what the photon pass reads from the scene: geometry, UVs,
// lightmap sizes, materials, lights, world (textures and world maps by their
// file names or sizes).
uint64_t scene_hash(const Scene& scene);

// The merge's checks: the segments tile [0, layout.batch_count) in order
// (a range's gather: the batches before kCheckBatches) and every one holds
// layout's texels, meshes and quantum. Messages name the segment's source.
void check_segments(const ShardJob& job);

// "" where every sum of acc is below 2^53 quanta (exact, so the merge equals
// the single-machine bake bit for bit); else a warning saying how many texels
// passed it (their last bits may then depend on the shard count).
std::string inexact_sums(const Accumulators& acc);

// 64-bit hash of bytes (the part file's checksums): word-wise multiply-xor.
uint64_t hash_bytes(const void* data, size_t size, uint64_t seed = 0);

}  // namespace plm

// The texel-range stages of a sharded bake (docs/farm.md,
// docs/design/sharding.md, "Texel ranges split the direct pass and the final
// gather"): the direct pass and the final gather split by contiguous ranges of
// the covered texels. A texel's direct samples and gather rays depend on the
// texel, the seed and (the gather) the estimate it looks up, never on which
// other texels run beside it, so range k of n holds exactly the sums one
// machine computes for those texels; the merge joins the ranges and derives
// what reads all texels (the phantom samples, the Sobol calibration's scale) as
// one machine does.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "transport/direct/direct_rounds.h"
#include "transport/farm/shard.h"
#include "transport/film/film.h"
#include "transport/gather/final_gather.h"

namespace plm {

// Covered texels of range k of n: contiguous, sizes differing by at most one.
CoveredSlice texel_range(size_t covered, uint32_t k, uint32_t n);

// Every range's direct pass (in range order, moved from) as one machine's:
// the sums in order, the calibration's scale from all its texels in order
// (1 with the random sampler), the phantom sample as the last round computed
// it (after round 0 alone: before the calibration's extra samples joined).
DirectResult join_direct(std::vector<DirectResult>& ranges, uint32_t sampler, const TexelSpace& space);

// Every range's gather (in range order, moved from) as one machine's.
// Both throw PLM_ERROR_INVALID_ARGUMENT where the ranges do not hold `covered` texels.
GatherResult join_gather(std::vector<GatherResult>& ranges, size_t covered);

}  // namespace plm

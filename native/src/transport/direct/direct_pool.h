// The direct light of the covered texels as the estimate uses it. Where the
// world lights the scene and every sample reaches every light
// (DirectSums::sky_rgb), the world's part -- sky light, which changes slowly
// except close to what blocks it -- is a local linear fit over the
// neighbouring texels of the same surface and similar direct light
// (lightmap/reconstruct.h, reconstruct_linear), reaching no further than
// kSkyReach x the harmonic mean distance of the texel's blocked sky rays
// (Ward's irradiance-cache radius: ambient occlusion changes over about the
// distance to the occluder). The rest -- sun lamps, area lights, a map's sun,
// whose shadows are sharp -- stays the texel's own mean. A fit over a 5 x 5
// neighbourhood averages about 25 texels' sky samples: in an open sunlit
// scene, where the sky's occluded share is most of the direct noise, the
// same error takes a fraction of the samples. The phantom sample of such
// texels is a typical world part: the lamps cannot be missed by every sample.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "transport/direct/direct.h"
#include "transport/film/film.h"

namespace plm {

// Per covered texel of a slice: the direct light (irradiance / pi, 3 values),
// its estimated variance of the mean and the phantom sample's part of that.
struct DirectValues {
  std::vector<double> value3, variance, phantom;
  bool empty() const { return variance.empty(); }
  double mean(size_t k) const { return (value3[3 * k] + value3[3 * k + 1] + value3[3 * k + 2]) / 3.0; }
};

// The fit's largest radius (texels) and its reach in harmonic mean distances.
// It pools texels whose normals differ by less than 5 degrees (kSkyMinCos):
// on a curved surface the sky light follows the normal, and a fit over the
// 25 degrees the photons' pooling allows left the subdivided monkeys of a
// courtyard 35 % noisier than their own means once their samples were many.
constexpr uint32_t kSkyRadius = 2;
constexpr float kSkyMinCos = 0.996f;
constexpr double kSkyReach = 0.5;
// Lightmaps with fewer split texels keep their own means: the choice of the
// radius averages over the lightmap's texels.
constexpr size_t kMinPooledTexels = 256;

// The direct values of covered texels [first, first + sums.size()); texels
// outside the slice take no part in any fit. Texels without split samples
// (CSG sub-texels, scenes without a world) keep their own mean and variance.
DirectValues pool_direct(const TexelSpace& space, const std::vector<DirectSums>& sums, size_t first,
                         const DirectNoise& noise);

}  // namespace plm

// Fills texels outside the UV islands from their filled neighbours, one ring
// per pass, so bilinear filtering at island borders shows no seams.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace plm {

// values: channels floats per texel; filled: 1 where a texel holds a value.
// Each pass gives every empty texel the average of its filled edge neighbours,
// or where it has none, of its filled corner neighbours.
void dilate(std::vector<float>& values, int channels, std::vector<uint8_t>& filled, uint32_t width,
            uint32_t height, uint32_t passes);

}  // namespace plm

#include "lightmap/dilate.h"

namespace plm {

void dilate(std::vector<float>& values, int channels, std::vector<uint8_t>& filled, uint32_t width,
            uint32_t height, uint32_t passes) {
  std::vector<uint32_t> ring;
  std::vector<float> ring_values;
  for (uint32_t pass = 0; pass < passes; ++pass) {
    ring.clear();
    ring_values.clear();
    for (uint32_t y = 0; y < height; ++y) {
      for (uint32_t x = 0; x < width; ++x) {
        const uint32_t i = y * width + x;
        if (filled[i]) continue;
        // Edge neighbours first: a texel between two islands that touches one
        // by an edge and the other by a corner takes the first's value alone.
        float sum[8] = {0, 0, 0, 0, 0, 0, 0, 0};
        int count = 0;
        for (int diagonal = 0; diagonal < 2 && count == 0; ++diagonal) {
          for (int dy = -1; dy <= 1; ++dy) {
            for (int dx = -1; dx <= 1; ++dx) {
              if ((dx != 0 && dy != 0) != (diagonal == 1) || (dx == 0 && dy == 0)) continue;
              const int64_t nx = int64_t(x) + dx, ny = int64_t(y) + dy;
              if (nx < 0 || ny < 0 || nx >= width || ny >= height) continue;
              const uint32_t j = uint32_t(ny) * width + uint32_t(nx);
              if (!filled[j]) continue;
              for (int c = 0; c < channels; ++c) sum[c] += values[size_t(j) * channels + c];
              ++count;
            }
          }
        }
        if (count == 0) continue;
        ring.push_back(i);
        for (int c = 0; c < channels; ++c) ring_values.push_back(sum[c] / float(count));
      }
    }
    if (ring.empty()) break;
    for (size_t k = 0; k < ring.size(); ++k) {
      filled[ring[k]] = 1;
      for (int c = 0; c < channels; ++c) values[size_t(ring[k]) * channels + c] = ring_values[k * channels + c];
    }
  }
}

}  // namespace plm

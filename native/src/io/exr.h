// OpenEXR output through OpenImageIO, written atomically: the image goes to a
// temporary file in the target folder, which is renamed over the target only
// once it is complete. A failed write leaves no file behind.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace plm {

// pixels: width * height * channel_names.size() floats, rows bottom first
// (UV order); the file gets rows top first. Throws plm::Error on failure.
void write_exr_atomic(const std::string& path, uint32_t width, uint32_t height,
                      const std::vector<std::string>& channel_names, const float* pixels);

// R, G, B from rgb (3 floats per pixel) and one more channel per plane
// (width * height floats each, named `names`), interleaved into one image and
// written as write_exr_atomic does. EXR sorts channels by name after R, G, B:
// give the planes in that order.
void write_rgb_exr_atomic(const std::string& path, uint32_t width, uint32_t height, const float* rgb,
                          const std::vector<std::string>& names, const std::vector<const float*>& planes);

}  // namespace plm

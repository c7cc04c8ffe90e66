// Image files, read and written by the engine itself: OpenEXR through the
// OpenEXR library; PNG, JPEG, BMP, TGA, PSD, GIF, Radiance HDR and binary
// PPM/PGM through stb_image; PFM (the float images the Blender add-on hands
// over) by a reader of its own. Other formats (TIFF, WebP, ...) are refused
// with a message saying which formats are read; the add-on converts those
// images first.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace plm {

struct ImageFile {
  uint32_t width = 0, height = 0;
  uint32_t channels = 0;  // 1 (grey), 2 (grey + alpha), 3 or 4
  // Bits of the stored integer samples (8 or 16, scaled here to [0, 1] as
  // stored: colour-encoded values stay encoded), 0 for float images (EXR, HDR, PFM).
  int integer_bits = 0;
  std::vector<float> pixels;  // width * height * channels, the top row first
};

// Reads the image at path. Throws plm::Error (PLM_ERROR_IO) naming owner and
// `what` ("texture", "environment map") when it cannot be read or has no pixels.
ImageFile read_image_file(const std::string& path, const std::string& owner, const char* what);

// The image's width and height without decoding its pixels (same errors).
void image_file_size(const std::string& path, const std::string& owner, const char* what, uint32_t& width,
                     uint32_t& height);

// An OpenEXR file of float channels, ZIP-compressed, written atomically: to a
// temporary file in the target folder, renamed over the target once complete;
// a failed write leaves no file behind. pixels: width * height *
// channel_names.size() floats, rows bottom first (UV order); the file gets rows
// top first; half: channels of 16-bit floats. Throws plm::Error (PLM_ERROR_IO) on failure.
void write_exr_atomic(const std::string& path, uint32_t width, uint32_t height,
                      const std::vector<std::string>& channel_names, const float* pixels, bool half = false);

// R, G, B from rgb (3 floats per pixel) and one more channel per plane
// (width * height floats each, named `names`), interleaved into one image and
// written as write_exr_atomic does. EXR sorts channels by name after R, G, B:
// give the planes in that order.
void write_rgb_exr_atomic(const std::string& path, uint32_t width, uint32_t height, const float* rgb,
                          const std::vector<std::string>& names, const std::vector<const float*>& planes);

// The named float channels of an EXR (a channel the file lacks reads as 0):
// width * height * names.size() floats, rows bottom first (the order
// write_exr_atomic takes); no names: the size only. Throws plm::Error
// (PLM_ERROR_IO) naming the file.
std::vector<float> read_exr_channels(const std::string& path, const std::vector<std::string>& names,
                                     uint32_t& width, uint32_t& height);

}  // namespace plm

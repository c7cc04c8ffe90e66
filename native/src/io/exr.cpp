#include "io/exr.h"

#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <OpenImageIO/imageio.h>

#include "util/error.h"

namespace plm {

void write_exr_atomic(const std::string& path, uint32_t width, uint32_t height,
                      const std::vector<std::string>& channel_names, const float* pixels) {
  if (path.empty()) fail(PLM_ERROR_INVALID_ARGUMENT, "EXR path is empty");
  static std::atomic<uint64_t> counter{0};
  const std::string tmp = path + ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter++);
  const int nc = static_cast<int>(channel_names.size());
  OIIO::ImageSpec spec(static_cast<int>(width), static_cast<int>(height), nc, OIIO::TypeDesc::FLOAT);
  spec.channelnames = channel_names;
  spec.attribute("compression", "zip");
  spec.attribute("Software", "photonlm");

  auto out = OIIO::ImageOutput::create("openexr");
  if (!out) fail(PLM_ERROR_IO, "cannot write '", path, "': OpenImageIO has no OpenEXR writer: ", OIIO::geterror());
  if (!out->open(tmp, spec)) fail(PLM_ERROR_IO, "cannot write '", path, "': ", out->geterror());
  // Rows bottom first in memory, top first in the file: a negative y stride.
  const OIIO::stride_t xstride = OIIO::stride_t(nc) * sizeof(float);
  const OIIO::stride_t ystride = xstride * OIIO::stride_t(width);
  const float* last_row = pixels + size_t(height - 1) * width * nc;
  bool ok = out->write_image(OIIO::TypeDesc::FLOAT, last_row, xstride, -ystride);
  std::string message = ok ? "" : out->geterror();
  ok = out->close() && ok;
  if (!ok) {
    if (message.empty()) message = out->geterror();
    std::remove(tmp.c_str());
    fail(PLM_ERROR_IO, "cannot write '", path, "': ", message);
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    fail(PLM_ERROR_IO, "cannot rename '", tmp, "' to '", path, "'");
  }
}

void write_rgb_exr_atomic(const std::string& path, uint32_t width, uint32_t height, const float* rgb,
                          const std::vector<std::string>& names, const std::vector<const float*>& planes) {
  const size_t n = size_t(width) * height, k = 3 + planes.size();
  std::vector<float> pixels(k * n);
  for (size_t t = 0; t < n; ++t) {
    for (size_t c = 0; c < 3; ++c) pixels[k * t + c] = rgb[3 * t + c];
    for (size_t j = 0; j < planes.size(); ++j) pixels[k * t + 3 + j] = planes[j][t];
  }
  std::vector<std::string> channels = {"R", "G", "B"};
  channels.insert(channels.end(), names.begin(), names.end());
  write_exr_atomic(path, width, height, channels, pixels.data());
}

}  // namespace plm

#include "util/image_file.h"

#include <unistd.h>

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfThreading.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstring>
#include <exception>
#include <fstream>
#include <memory>
#include <thread>

#define STB_IMAGE_IMPLEMENTATION
#define STBI_FAILURE_USERMSG
#include <stb/stb_image.h>

#include "util/error.h"

namespace plm {
namespace {

constexpr const char* kFormats = "OpenEXR, Radiance HDR, PFM, PNG, JPEG, BMP, TGA, PSD, GIF and binary PPM/PGM";
constexpr double kMaxPixels = double(1u << 28);

enum class Format { Exr, Pfm, Stb };

Format sniff(const std::string& path, const std::string& owner, const char* what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(PLM_ERROR_IO, owner, ": cannot read ", what, " '", path, "': cannot open the file");
  unsigned char magic[4] = {0, 0, 0, 0};
  in.read(reinterpret_cast<char*>(magic), 4);
  if (magic[0] == 0x76 && magic[1] == 0x2f && magic[2] == 0x31 && magic[3] == 0x01) return Format::Exr;
  if (magic[0] == 'P' && (magic[1] == 'F' || magic[1] == 'f') && std::isspace(magic[2])) return Format::Pfm;
  return Format::Stb;
}

void check_size(long long w, long long h, const std::string& path, const std::string& owner, const char* what) {
  if (w <= 0 || h <= 0) fail(PLM_ERROR_IO, owner, ": ", what, " '", path, "' has no pixels");
  if (double(w) * double(h) > kMaxPixels)
    fail(PLM_ERROR_IO, owner, ": ", what, " '", path, "' is ", w, " x ", h, " pixels, more than 2^28");
}

// The channels to read from an EXR: R, G, B (plain or the last part of a
// layer's name, "View Layer.Combined.R"), else Y, else the only channel.
std::vector<std::string> exr_channels(const Imf::ChannelList& list) {
  auto find = [&](const char* c) -> std::string {
    if (list.findChannel(c)) return c;
    const std::string suffix = std::string(".") + c;
    for (auto it = list.begin(); it != list.end(); ++it) {
      const std::string name = it.name();
      if (name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0)
        return name;
    }
    return "";
  };
  const std::string r = find("R"), g = find("G"), b = find("B");
  if (!r.empty() && !g.empty() && !b.empty()) return {r, g, b};
  if (list.findChannel("Y")) return {"Y"};
  auto first = list.begin();
  if (first != list.end() && ++list.begin() == list.end()) return {first.name()};
  return {};
}

ImageFile read_exr(const std::string& path, const std::string& owner, const char* what, bool pixels) {
  ImageFile img;
  try {
    Imf::InputFile file(path.c_str());
    const Imath::Box2i dw = file.header().dataWindow();
    const long long w = (long long)dw.max.x - dw.min.x + 1, h = (long long)dw.max.y - dw.min.y + 1;
    check_size(w, h, path, owner, what);
    const std::vector<std::string> names = exr_channels(file.header().channels());
    if (names.empty())
      fail(PLM_ERROR_IO, owner, ": ", what, " '", path, "' has no R, G, B or Y channel");
    img.width = uint32_t(w);
    img.height = uint32_t(h);
    img.channels = uint32_t(names.size());
    if (!pixels) return img;
    img.pixels.assign(size_t(w) * size_t(h) * img.channels, 0.0f);
    const size_t xs = img.channels * sizeof(float), ys = xs * size_t(w);
    // Slice addresses are base + x xs + y ys for data-window coordinates (x, y).
    char* origin = reinterpret_cast<char*>(img.pixels.data()) - ptrdiff_t(dw.min.x) * ptrdiff_t(xs) -
                   ptrdiff_t(dw.min.y) * ptrdiff_t(ys);
    Imf::FrameBuffer fb;
    for (size_t c = 0; c < names.size(); ++c)
      fb.insert(names[c], Imf::Slice(Imf::FLOAT, origin + c * sizeof(float), xs, ys, 1, 1, 0.0));
    file.setFrameBuffer(fb);
    file.readPixels(dw.min.y, dw.max.y);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    fail(PLM_ERROR_IO, owner, ": cannot read ", what, " '", path, "': ", e.what());
  }
  return img;
}

ImageFile read_pfm(const std::string& path, const std::string& owner, const char* what, bool pixels) {
  std::ifstream in(path, std::ios::binary);
  std::string tag;
  long long w = 0, h = 0;
  double scale = 0.0;
  in >> tag >> w >> h >> scale;
  if (!in || (tag != "PF" && tag != "Pf") || scale == 0.0 || !std::isspace(in.get()))
    fail(PLM_ERROR_IO, owner, ": cannot read ", what, " '", path, "': not a PFM file");
  check_size(w, h, path, owner, what);
  ImageFile img;
  img.width = uint32_t(w);
  img.height = uint32_t(h);
  img.channels = tag == "PF" ? 3 : 1;
  if (!pixels) return img;
  const size_t row = size_t(w) * img.channels;
  std::vector<float> data(row * size_t(h));
  in.read(reinterpret_cast<char*>(data.data()), std::streamsize(data.size() * sizeof(float)));
  if (!in) fail(PLM_ERROR_IO, owner, ": cannot read ", what, " '", path, "': the file is too short");
  if (scale > 0.0)  // big-endian samples
    for (float& f : data) {
      uint32_t u;
      std::memcpy(&u, &f, 4);
      u = __builtin_bswap32(u);
      std::memcpy(&f, &u, 4);
    }
  img.pixels.resize(data.size());
  for (size_t y = 0; y < size_t(h); ++y)  // PFM rows run bottom to top
    std::memcpy(&img.pixels[y * row], &data[(size_t(h) - 1 - y) * row], row * sizeof(float));
  return img;
}

bool is_pnm(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[2] = {0, 0};
  in.read(magic, 2);
  return magic[0] == 'P' && magic[1] >= '1' && magic[1] <= '6';
}

ImageFile read_stb(const std::string& path, const std::string& owner, const char* what, bool pixels) {
  int w = 0, h = 0, n = 0;
  if (!stbi_info(path.c_str(), &w, &h, &n))
    fail(PLM_ERROR_IO, owner, ": cannot read ", what, " '", path, "': ", stbi_failure_reason(), " (formats read: ",
         kFormats, ")");
  check_size(w, h, path, owner, what);
  ImageFile img;
  img.width = uint32_t(w);
  img.height = uint32_t(h);
  img.channels = uint32_t(n);
  const bool hdr = stbi_is_hdr(path.c_str()) != 0;
  const bool deep = !hdr && stbi_is_16_bit(path.c_str()) != 0;
  img.integer_bits = hdr ? 0 : deep ? 16 : 8;
  if (deep && is_pnm(path))  // stb_image 2.27 reads their samples in the wrong byte order
    fail(PLM_ERROR_IO, owner, ": ", what, " '", path, "' is a 16-bit PPM/PGM, which is not read: save it as a "
         "16-bit PNG");
  if (!pixels) return img;
  const size_t count = size_t(w) * size_t(h) * size_t(n);
  img.pixels.resize(count);
  auto failed = [&] {
    fail(PLM_ERROR_IO, owner, ": cannot read ", what, " '", path, "': ", stbi_failure_reason());
  };
  if (hdr) {  // Radiance HDR: linear floats (stbi_loadf is never called on 8-bit images)
    std::unique_ptr<float, void (*)(void*)> data(stbi_loadf(path.c_str(), &w, &h, &n, 0), stbi_image_free);
    if (!data) failed();
    std::memcpy(img.pixels.data(), data.get(), count * sizeof(float));
  } else if (deep) {
    std::unique_ptr<stbi_us, void (*)(void*)> data(stbi_load_16(path.c_str(), &w, &h, &n, 0), stbi_image_free);
    if (!data) failed();
    for (size_t i = 0; i < count; ++i) img.pixels[i] = float(data.get()[i]) * (1.0f / 65535.0f);
  } else {
    std::unique_ptr<stbi_uc, void (*)(void*)> data(stbi_load(path.c_str(), &w, &h, &n, 0), stbi_image_free);
    if (!data) failed();
    for (size_t i = 0; i < count; ++i) img.pixels[i] = float(data.get()[i]) * (1.0f / 255.0f);
  }
  return img;
}

ImageFile read_any(const std::string& path, const std::string& owner, const char* what, bool pixels) {
  switch (sniff(path, owner, what)) {
    case Format::Exr:
      return read_exr(path, owner, what, pixels);
    case Format::Pfm:
      return read_pfm(path, owner, what, pixels);
    case Format::Stb:
      break;
  }
  return read_stb(path, owner, what, pixels);
}

}  // namespace

ImageFile read_image_file(const std::string& path, const std::string& owner, const char* what) {
  return read_any(path, owner, what, true);
}

void image_file_size(const std::string& path, const std::string& owner, const char* what, uint32_t& width,
                     uint32_t& height) {
  const ImageFile img = read_any(path, owner, what, false);
  width = img.width;
  height = img.height;
}

void write_exr_atomic(const std::string& path, uint32_t width, uint32_t height,
                      const std::vector<std::string>& channel_names, const float* pixels, bool half) {
  if (path.empty()) fail(PLM_ERROR_INVALID_ARGUMENT, "EXR path is empty");
  static std::atomic<uint64_t> counter{0};
  const std::string tmp = path + ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter++);
  const size_t nc = channel_names.size();
  try {
    Imf::Header header(static_cast<int>(width), static_cast<int>(height));
    // zlib's fastest level: lightmaps' noisy floats compress about as well
    // (a 256 x 256 ground: 0.99 MB at level 1 and 4 alike, 1.6 MB raw) in
    // 5-30 % less time.
    header.compression() = Imf::ZIP_COMPRESSION;
    header.zipCompressionLevel() = 1;
    header.insert("Software", Imf::StringAttribute("photonlm"));
    // Rows bottom first in memory, top first in the file.
    const size_t row = size_t(width) * nc;
    std::vector<float> top_first(row * height);
    for (size_t y = 0; y < height; ++y)
      std::memcpy(&top_first[y * row], pixels + (size_t(height) - 1 - y) * row, row * sizeof(float));
    Imf::FrameBuffer fb;
    char* base = reinterpret_cast<char*>(top_first.data());
    std::vector<Imath::half> halves;
    size_t size = sizeof(float);
    if (half) {
      halves.assign(top_first.begin(), top_first.end());
      base = reinterpret_cast<char*>(halves.data());
      size = sizeof(Imath::half);
    }
    const Imf::PixelType type = half ? Imf::HALF : Imf::FLOAT;
    for (size_t c = 0; c < nc; ++c) {
      header.channels().insert(channel_names[c], Imf::Channel(type));
      fb.insert(channel_names[c], Imf::Slice(type, base + c * size, nc * size, row * size));
    }
    // Blocks of scanlines are compressed in parallel on OpenEXR's own pool:
    // zlib is most of a large lightmap's write. A host that set the pool up
    // (Blender) keeps its own; otherwise it gets up to 8 threads.
    static const int threads = [] {
      if (Imf::globalThreadCount() == 0)
        Imf::setGlobalThreadCount(int(std::clamp(std::thread::hardware_concurrency(), 1u, 8u)));
      return Imf::globalThreadCount();
    }();
    Imf::OutputFile file(tmp.c_str(), header, threads);
    file.setFrameBuffer(fb);
    file.writePixels(int(height));
  } catch (const std::exception& e) {
    std::remove(tmp.c_str());
    fail(PLM_ERROR_IO, "cannot write '", path, "': ", e.what());
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

std::vector<float> read_exr_channels(const std::string& path, const std::vector<std::string>& names,
                                     uint32_t& width, uint32_t& height) {
  std::vector<float> pixels;
  try {
    Imf::InputFile file(path.c_str());
    const Imath::Box2i dw = file.header().dataWindow();
    const long long w = (long long)dw.max.x - dw.min.x + 1, h = (long long)dw.max.y - dw.min.y + 1;
    check_size(w, h, path, "lightmap", "file");
    width = uint32_t(w);
    height = uint32_t(h);
    if (names.empty()) return pixels;  // the size only
    const size_t nc = names.size(), xs = nc * sizeof(float), ys = xs * size_t(w);
    std::vector<float> top_first(size_t(w) * size_t(h) * nc, 0.0f);
    char* origin = reinterpret_cast<char*>(top_first.data()) - ptrdiff_t(dw.min.x) * ptrdiff_t(xs) -
                   ptrdiff_t(dw.min.y) * ptrdiff_t(ys);
    Imf::FrameBuffer fb;
    for (size_t c = 0; c < nc; ++c)
      fb.insert(names[c], Imf::Slice(Imf::FLOAT, origin + c * sizeof(float), xs, ys, 1, 1, 0.0));
    file.setFrameBuffer(fb);
    file.readPixels(dw.min.y, dw.max.y);
    // Top first in the file, bottom first in memory.
    const size_t row = size_t(w) * nc;
    pixels.resize(top_first.size());
    for (size_t y = 0; y < size_t(h); ++y)
      std::memcpy(&pixels[y * row], &top_first[(size_t(h) - 1 - y) * row], row * sizeof(float));
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    fail(PLM_ERROR_IO, "cannot read lightmap '", path, "': ", e.what());
  }
  return pixels;
}

}  // namespace plm

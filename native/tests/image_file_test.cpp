// Image files: every format the engine reads gives back the pixels written by
// an independent writer (stb_image_write, OpenEXR, a PFM writer below), top
// row first; unreadable files and other formats are refused with a message
// naming the file, the owner and the formats read.
#include <gtest/gtest.h>
#include <unistd.h>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb/stb_image_write.h>

#include "test_support.h"
#include "util/error.h"
#include "util/image_file.h"

namespace {

std::string temp_dir() {
  static std::string dir;
  if (dir.empty()) {
    char tmpl[] = "/tmp/photonlm_images_XXXXXX";
    dir = mkdtemp(tmpl);
  }
  return dir;
}

// 5 x 3 RGB bytes, every pixel different, row 0 = the top row.
std::vector<unsigned char> pattern_bytes() {
  std::vector<unsigned char> px(5 * 3 * 3);
  for (size_t i = 0; i < px.size(); ++i) px[i] = static_cast<unsigned char>(17 * i % 256);
  return px;
}

std::string error_of(const std::string& path) {
  try {
    plm::read_image_file(path, "material 'wall'", "texture");
  } catch (const plm::Error& e) {
    EXPECT_EQ(e.status(), PLM_ERROR_IO);
    return e.what();
  }
  return "";
}

TEST(ImageFile, EightBitFormatsReadAsStored) {
  const std::vector<unsigned char> px = pattern_bytes();
  const std::string png = temp_dir() + "/p.png", bmp = temp_dir() + "/p.bmp", tga = temp_dir() + "/p.tga";
  ASSERT_TRUE(stbi_write_png(png.c_str(), 5, 3, 3, px.data(), 5 * 3));
  ASSERT_TRUE(stbi_write_bmp(bmp.c_str(), 5, 3, 3, px.data()));
  ASSERT_TRUE(stbi_write_tga(tga.c_str(), 5, 3, 3, px.data()));
  for (const std::string& path : {png, bmp, tga}) {
    const plm::ImageFile img = plm::read_image_file(path, "m", "texture");
    ASSERT_EQ(img.width, 5u) << path;
    ASSERT_EQ(img.height, 3u);
    ASSERT_EQ(img.channels, 3u);
    EXPECT_EQ(img.integer_bits, 8);
    for (size_t i = 0; i < px.size(); ++i) ASSERT_EQ(img.pixels[i], float(px[i]) * (1.0f / 255.0f)) << path << i;
    uint32_t w = 0, h = 0;
    plm::image_file_size(path, "m", "texture", w, h);
    EXPECT_EQ(w * 10 + h, 53u);
  }
}

// A 16-bit grey PNG (uncompressed deflate blocks), written here byte by byte.
void write_png16(const std::string& path, int w, int h, const std::vector<uint16_t>& grey) {
  auto crc = [](const std::string& bytes) {
    uint32_t c = 0xffffffffu;
    for (unsigned char b : bytes) {
      c ^= b;
      for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
    }
    return ~c;
  };
  auto be32 = [](uint32_t v) {
    return std::string{char(v >> 24), char(v >> 16), char(v >> 8), char(v)};
  };
  std::string raw;  // scanlines: filter byte 0, then big-endian samples
  for (int y = 0; y < h; ++y) {
    raw += '\0';
    for (int x = 0; x < w; ++x) raw += std::string{char(grey[size_t(y * w + x)] >> 8), char(grey[size_t(y * w + x)])};
  }
  uint32_t a = 1, b = 0;  // Adler-32
  for (unsigned char c : raw) {
    a = (a + c) % 65521;
    b = (b + a) % 65521;
  }
  const uint16_t len = uint16_t(raw.size());
  const std::string zlib = std::string{'\x78', '\x01', '\x01', char(len), char(len >> 8), char(~len), char(~len >> 8)} +
                           raw + be32((b << 16) | a);
  auto chunk = [&](const std::string& type, const std::string& data) {
    return be32(uint32_t(data.size())) + type + data + be32(crc(type + data));
  };
  const std::string ihdr = be32(uint32_t(w)) + be32(uint32_t(h)) + std::string{16, 0, 0, 0, 0};
  std::ofstream(path, std::ios::binary) << std::string("\x89PNG\r\n\x1a\n", 8) << chunk("IHDR", ihdr)
                                        << chunk("IDAT", zlib) << chunk("IEND", "");
}

TEST(ImageFile, SixteenBitImagesKeepTheirDepth) {
  const std::string path = temp_dir() + "/deep.png";
  const std::vector<uint16_t> values = {0, 1, 32768, 65535, 4660, 43981};  // 3 x 2
  write_png16(path, 3, 2, values);
  const plm::ImageFile img = plm::read_image_file(path, "m", "texture");
  ASSERT_EQ(img.channels, 1u);
  ASSERT_EQ(img.width * 10 + img.height, 32u);
  EXPECT_EQ(img.integer_bits, 16);
  for (size_t i = 0; i < values.size(); ++i) EXPECT_EQ(img.pixels[i], float(values[i]) * (1.0f / 65535.0f)) << i;
  // 16-bit PGM: refused rather than read with its bytes swapped.
  const std::string pgm = temp_dir() + "/deep.pgm";
  std::ofstream(pgm, std::ios::binary) << "P5\n1 1\n65535\n" << std::string("\x12\x34", 2);
  EXPECT_NE(error_of(pgm).find("16-bit PNG"), std::string::npos) << error_of(pgm);
}

TEST(ImageFile, RadianceHdrIsLinearFloat) {
  const std::string path = temp_dir() + "/sky.hdr";
  const float px[6] = {500.0f, 700.0f, 1000.0f, 0.125f, 0.25f, 0.2f};
  ASSERT_TRUE(stbi_write_hdr(path.c_str(), 2, 1, 3, px));
  const plm::ImageFile img = plm::read_image_file(path, "m", "environment map");
  EXPECT_EQ(img.integer_bits, 0);
  ASSERT_EQ(img.pixels.size(), 6u);
  // RGBE: 8-bit mantissas sharing the exponent of the pixel's largest component.
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(img.pixels[i], px[i], (i < 3 ? 1000.0f : 0.25f) / 128.0f) << i;
}

TEST(ImageFile, PfmRowsRunBottomToTopInEitherByteOrder) {
  for (bool little : {true, false}) {
    const std::string path = temp_dir() + (little ? "/le.pfm" : "/be.pfm");
    std::ofstream f(path, std::ios::binary);
    f << "PF\n2 2\n" << (little ? "-1.0" : "1.0") << "\n";
    const float rows[2][6] = {{1, 2, 3, 4, 5, 6}, {7, 8, 9, 10, 11, 12.5f}};  // bottom row first
    for (const auto& row : rows)
      for (float v : row) {
        uint32_t u;
        std::memcpy(&u, &v, 4);
        if (!little) u = __builtin_bswap32(u);
        f.write(reinterpret_cast<const char*>(&u), 4);
      }
    f.close();
    const plm::ImageFile img = plm::read_image_file(path, "m", "texture");
    ASSERT_EQ(img.channels, 3u);
    EXPECT_EQ(img.integer_bits, 0);
    EXPECT_EQ(img.pixels[0], 7.0f) << "top row first";
    EXPECT_EQ(img.pixels[5], 12.5f);
    EXPECT_EQ(img.pixels[6], 1.0f);
  }
}

TEST(ImageFile, ExrRoundTripsBitForBitWithRowsFlipped) {
  const std::string path = temp_dir() + "/rt.exr";
  std::vector<float> px(4 * 3 * 5);  // rows bottom first (UV order), 5 channels
  for (size_t i = 0; i < px.size(); ++i) px[i] = std::ldexp(float(i) + 0.1f, int(i % 7) - 3);
  plm::write_exr_atomic(path, 4, 3, {"R", "G", "B", "error", "hits"}, px.data());
  const plm_test::ExrChannels all = plm_test::read_exr_channels(path);
  ASSERT_EQ(all.channels.size(), 5u);
  const plm::ImageFile img = plm::read_image_file(path, "m", "texture");
  ASSERT_EQ(img.channels, 3u);
  for (uint32_t y = 0; y < 3; ++y)
    for (uint32_t x = 0; x < 4; ++x)
      for (uint32_t c = 0; c < 3; ++c)
        ASSERT_EQ(img.pixels[(y * 4 + x) * 3 + c], px[((2 - y) * 4 + x) * 5 + c]);
  EXPECT_EQ(all.channels.at("hits")[0], px[(2 * 4) * 5 + 4]);
}

// An EXR of named float channels, width x height, all set to value + channel index.
void write_channels(const std::string& path, const std::vector<std::string>& names, int w, int h, float value) {
  Imf::Header header(w, h);
  std::vector<std::vector<float>> data(names.size());
  Imf::FrameBuffer fb;
  for (size_t c = 0; c < names.size(); ++c) {
    header.channels().insert(names[c], Imf::Channel(Imf::FLOAT));
    data[c].assign(size_t(w) * h, value + float(c));
    fb.insert(names[c], Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(data[c].data()), 4, 4 * size_t(w)));
  }
  Imf::OutputFile file(path.c_str(), header);
  file.setFrameBuffer(fb);
  file.writePixels(h);
}

TEST(ImageFile, ExrChannelsAreFoundByName) {
  const std::string grey = temp_dir() + "/y.exr", layered = temp_dir() + "/layers.exr", odd = temp_dir() + "/z.exr";
  write_channels(grey, {"Y"}, 2, 2, 3.0f);
  write_channels(layered, {"ViewLayer.Combined.B", "ViewLayer.Combined.G", "ViewLayer.Combined.R"}, 2, 2, 1.0f);
  write_channels(odd, {"U", "V"}, 2, 2, 1.0f);
  const plm::ImageFile y = plm::read_image_file(grey, "m", "texture");
  EXPECT_EQ(y.channels, 1u);
  EXPECT_EQ(y.pixels[0], 3.0f);
  const plm::ImageFile l = plm::read_image_file(layered, "m", "texture");
  ASSERT_EQ(l.channels, 3u);
  EXPECT_EQ(l.pixels[0], 3.0f);  // R: the third channel written
  EXPECT_EQ(l.pixels[2], 1.0f);  // B
  const std::string e = error_of(odd);
  EXPECT_NE(e.find("no R, G, B or Y channel"), std::string::npos) << e;
}

TEST(ImageFile, OtherFormatsAndBrokenFilesAreNamedErrors) {
  const std::string tiff = temp_dir() + "/scan.tif", empty = temp_dir() + "/empty.png",
                    short_pfm = temp_dir() + "/short.pfm";
  std::ofstream(tiff, std::ios::binary) << "II*\0 not really a tiff";
  std::ofstream(empty, std::ios::binary).close();
  std::ofstream(short_pfm, std::ios::binary) << "PF\n4 4\n-1.0\n" << std::string(12, '\0');
  for (const std::string& path : {tiff, empty}) {
    const std::string e = error_of(path);
    EXPECT_NE(e.find("material 'wall'"), std::string::npos) << e;
    EXPECT_NE(e.find(path), std::string::npos) << e;
    EXPECT_NE(e.find("OpenEXR, Radiance HDR, PFM, PNG, JPEG"), std::string::npos) << e;
  }
  EXPECT_NE(error_of(short_pfm).find("too short"), std::string::npos);
  EXPECT_NE(error_of(temp_dir() + "/missing.png").find("cannot open the file"), std::string::npos);
}

TEST(ImageFile, FailedExrWriteLeavesNothing) {
  const float px[3] = {1, 2, 3};
  EXPECT_THROW(plm::write_exr_atomic(temp_dir() + "/no/such/dir/x.exr", 1, 1, {"R", "G", "B"}, px), plm::Error);
}

}  // namespace

// Lightmaps held by the caller written and read through the C API (plm_write_lightmap_exr,
// plm_read_lightmap_exr): the channels of a baked lightmap's file, rows bottom first, checked
// against an independent OpenEXR reader; bad arguments refused with a message. Heat maps
// (plm_write_heat_map_exr): one value a texel as R = G = B in 16-bit floats.
#include <gtest/gtest.h>
#include <unistd.h>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfInputFile.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "photonlm/photonlm.h"
#include "test_support.h"

namespace {

std::string temp_dir() {
  char tmpl[] = "/tmp/photonlm_lmfile_XXXXXX";
  return mkdtemp(tmpl);
}

TEST(LightmapFile, WritesChannelsBottomRowFirstAndReadsBack) {
  const uint32_t w = 5, h = 3;
  std::vector<float> rgb(3 * w * h), err(w * h), hits(w * h);
  for (size_t t = 0; t < w * h; ++t) {
    for (int c = 0; c < 3; ++c) rgb[3 * t + c] = float(t) + 0.25f * float(c);
    err[t] = 0.5f * float(t);
    hits[t] = float(100 + t);
  }
  const std::string dir = temp_dir(), path = dir + "/page.exr";
  ASSERT_EQ(plm_write_lightmap_exr(path.c_str(), w, h, rgb.data(), err.data(), hits.data()), PLM_OK)
      << plm_last_error();
  const plm_test::ExrChannels exr = plm_test::read_exr_channels(path);
  ASSERT_EQ(exr.width, int(w));
  ASSERT_EQ(exr.height, int(h));
  for (uint32_t y = 0; y < h; ++y)  // file row 0 = top = lightmap row h - 1
    for (uint32_t x = 0; x < w; ++x) {
      const size_t f = size_t(h - 1 - y) * w + x, t = size_t(y) * w + x;
      EXPECT_EQ(exr.channels.at("G")[f], rgb[3 * t + 1]);
      EXPECT_EQ(exr.channels.at("error")[f], err[t]);
      EXPECT_EQ(exr.channels.at("hits")[f], hits[t]);
    }
  uint32_t rw = 0, rh = 0;
  ASSERT_EQ(plm_read_lightmap_exr(path.c_str(), &rw, &rh, nullptr, nullptr, nullptr), PLM_OK);
  EXPECT_EQ(rw, w);
  EXPECT_EQ(rh, h);
  std::vector<float> rgb2(rgb.size()), err2(err.size()), hits2(hits.size());
  ASSERT_EQ(plm_read_lightmap_exr(path.c_str(), &rw, &rh, rgb2.data(), err2.data(), hits2.data()), PLM_OK);
  EXPECT_EQ(rgb2, rgb);
  EXPECT_EQ(err2, err);
  EXPECT_EQ(hits2, hits);
  // Without error and hits the file holds zeros there.
  ASSERT_EQ(plm_write_lightmap_exr(path.c_str(), w, h, rgb.data(), nullptr, nullptr), PLM_OK);
  ASSERT_EQ(plm_read_lightmap_exr(path.c_str(), &rw, &rh, nullptr, err2.data(), hits2.data()), PLM_OK);
  EXPECT_EQ(err2, std::vector<float>(w * h, 0.0f));
  EXPECT_EQ(hits2, std::vector<float>(w * h, 0.0f));
  std::remove(path.c_str());
  rmdir(dir.c_str());
}

TEST(LightmapFile, HeatMapIsOneValueAsRgbOfHalfFloats) {
  const uint32_t w = 6, h = 4;
  std::vector<float> values(w * h);
  for (size_t t = 0; t < values.size(); ++t) values[t] = 0.001f * float(t * t) + 0.0123f;
  const std::string dir = temp_dir(), path = dir + "/floor_error.exr";
  ASSERT_EQ(plm_write_heat_map_exr(path.c_str(), w, h, values.data()), PLM_OK) << plm_last_error();
  {
    Imf::InputFile file(path.c_str());
    const Imf::ChannelList& channels = file.header().channels();
    int count = 0;
    for (auto it = channels.begin(); it != channels.end(); ++it, ++count) EXPECT_EQ(it.channel().type, Imf::HALF);
    EXPECT_EQ(count, 3);
  }
  const plm_test::ExrChannels exr = plm_test::read_exr_channels(path);
  ASSERT_EQ(exr.width, int(w));
  ASSERT_EQ(exr.height, int(h));
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const size_t f = size_t(h - 1 - y) * w + x, t = size_t(y) * w + x;
      EXPECT_NEAR(exr.channels.at("R")[f], values[t], 5e-4 * values[t]);  // 11 bits of mantissa
      EXPECT_EQ(exr.channels.at("G")[f], exr.channels.at("R")[f]);
      EXPECT_EQ(exr.channels.at("B")[f], exr.channels.at("R")[f]);
    }
  EXPECT_EQ(plm_write_heat_map_exr(path.c_str(), 0, h, values.data()), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("0 x 4"), std::string::npos);
  EXPECT_EQ(plm_write_heat_map_exr(path.c_str(), w, h, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("values"), std::string::npos);
  EXPECT_EQ(plm_write_heat_map_exr((dir + "/missing/x.exr").c_str(), w, h, values.data()), PLM_ERROR_IO);
  std::remove(path.c_str());
  rmdir(dir.c_str());
}

TEST(LightmapFile, BadArgumentsAreRefusedWithAMessage) {
  const std::string dir = temp_dir(), path = dir + "/x.exr";
  std::vector<float> rgb(3 * 4 * 4, 1.0f);
  EXPECT_EQ(plm_write_lightmap_exr(nullptr, 4, 4, rgb.data(), nullptr, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("path"), std::string::npos);
  EXPECT_EQ(plm_write_lightmap_exr(path.c_str(), 4, 4, nullptr, nullptr, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_write_lightmap_exr(path.c_str(), 0, 4, rgb.data(), nullptr, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("0 x 4"), std::string::npos);
  EXPECT_EQ(plm_write_lightmap_exr((dir + "/missing/x.exr").c_str(), 4, 4, rgb.data(), nullptr, nullptr),
            PLM_ERROR_IO);
  uint32_t w = 0, h = 0;
  EXPECT_EQ(plm_read_lightmap_exr(path.c_str(), &w, &h, nullptr, nullptr, nullptr), PLM_ERROR_IO);
  EXPECT_NE(std::string(plm_last_error()).find("x.exr"), std::string::npos);
  EXPECT_EQ(plm_read_lightmap_exr(path.c_str(), nullptr, &h, nullptr, nullptr, nullptr),
            PLM_ERROR_INVALID_ARGUMENT);
  ASSERT_EQ(plm_write_lightmap_exr(path.c_str(), 4, 4, rgb.data(), nullptr, nullptr), PLM_OK);
  w = 4, h = 3;  // buffers for another size
  EXPECT_EQ(plm_read_lightmap_exr(path.c_str(), &w, &h, rgb.data(), nullptr, nullptr), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("4 x 4"), std::string::npos);
  std::remove(path.c_str());
  rmdir(dir.c_str());
}

}  // namespace

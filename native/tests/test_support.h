// Helpers shared by the C API tests: a baked result and its lightmaps.
#pragma once

#include <gtest/gtest.h>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "photonlm/photonlm.h"

namespace plm_test {

// A struct for the C API to fill: zeros and its struct_size (photonlm.h "Struct sizes").
template <typename T>
T sized() {
  T t{};
  t.struct_size = uint32_t(sizeof(T));
  return t;
}

struct Map {
  uint32_t w = 0, h = 0;
  std::vector<float> rgb, error, hits, coverage;
  double value(size_t t) const { return (double(rgb[3 * t]) + rgb[3 * t + 1] + rgb[3 * t + 2]) / 3.0; }
};

struct BakeResult {
  plm_result* r = nullptr;
  BakeResult() = default;
  BakeResult(const BakeResult&) = delete;
  BakeResult& operator=(const BakeResult&) = delete;
  ~BakeResult() { plm_result_release(r); }
  Map map(uint32_t mesh) const {
    Map m;
    EXPECT_EQ(plm_result_lightmap_size(r, mesh, &m.w, &m.h), PLM_OK) << plm_last_error();
    const size_t n = size_t(m.w) * m.h;
    m.rgb.resize(3 * n);
    m.error.resize(n);
    m.hits.resize(n);
    m.coverage.resize(n);
    EXPECT_EQ(plm_result_copy_lightmap(r, mesh, m.rgb.data(), m.error.data(), m.hits.data(), m.coverage.data()), PLM_OK)
        << plm_last_error();
    return m;
  }
  plm_bake_stats stats() const {
    plm_bake_stats s = sized<plm_bake_stats>();
    EXPECT_EQ(plm_result_stats(r, &s), PLM_OK);
    return s;
  }
  // The first warning containing needle, or "".
  std::string warning(const char* needle) const {
    for (uint32_t i = 0; i < plm_result_warning_count(r); ++i)
      if (std::strstr(plm_result_warning(r, i), needle)) return plm_result_warning(r, i);
    return "";
  }
  std::string all_warnings() const {
    std::string s;
    for (uint32_t i = 0; i < plm_result_warning_count(r); ++i) s += std::string(plm_result_warning(r, i)) + "\n";
    return s;
  }
};

// A sun of strength `power` (W/m^2) tilted `a` radians from the zenith about
// the x axis: its light travels along (0, sin a, -cos a).
inline plm_light tilted_sun(float power, float a) {
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_SUN);
  l.power = power;
  l.matrix[5] = std::cos(a);
  l.matrix[6] = -std::sin(a);
  l.matrix[9] = std::sin(a);
  l.matrix[10] = std::cos(a);
  return l;
}

// A portal of sx x sy m centred at (x, 0, z), facing down (-Z of its frame).
inline plm_light portal(float sx, float sy, float x, float z) {
  plm_light p;
  plm_light_default(&p, PLM_LIGHT_PORTAL);
  p.size_x = sx;
  p.size_y = sy;
  p.matrix[3] = x;
  p.matrix[11] = z;
  return p;
}

// An open sunlit scene: an 8 x 8 m ground (ground_res texels a side) with a
// 1 x 1 x 1.5 m box on it turned 0.35 rad (a 3 x 2 atlas of 8 x 8 texel
// faces), a sun 45 degrees from the zenith (4 W/m^2) and a sky (0.3, 0.4, 0.6).
template <typename Builder>
void open_scene(Builder& b, bool sun = true, bool sky = true, uint32_t ground_res = 32) {
  const uint32_t ground = b.material("ground", {0.35f, 0.42f, 0.30f});
  const uint32_t white = b.material("box", {0.8f, 0.8f, 0.8f});
  b.quad("ground", {-4, -4, 0}, {8, 0, 0}, {0, 8, 0}, ground, ground_res);
  b.box("box", {0, 0, 0.75f}, {1.0f, 1.0f, 1.5f}, 0.35f, white, 8);
  if (sun) b.light(tilted_sun(4.0f, float(M_PI / 4.0)), "sun");
  if (sky) {
    const float radiance[3] = {0.3f, 0.4f, 0.6f};
    EXPECT_EQ(plm_scene_set_world(b.scene, radiance), PLM_OK);
  }
}

// The engine's default settings with a photon count (the cap with a target) and direct samples.
inline plm_bake_settings settings_with(uint64_t photons, uint32_t direct_samples, uint32_t max_bounces = 1024) {
  plm_bake_settings s;
  plm_bake_settings_default(&s);
  s.photon_count = photons;
  s.direct_samples = direct_samples;
  s.max_bounces = max_bounces;
  return s;
}

// Bakes a scene built with a plm_demo::SceneBuilder (or anything with ok(), error and scene),
// failing the test with the engine's message.
template <typename Builder>
void bake(Builder& b, const plm_bake_settings& s, BakeResult& out) {
  ASSERT_TRUE(b.ok()) << b.error;
  ASSERT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &out.r), PLM_OK) << plm_last_error();
}

// View factor from a floor point to the rectangle [x1, x2] x [y1, y2] one
// unit above it (corner formula, odd in both offsets, summed with signs).
inline double view_factor(double x, double y, double x1, double x2, double y1, double y2) {
  auto corner = [](double a, double b) {
    const double sa = std::sqrt(1.0 + a * a), sb = std::sqrt(1.0 + b * b);
    return (a / sa * std::atan(b / sa) + b / sb * std::atan(a / sb)) / (2.0 * M_PI);
  };
  return corner(x2 - x, y2 - y) - corner(x1 - x, y2 - y) - corner(x2 - x, y1 - y) + corner(x1 - x, y1 - y);
}

// The 8 x 8 texels of the floor [-1, 1]^2 (row by row from y = -1): each one's
// mean view factor (12 x 12 points) to the 1 x 1 m hole centred one unit above it.
inline std::vector<double> hole_view_factors() {
  std::vector<double> out(64);
  const int k = 12;
  for (int j = 0; j < 8; ++j)
    for (int i = 0; i < 8; ++i) {
      double sum = 0.0;
      for (int a = 0; a < k; ++a)
        for (int c = 0; c < k; ++c)
          sum += view_factor(-1.0 + 0.25 * (i + (a + 0.5) / k), -1.0 + 0.25 * (j + (c + 0.5) / k), -0.5, 0.5, -0.5, 0.5);
      out[size_t(j) * 8 + size_t(i)] = sum / (k * k);
    }
  return out;
}

// A latitude-longitude sphere of nu x nv quads around `centre` (u = longitude,
// v = latitude from the -z pole; a lightmap of nu x nv texels, one per quad)
// in `material`: the carrier of a CSG sphere. Returns the mesh id.
inline uint32_t add_latlong_sphere(plm_scene* scene, const char* name, const double centre[3], double radius,
                                   uint32_t nu, uint32_t nv, uint32_t material) {
  std::vector<float> pos, uv;
  std::vector<uint32_t> idx;
  for (uint32_t j = 0; j <= nv; ++j)
    for (uint32_t i = 0; i <= nu; ++i) {
      const double phi = 2 * M_PI * i / nu, theta = M_PI * j / nv;
      pos.insert(pos.end(), {float(centre[0] + radius * std::sin(theta) * std::cos(phi)),
                             float(centre[1] + radius * std::sin(theta) * std::sin(phi)),
                             float(centre[2] - radius * std::cos(theta))});
    }
  for (uint32_t j = 0; j < nv; ++j)
    for (uint32_t i = 0; i < nu; ++i) {
      const uint32_t a = j * (nu + 1) + i, c = a + nu + 1;
      const float u0 = float(i) / nu, u1 = float(i + 1) / nu, v0 = float(j) / nv, v1 = float(j + 1) / nv;
      idx.insert(idx.end(), {a, a + 1, c + 1, a, c + 1, c});
      uv.insert(uv.end(), {u0, v0, u1, v0, u1, v1, u0, v0, u1, v1, u0, v1});
    }
  const uint32_t tris = uint32_t(idx.size() / 3);
  const std::vector<uint32_t> mats(tris, material);
  uint32_t id = 0;
  EXPECT_EQ(plm_scene_add_mesh(scene, name, pos.data(), uint32_t(pos.size() / 3), idx.data(), tris, uv.data(),
                               mats.data(), nu, nv, &id),
            PLM_OK)
      << plm_last_error();
  return id;
}

// Flips bit 4 of the byte at `offset` of a file (a damaged part file, say).
inline void flip_byte(const std::string& path, std::streamoff offset) {
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  f.seekp(offset);
  char c = 0;
  f.read(&c, 1);
  c ^= 0x10;
  f.seekp(offset);
  f.write(&c, 1);
}

// An EXR file's float channels by name, read with the OpenEXR library: each
// width * height floats, the file's top row first.
struct ExrChannels {
  int width = 0, height = 0;
  std::map<std::string, std::vector<float>> channels;
};

inline ExrChannels read_exr_channels(const std::string& path) {
  Imf::InputFile file(path.c_str());
  const Imath::Box2i dw = file.header().dataWindow();
  ExrChannels out;
  out.width = dw.max.x - dw.min.x + 1;
  out.height = dw.max.y - dw.min.y + 1;
  Imf::FrameBuffer fb;
  for (auto it = file.header().channels().begin(); it != file.header().channels().end(); ++it) {
    std::vector<float>& v = out.channels[it.name()];
    v.resize(size_t(out.width) * size_t(out.height));
    fb.insert(it.name(), Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(v.data()), sizeof(float),
                                    sizeof(float) * size_t(out.width)));
  }
  file.setFrameBuffer(fb);
  file.readPixels(dw.min.y, dw.max.y);
  return out;
}

}  // namespace plm_test

#include "transport/plan/memory.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <set>
#include <string>

namespace plm {
namespace {

// Measured with `/usr/bin/time -v photonlm bake` on quads of 1024^2 and 2048^2
// texels under a sun and a sky, wholly and half covered, and meshes of 0.5 M
// triangles: about 225 bytes for every texel of a lightmap (areas, sums,
// estimates, images), 210 more for each covered one (direct and gather sums,
// the direct values and the sky light's fits), 300 per triangle (the mesh,
// Embree's BVH, the hit tables) and 64 MB besides.
constexpr uint64_t kBytesPerTexel = 225, kBytesPerCoveredTexel = 210, kBytesPerTriangle = 300;
constexpr uint64_t kBaseBytes = uint64_t(64) << 20;
// Scenes with specular lobes keep the caustic photons' sums apart (transport/film/film.h):
// 3 + 1 doubles and a count per texel.
constexpr uint64_t kCausticBytesPerTexel = 36;
// Light groups (transport/output/layers.h): per layer, 3 doubles of photon
// flux and, in the images, 4 floats a texel; while a lightmap's layers are
// made, 3 doubles and 4 floats more; 3 floats of direct sums per covered texel.
constexpr uint64_t kLayerBytesPerTexel = 24 + 16 + 40, kLayerBytesPerCoveredTexel = 12;
// Image textures: float RGB for the bake (12 bytes a pixel), and while one is
// read, its pixels as read (up to 4 float channels: 16 bytes).
constexpr uint64_t kBytesPerTexturePixel = 12, kBytesPerReadPixel = 16;

// A number from a "key: value kB" line of a /proc file, in bytes; 0 if absent.
uint64_t proc_field(const char* path, const std::string& key) {
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.compare(0, key.size(), key) != 0) continue;
    unsigned long long kb = 0;
    if (std::sscanf(line.c_str() + key.size(), " %llu", &kb) == 1) return uint64_t(kb) * 1024;
  }
  return 0;
}

// A file holding one number ("max" or absent: 0).
uint64_t file_number(const char* path) {
  std::ifstream in(path);
  unsigned long long v = 0;
  return in >> v ? uint64_t(v) : 0;
}

}  // namespace

MemoryEstimate estimate_bake_memory(const Scene& scene, bool directional) {
  MemoryEstimate e;
  e.bytes = kBaseBytes;
  std::set<std::string> images;
  uint64_t largest_image = 0;
  for (const Material& m : scene.materials) {
    for (int k = 0; k < 2; ++k) {
      const std::string& path = k ? m.emission_texture : m.albedo_texture;
      const uint64_t pixels = k ? m.emission_texture_pixels : m.albedo_texture_pixels;
      if (path.empty() || !images.insert(path).second) continue;
      e.bytes += kBytesPerTexturePixel * pixels;
      largest_image = std::max(largest_image, pixels);
    }
  }
  e.bytes += kBytesPerReadPixel * largest_image;
  // Light groups: the declared ones, and the default group; directional
  // lightmaps' moments cost as much as three layers (transport/context/split.h).
  const uint64_t layers = (scene.light_groups.empty() ? 0 : scene.light_groups.size() + 1) + (directional ? 3 : 0);
  const uint64_t per_texel =
      kBytesPerTexel + (scene.has_lobes() ? kCausticBytesPerTexel : 0) + layers * kLayerBytesPerTexel;
  const uint64_t per_covered = kBytesPerCoveredTexel + layers * kLayerBytesPerCoveredTexel;
  for (size_t i = 0; i < scene.meshes.size(); ++i) {
    const Mesh& m = scene.meshes[i];
    e.bytes += kBytesPerTriangle * m.triangle_count();
    if (!m.has_lightmap()) continue;
    const double texels = double(m.lightmap_width) * double(m.lightmap_height);
    double uv_area = 0.0;  // in units of the UV square
    for (uint32_t t = 0; t < m.triangle_count(); ++t) {
      const float* uv = &m.uv[6 * size_t(t)];
      uv_area += 0.5 * std::fabs(double(uv[2] - uv[0]) * (uv[5] - uv[1]) - double(uv[4] - uv[0]) * (uv[3] - uv[1]));
    }
    // Islands cover a few more texels than their area (their borders): 1.2x.
    const double covered = std::min(texels, 1.2 * uv_area * texels);
    const uint64_t bytes = uint64_t(texels) * per_texel + uint64_t(covered) * per_covered;
    e.bytes += bytes;
    if (bytes > e.largest_bytes) e.largest_bytes = bytes, e.largest_mesh = i;
  }
  return e;
}

uint64_t available_memory() {
  uint64_t free = proc_field("/proc/meminfo", "MemAvailable:");
  const uint64_t limit = file_number("/sys/fs/cgroup/memory.max");  // cgroup v2; "max" reads as 0
  if (limit > 0) {
    const uint64_t used = file_number("/sys/fs/cgroup/memory.current");
    const uint64_t left = limit > used ? limit - used : 0;
    free = free ? std::min(free, left) : left;
  }
  return free;
}

std::string format_bytes(uint64_t bytes) {
  char s[32];
  if (bytes >= (uint64_t(1) << 30)) std::snprintf(s, sizeof s, "%.1f GB", double(bytes) / double(uint64_t(1) << 30));
  else std::snprintf(s, sizeof s, "%.0f MB", double(bytes) / double(uint64_t(1) << 20));
  return s;
}

}  // namespace plm

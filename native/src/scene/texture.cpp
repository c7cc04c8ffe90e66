#include "scene/texture.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "util/error.h"
#include "util/image_file.h"

namespace plm {
namespace {

float srgb_to_linear(float c) {
  return c <= 0.04045f ? c * (1.0f / 12.92f) : std::pow((c + 0.055f) * (1.0f / 1.055f), 2.4f);
}

// One axis of a bilinear lookup: coordinate s on an axis of n pixels whose
// centres lie at (i + 0.5) / n, wrapped periodically. Gives the lower pixel
// i0, the upper one i1 and the weight f of i1; false where s is not finite.
bool wrap_axis(float s, uint32_t n, uint32_t& i0, uint32_t& i1, float& f) {
  const float p = s * float(n) - 0.5f;
  const float below = std::floor(p);
  int64_t k;
  if (std::fabs(below) < 1e18f) {
    k = int64_t(below);
  } else {
    if (!std::isfinite(below)) return false;
    k = int64_t(std::fmod(double(below), double(n)));  // an integer already: no fraction left at this size
  }
  f = p - below;
  if (uint64_t(k) >= n) {
    k %= int64_t(n);
    if (k < 0) k += int64_t(n);
  }
  i0 = uint32_t(k);
  i1 = i0 + 1 == n ? 0 : i0 + 1;
  return true;
}

// Decodes the image at path into texture (all but the mean).
void load_texture(TextureSet::Texture& t, const std::string& path, uint32_t flags, bool clamp,
                  const std::string& owner) {
  const ImageFile img = read_image_file(path, owner, "texture");
  const uint32_t nch = img.channels;
  const bool srgb = flags == PLM_TEXTURE_COLOR_SRGB || (flags == PLM_TEXTURE_COLOR_AUTO && img.integer_bits > 0);
  // Cycles keeps 8-bit sRGB images encoded and decodes after interpolating
  // (a red / green edge blends through a darker colour); deeper images are
  // decoded to linear on load.
  t.decode_after = srgb && img.integer_bits == 8;
  const size_t pixels = size_t(img.width) * size_t(img.height);
  const std::vector<float>& in = img.pixels;

  t.width = img.width;
  t.height = img.height;
  t.rgb.resize(pixels * 3);
  for (size_t p = 0; p < pixels; ++p) {
    for (int c = 0; c < 3; ++c) {
      float v = in[p * size_t(nch) + size_t(nch >= 3 ? c : 0)];  // grey (+ alpha) images: R = G = B
      if (srgb && !t.decode_after) v = srgb_to_linear(v);
      if (!std::isfinite(v) || v < 0.0f) v = 0.0f;
      v = std::min(v, clamp ? 1.0f : 1e30f);
      t.rgb[p * 3 + size_t(c)] = v;
    }
  }
}

// The mean of what lookups return: the pixels' mean, or for images decoded
// after the lookup the mean of decoded bilinear values at 2 x 2 points per pixel.
Vec3 texture_mean(const TextureSet::Texture& t) {
  const size_t pixels = size_t(t.width) * size_t(t.height);
  double sum[3] = {0, 0, 0};
  if (!t.decode_after) {
    for (size_t p = 0; p < pixels; ++p)
      for (int c = 0; c < 3; ++c) sum[c] += t.rgb[p * 3 + size_t(c)];
  } else {
    const int w = int(t.width), h = int(t.height);
    auto at = [&](int x, int y, int c) {
      x = (x % w + w) % w;
      y = (y % h + h) % h;
      return t.rgb[(size_t(y) * size_t(w) + size_t(x)) * 3 + size_t(c)];
    };
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (int sy = 0; sy < 2; ++sy)
          for (int sx = 0; sx < 2; ++sx) {
            // Sample at pixel-space (x + 0.25 + 0.5 sx, y + ...): between pixel centres x0, x0 + 1.
            const float px = float(x) - 0.25f + 0.5f * float(sx), py = float(y) - 0.25f + 0.5f * float(sy);
            const int x0 = int(std::floor(px)), y0 = int(std::floor(py));
            const float fx = px - float(x0), fy = py - float(y0);
            for (int c = 0; c < 3; ++c) {
              const float v = (1 - fy) * ((1 - fx) * at(x0, y0, c) + fx * at(x0 + 1, y0, c)) +
                              fy * ((1 - fx) * at(x0, y0 + 1, c) + fx * at(x0 + 1, y0 + 1, c));
              sum[c] += 0.25 * double(srgb_to_linear(v));
            }
          }
  }
  const double n = double(pixels);
  return {float(sum[0] / n), float(sum[1] / n), float(sum[2] / n)};
}

}  // namespace

uint64_t check_texture_file(const std::string& path, const std::string& owner) {
  uint32_t w = 0, h = 0;
  image_file_size(path, owner, "texture", w, h);
  return uint64_t(w) * uint64_t(h);
}

TextureSet::TextureSet(const Scene& scene) {
  // (path, flags x clamp) -> index into textures_: a file used twice the same way is read once.
  std::map<std::pair<std::string, uint32_t>, int32_t> loaded;
  auto load = [&](const std::string& path, uint32_t flags, bool clamp, const std::string& owner) {
    const auto key = std::make_pair(path, flags * 2 + (clamp ? 1u : 0u));
    const auto found = loaded.find(key);
    if (found != loaded.end()) return found->second;
    Texture t;
    load_texture(t, path, flags, clamp, owner);
    t.mean = texture_mean(t);
    textures_.push_back(std::move(t));
    const int32_t index = int32_t(textures_.size() - 1);
    loaded[key] = index;
    return index;
  };

  albedo_.resize(scene.materials.size());
  emission_.resize(scene.materials.size());
  for (size_t i = 0; i < scene.materials.size(); ++i) {
    const Material& m = scene.materials[i];
    const std::string owner =
        "material '" + (m.name.empty() ? "#" + std::to_string(i) : m.name) + "' (" + std::to_string(i) + ")";
    Slot& a = albedo_[i];
    a.constant = a.flat = m.albedo;
    if (!m.albedo_texture.empty()) {
      a.texture = load(m.albedo_texture, m.albedo_texture_flags, true, owner);
      a.flat = m.albedo * textures_[size_t(a.texture)].mean;
    }
    Slot& e = emission_[i];
    e.constant = e.flat = m.emission;
    if (!m.emission_texture.empty()) {
      e.texture = load(m.emission_texture, m.emission_texture_flags, false, owner);
      e.flat = m.emission * textures_[size_t(e.texture)].mean;
    }
  }
  for (const Mesh& mesh : scene.meshes) {
    if (!mesh.texture_uv.empty() || mesh.material_ids.empty()) continue;
    for (uint32_t id : mesh.material_ids) {
      if (id < albedo_.size() && (albedo_[id].texture >= 0 || emission_[id].texture >= 0)) {
        const std::string& mat = scene.materials[id].name;
        warnings.push_back("mesh '" + mesh.name + "' uses textured material '" +
                           (mat.empty() ? "#" + std::to_string(id) : mat) +
                           "' but has no texture UVs: the texture's mean colour is used");
        break;
      }
    }
  }
}

TextureSet::~TextureSet() = default;

Vec3 TextureSet::sample(const Texture& t, float u, float v) {
  uint32_t x0, x1, y0, y1;
  float fx, fy;
  // Row 0 is the image's top row and Blender's v = 0 its bottom: the row coordinate is 1 - v.
  if (!wrap_axis(u, t.width, x0, x1, fx) || !wrap_axis(1.0f - v, t.height, y0, y1, fy)) return t.mean;
  const float* row0 = t.rgb.data() + size_t(y0) * size_t(t.width) * 3;
  const float* row1 = t.rgb.data() + size_t(y1) * size_t(t.width) * 3;
  const float* a = row0 + size_t(x0) * 3;
  const float* b = row0 + size_t(x1) * 3;
  const float* c = row1 + size_t(x0) * 3;
  const float* d = row1 + size_t(x1) * 3;
  const float gx = 1.0f - fx, gy = 1.0f - fy;
  float rgb[3];
  for (int k = 0; k < 3; ++k) rgb[k] = gy * (gx * a[k] + fx * b[k]) + fy * (gx * c[k] + fx * d[k]);
  if (t.decode_after) return {srgb_to_linear(rgb[0]), srgb_to_linear(rgb[1]), srgb_to_linear(rgb[2])};
  return {rgb[0], rgb[1], rgb[2]};
}

Vec3 TextureSet::lookup(int32_t texture, const Mesh& mesh, uint32_t tri, float bu, float bv) const {
  const float bw = 1.0f - bu - bv;
  const float* uv = &mesh.texture_uv[6 * size_t(tri)];
  return sample(textures_[size_t(texture)], bw * uv[0] + bu * uv[2] + bv * uv[4],
                bw * uv[1] + bu * uv[3] + bv * uv[5]);
}

Vec3 TextureSet::triangle_emission(const Mesh& mesh, uint32_t material, uint32_t tri) const {
  const Slot& s = emission_[material];
  if (s.texture < 0) return s.constant;
  if (mesh.texture_uv.empty()) return s.flat;
  // The mean over k^2 equal-area sub-triangles' centroids, k ~ the
  // triangle's size in texels (1..32).
  const Texture& t = textures_[size_t(s.texture)];
  const float* uv = &mesh.texture_uv[6 * size_t(tri)];
  const float du1 = (uv[2] - uv[0]) * float(t.width), dv1 = (uv[3] - uv[1]) * float(t.height);
  const float du2 = (uv[4] - uv[0]) * float(t.width), dv2 = (uv[5] - uv[1]) * float(t.height);
  const float texels = 0.5f * std::fabs(du1 * dv2 - du2 * dv1);
  const float capped = texels < 4096.0f ? texels : 4096.0f;  // also where huge UVs made it NaN
  const int k = std::clamp(int(std::ceil(std::sqrt(capped))), 1, 32);
  Vec3 sum{0, 0, 0};
  const float inv = 1.0f / float(k);
  for (int i = 0; i < k; ++i) {
    for (int j = 0; j < k - i; ++j) {
      sum += lookup(s.texture, mesh, tri, (float(i) + 1.0f / 3.0f) * inv, (float(j) + 1.0f / 3.0f) * inv);
      if (j < k - i - 1)
        sum += lookup(s.texture, mesh, tri, (float(i) + 2.0f / 3.0f) * inv, (float(j) + 2.0f / 3.0f) * inv);
    }
  }
  return s.constant * (sum / float(k * k));
}

}  // namespace plm

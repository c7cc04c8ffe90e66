#include "texture/texture.h"

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/texture.h>
#include <tbb/enumerable_thread_specific.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <map>
#include <utility>

#include "util/error.h"

namespace plm {
namespace {

namespace fs = std::filesystem;

float srgb_to_linear(float c) {
  return c <= 0.04045f ? c * (1.0f / 12.92f) : std::pow((c + 0.055f) * (1.0f / 1.055f), 2.4f);
}

// A fresh private directory under the system's temporary directory.
fs::path make_temp_dir() {
  static std::atomic<uint64_t> counter{0};
  std::error_code ec;
  const fs::path base = fs::temp_directory_path(ec);
  if (ec) fail(PLM_ERROR_IO, "textures: no temporary directory: ", ec.message());
  for (int attempt = 0; attempt < 100; ++attempt) {
    const fs::path dir = base / ("photonlm-tex-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    if (fs::create_directory(dir, ec)) return dir;
  }
  fail(PLM_ERROR_IO, "textures: cannot create a temporary directory in ", base.string(), ": ", ec.message());
}

}  // namespace

void check_texture_file(const std::string& path, const std::string& owner) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    std::string why = OIIO::geterror();
    if (why.empty()) why = "not a readable image";
    fail(PLM_ERROR_IO, owner, ": cannot read texture '", path, "': ", why);
  }
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0)
    fail(PLM_ERROR_IO, owner, ": texture '", path, "' has no pixels");
}

struct TextureSet::Texture {
  OIIO::TextureSystem::TextureHandle* handle = nullptr;
  Vec3 mean;
  uint32_t width = 0, height = 0;
  bool decode_after = false;  // 8-bit sRGB: filtered encoded, decoded after the lookup (as Cycles does)
};

struct TextureSet::Impl {
  OIIO::TextureSystem* ts = nullptr;
  fs::path dir;
  std::vector<std::unique_ptr<Texture>> storage;
  std::map<std::pair<std::string, uint32_t>, int32_t> loaded;  // (path, flags x clamp) -> index
  OIIO::TextureOpt opt;
  // Our own per-thread lookup state, created on a thread's first use and
  // destroyed with the set (OIIO's implicit per-thread state could outlive a
  // TextureSystem and be picked up by the next one at the same address).
  tbb::enumerable_thread_specific<OIIO::TextureSystem::Perthread*> threads{nullptr};

  ~Impl() {
    if (ts) {
      for (OIIO::TextureSystem::Perthread* p : threads)
        if (p) ts->destroy_thread_info(p);
      OIIO::TextureSystem::destroy(ts, true);
    }
    std::error_code ec;
    if (!dir.empty()) fs::remove_all(dir, ec);
  }
};

TextureSet::TextureSet(const Scene& scene) : impl_(std::make_unique<Impl>()) {
  impl_->ts = OIIO::TextureSystem::create(false);
  if (!impl_->ts) fail(PLM_ERROR_INTERNAL, "textures: OpenImageIO could not create a TextureSystem");
  impl_->ts->attribute("max_memory_MB", 1024.0f);
  impl_->dir = make_temp_dir();
  OIIO::TextureOpt& opt = impl_->opt;
  opt.swrap = opt.twrap = OIIO::TextureOpt::WrapPeriodic;
  opt.interpmode = OIIO::TextureOpt::InterpBilinear;
  opt.mipmode = OIIO::TextureOpt::MipModeNoMIP;

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
      a.flat = m.albedo * textures_[size_t(a.texture)]->mean;
    }
    Slot& e = emission_[i];
    e.constant = e.flat = m.emission;
    if (!m.emission_texture.empty()) {
      e.texture = load(m.emission_texture, m.emission_texture_flags, false, owner);
      e.flat = m.emission * textures_[size_t(e.texture)]->mean;
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

int32_t TextureSet::load(const std::string& path, uint32_t flags, bool clamp, const std::string& owner) {
  const auto key = std::make_pair(path, flags * 2 + (clamp ? 1u : 0u));
  const auto found = impl_->loaded.find(key);
  if (found != impl_->loaded.end()) return found->second;

  // Read directly (not through OIIO's shared ImageCache: no process-wide state).
  auto input = OIIO::ImageInput::open(path);
  if (!input) fail(PLM_ERROR_IO, owner, ": cannot read texture '", path, "': ", OIIO::geterror());
  const OIIO::ImageSpec native = input->spec();
  const int w = native.width, h = native.height, nch = native.nchannels;
  if (w <= 0 || h <= 0 || nch <= 0) fail(PLM_ERROR_IO, owner, ": texture '", path, "' has no pixels");
  if (double(w) * double(h) > double(1u << 28))
    fail(PLM_ERROR_IO, owner, ": texture '", path, "' is ", w, " x ", h, " pixels, more than 2^28");
  const bool srgb = flags == PLM_TEXTURE_COLOR_SRGB ||
                    (flags == PLM_TEXTURE_COLOR_AUTO && !native.format.is_floating_point());
  // Cycles keeps 8-bit sRGB images encoded and decodes after interpolating
  // (a red / green edge blends through a darker colour); deeper images are
  // decoded to linear on load.
  const bool decode_after = srgb && native.format == OIIO::TypeDesc::UINT8;
  std::vector<float> in(size_t(w) * size_t(h) * size_t(nch));
  if (!input->read_image(0, 0, 0, nch, OIIO::TypeDesc::FLOAT, in.data()))
    fail(PLM_ERROR_IO, owner, ": cannot read texture '", path, "': ", input->geterror());
  input->close();

  OIIO::ImageSpec spec(w, h, 3, OIIO::TypeDesc::FLOAT);
  std::vector<float> rgb(size_t(w) * size_t(h) * 3);
  double sum[3] = {0, 0, 0};
  for (size_t p = 0; p < size_t(w) * size_t(h); ++p) {
    for (int c = 0; c < 3; ++c) {
      float v = in[p * size_t(nch) + size_t(nch >= 3 ? c : 0)];  // grey (+ alpha) images: R = G = B
      if (srgb && !decode_after) v = srgb_to_linear(v);
      if (!std::isfinite(v) || v < 0.0f) v = 0.0f;
      if (clamp) v = std::min(v, 1.0f);
      if (!clamp) v = std::min(v, 1e30f);
      rgb[p * 3 + size_t(c)] = v;
      sum[c] += v;
    }
  }
  if (decode_after) {
    // The mean of what lookups return: decoded bilinear values at 2 x 2 points per pixel.
    sum[0] = sum[1] = sum[2] = 0.0;
    auto at = [&](int x, int y, int c) {
      x = (x % w + w) % w;
      y = (y % h + h) % h;
      return rgb[(size_t(y) * size_t(w) + size_t(x)) * 3 + size_t(c)];
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
  OIIO::ImageBuf linear(spec, rgb.data());
  const fs::path out = impl_->dir / (std::to_string(impl_->storage.size()) + ".exr");
  OIIO::ImageSpec config;
  config.attribute("wrapmodes", "periodic");
  config.set_format(OIIO::TypeDesc::FLOAT);
  if (!OIIO::ImageBufAlgo::make_texture(OIIO::ImageBufAlgo::MakeTxTexture, linear, out.string(), config))
    fail(PLM_ERROR_IO, owner, ": cannot prepare texture '", path, "': ", OIIO::geterror());

  auto t = std::make_unique<Texture>();
  t->handle = impl_->ts->get_texture_handle(OIIO::ustring(out.string()));
  if (!t->handle) fail(PLM_ERROR_IO, owner, ": cannot open texture '", path, "': ", impl_->ts->geterror());
  const double n = double(w) * double(h);
  t->mean = {float(sum[0] / n), float(sum[1] / n), float(sum[2] / n)};
  t->width = uint32_t(w);
  t->height = uint32_t(h);
  t->decode_after = decode_after;
  textures_.push_back(t.get());
  impl_->storage.push_back(std::move(t));
  const int32_t index = int32_t(textures_.size() - 1);
  impl_->loaded[key] = index;
  return index;
}

void* TextureSet::thread_info() const {
  OIIO::TextureSystem::Perthread*& p = impl_->threads.local();
  if (!p) p = impl_->ts->create_thread_info();
  return p;
}

Vec3 TextureSet::lookup_st(int32_t texture, float u, float v, void* thread) const {
  OIIO::TextureOpt opt = impl_->opt;  // a stack copy: texture() takes it by reference
  float rgb[3] = {0, 0, 0};
  // Blender's v = 0 is the image's bottom row; OIIO's t = 0 its top.
  if (!impl_->ts->texture(textures_[size_t(texture)]->handle, static_cast<OIIO::TextureSystem::Perthread*>(thread),
                          opt, u, 1.0f - v, 0.0f, 0.0f, 0.0f, 0.0f, 3, rgb))
    return textures_[size_t(texture)]->mean;
  if (textures_[size_t(texture)]->decode_after)
    return {srgb_to_linear(rgb[0]), srgb_to_linear(rgb[1]), srgb_to_linear(rgb[2])};
  return {rgb[0], rgb[1], rgb[2]};
}

Vec3 TextureSet::lookup(int32_t texture, const Mesh& mesh, uint32_t tri, float bu, float bv, void* thread) const {
  const float bw = 1.0f - bu - bv;
  const float* uv = &mesh.texture_uv[6 * size_t(tri)];
  return lookup_st(texture, bw * uv[0] + bu * uv[2] + bv * uv[4], bw * uv[1] + bu * uv[3] + bv * uv[5], thread);
}

Vec3 TextureSet::triangle_emission(const Mesh& mesh, uint32_t material, uint32_t tri, void* thread) const {
  const Slot& s = emission_[material];
  if (s.texture < 0) return s.constant;
  if (mesh.texture_uv.empty()) return s.flat;
  // The mean over k^2 equal-area sub-triangles' centroids, k ~ the
  // triangle's size in texels (1..32).
  const Texture& t = *textures_[size_t(s.texture)];
  const float* uv = &mesh.texture_uv[6 * size_t(tri)];
  const float du1 = (uv[2] - uv[0]) * float(t.width), dv1 = (uv[3] - uv[1]) * float(t.height);
  const float du2 = (uv[4] - uv[0]) * float(t.width), dv2 = (uv[5] - uv[1]) * float(t.height);
  const float texels = 0.5f * std::fabs(du1 * dv2 - du2 * dv1);
  const int k = std::clamp(int(std::ceil(std::sqrt(std::min(texels, 4096.0f)))), 1, 32);
  Vec3 sum{0, 0, 0};
  const float inv = 1.0f / float(k);
  for (int i = 0; i < k; ++i) {
    for (int j = 0; j < k - i; ++j) {
      sum += lookup(s.texture, mesh, tri, (float(i) + 1.0f / 3.0f) * inv, (float(j) + 1.0f / 3.0f) * inv, thread);
      if (j < k - i - 1)
        sum += lookup(s.texture, mesh, tri, (float(i) + 2.0f / 3.0f) * inv, (float(j) + 2.0f / 3.0f) * inv, thread);
    }
  }
  return s.constant * (sum / float(k * k));
}

}  // namespace plm

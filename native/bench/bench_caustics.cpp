// Caustic density estimation compared (docs/benchmarks/engine.md "Caustics"): the
// engine's per-texel deposit with its reconstruction (pooling radius chosen
// by estimated error, lightmap/reconstruct.h) against a k-nearest-photon
// estimate on a uniform grid [Purcell03] at each texel's centre, on the same
// caustic photons. Two receivers: a floor under a glass ball focusing the sun
// (reference: the per-texel deposit of many more photons, no pooling) and a
// wall lit by a mirror's sun patch (reference: exact, the patch's value times
// each texel's share of it). Prints error against photons and seconds.
//
//   ./build/bin/photonlm_bench_caustics [--max-photons 16000000] [--ref-photons 256000000] [--threads N]
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <queue>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include "accel/embree_scene.h"
#include "api/handles.h"
#include "demo_scenes.h"
#include "lightmap/reconstruct.h"
#include "transport/context/bake_scene.h"
#include "transport/film/film.h"
#include "transport/lights/emitters.h"
#include "transport/materials/bsdf.h"
#include "transport/materials/material_table.h"
#include "transport/output/ol_film.h"
#include "transport/photons/photon_sampler.h"
#include "transport/photons/photon_tracer.h"

namespace {

using namespace plm;
using Clock = std::chrono::steady_clock;
constexpr double kPiB = 3.14159265358979323846;

double seconds(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

plm_light sun_along(plm_demo::V3 d, float e) {
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_SUN);
  l.power = e;
  l.angle = 0.0f;
  const Vec3 z = -normalize(Vec3{d.x, d.y, d.z});
  Vec3 x, y;
  make_frame(z, x, y);
  for (int r = 0; r < 3; ++r) {
    l.matrix[4 * r + 0] = x[r];
    l.matrix[4 * r + 1] = y[r];
    l.matrix[4 * r + 2] = z[r];
    l.matrix[4 * r + 3] = 0.0f;
  }
  return l;
}

void glass_lobe(plm_scene* s, uint32_t m, plm_lobe_type type, plm_demo::V3 c, float ior) {
  plm_lobe l;
  plm_lobe_default(&l, type);
  l.color[0] = c.x, l.color[1] = c.y, l.color[2] = c.z;
  l.ior = ior;
  if (plm_scene_add_material_lobe(s, m, &l) != PLM_OK) std::fprintf(stderr, "%s\n", plm_last_error()), std::exit(1);
}

// A glass ball (radius 0.3 m, centre 0.6 m up, smooth UV sphere) over a black
// 2 x 2 m floor of 64 x 64 texels, the sun straight above.
void build_ball(plm_demo::SceneBuilder& b) {
  const uint32_t floor = b.material("floor", {0, 0, 0});
  const uint32_t glass = b.material("glass", {0, 0, 0});
  glass_lobe(b.scene, glass, PLM_LOBE_GLASS, {1, 1, 1}, 1.5f);
  b.quad("floor", {-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, floor, 64);
  const int rings = 48, segments = 96;
  const float r = 0.3f, cz = 0.6f;
  std::vector<float> pos;
  std::vector<uint32_t> idx;
  for (int i = 0; i <= rings; ++i)
    for (int j = 0; j <= segments; ++j) {
      const double th = kPiB * i / rings, ph = 2.0 * kPiB * j / segments;
      pos.insert(pos.end(), {r * float(std::sin(th) * std::cos(ph)), r * float(std::sin(th) * std::sin(ph)),
                             cz + r * float(std::cos(th))});
    }
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const uint32_t a = uint32_t(i * (segments + 1) + j), c = a + uint32_t(segments + 1);
      if (i > 0) idx.insert(idx.end(), {a, c, a + 1});
      if (i < rings - 1) idx.insert(idx.end(), {a + 1, c, c + 1});
    }
  std::vector<uint32_t> mats(idx.size() / 3, glass);
  uint32_t id = 0;
  plm_scene_add_mesh(b.scene, "ball", pos.data(), uint32_t(pos.size() / 3), idx.data(), uint32_t(idx.size() / 3),
                     nullptr, mats.data(), 0, 0, &id);
  plm_scene_set_mesh_smooth(b.scene, id, 1);
  b.light(sun_along({0, 0, -1}, 1.0f), "sun");
}

// The mirror's sun patch: a 1 x 1 m mirror (FRESNEL, F0 0.9) on the ground,
// the sun at 45 degrees, a black wall 3 x 3 m (48 x 48 texels) at x = 2
// whose patch, z in [1.5, 2.5], y in [-0.5, 0.5], falls across texel edges
// (the wall starts at z = 0.52, y = 1.49).
constexpr float kWallZ0 = 0.52f, kWallY0 = 1.49f, kWallSide = 3.0f;
void build_mirror(plm_demo::SceneBuilder& b) {
  const uint32_t black = b.material("black", {0, 0, 0});
  const uint32_t metal = b.material("metal", {0, 0, 0});
  glass_lobe(b.scene, metal, PLM_LOBE_FRESNEL, {0.9f, 0.9f, 0.9f}, 1.5f);
  b.quad("wall", {2, kWallY0, kWallZ0}, {0, -kWallSide, 0}, {0, 0, kWallSide}, black, 48);
  b.quad("mirror", {-0.5f, -0.5f, 0}, {1, 0, 0}, {0, 1, 0}, metal, 0);
  b.light(sun_along({std::sqrt(0.5f), 0, -std::sqrt(0.5f)}, 1.0f), "sun");
}

// The exact caustic on the mirror's wall: E R(45) cos 45 / pi over the
// patch, times each texel's share of the patch.
std::vector<double> mirror_reference(uint32_t res) {
  const double c = std::sqrt(0.5);
  const double F0 = bsdf::fresnel_dielectric(1.0f, 1.5f), fh = (bsdf::fresnel_dielectric(float(c), 1.5f) - F0) / (1 - F0);
  const double value = c * (0.9 * (1 - fh) + fh) / kPiB;
  std::vector<double> ref(size_t(res) * res);
  const double side = kWallSide / res;
  for (uint32_t j = 0; j < res; ++j)
    for (uint32_t i = 0; i < res; ++i) {
      const double y1 = kWallY0 - i * side, y0 = y1 - side;  // u runs along -y
      const double z0 = kWallZ0 + j * side, z1 = z0 + side;
      const double oy = std::max(0.0, std::min(y1, 0.5) - std::max(y0, -0.5));
      const double oz = std::max(0.0, std::min(z1, 2.5) - std::max(z0, 1.5));
      ref[size_t(j) * res + i] = value * oy * oz / (side * side);
    }
  return ref;
}

// What the bake sets up, for tracing photons by hand.
struct Setup {
  const Scene& scene;
  std::vector<std::string> warnings;
  std::unique_ptr<BakeScene> ctx;
  OlGroups ols;
  const TexelSpace& space;
  Setup(const Scene& s, unsigned threads)
      : scene(s), ctx(std::make_unique<BakeScene>(s, BakeSettings{}, threads)), space(ctx->space) {
    ctx->accel = std::make_unique<EmbreeScene>(s, threads);
    ctx->rtc = ctx->accel->handle();
    ctx->space = build_texel_space(s, warnings);
    ols = build_ol_groups(s, warnings);
    ctx->ol_views = ols.views;
    const Vec3 lo = ctx->accel->bounds_min(), hi = ctx->accel->bounds_max();
    ctx->extent = length(hi - lo);
    ctx->emitters = build_emitters(s, (lo + hi) * 0.5f, 0.5f * ctx->extent * 1.01f);
    ctx->lobes = MaterialTable(s);
    ctx->caustics = ctx->lobes.any_lobes();
  }
};

struct Traced {
  std::vector<double> sum, sq;  // per texel of the receiver: caustic flux (3) and squared mean flux
  std::vector<uint32_t> hits;
  double total_sq = 0.0;
  uint64_t total_hits = 0;
  std::vector<CausticPoint> points;
  double seconds = 0.0;
};

// Traces `photons` photons (seed), keeping the receiver's caustic sums and, with points, the hits' points.
Traced trace(Setup& st, uint32_t receiver, uint64_t photons, uint32_t seed, bool points, tbb::task_arena& arena) {
  BakeSettings& settings = st.ctx->settings;
  settings.seed = seed;
  settings.photon_count = photons;
  settings.decide(st.scene);
  PhotonTracer tracer(*st.ctx);
  tracer.keep_caustic_points(points);
  const MeshView& v = st.space.views[receiver];
  const size_t n = size_t(v.mesh->lightmap_width) * v.mesh->lightmap_height;
  Traced out;
  out.sum.assign(3 * n, 0.0);
  out.sq.assign(n, 0.0);
  out.hits.assign(n, 0);
  const uint64_t batches = (photons + kBatchPhotons - 1) / kBatchPhotons;
  constexpr uint64_t kGroup = 64;
  std::vector<BatchOutput> bo(kGroup);
  const auto t0 = Clock::now();
  for (uint64_t g = 0; g < batches; g += kGroup) {
    const uint64_t count = std::min(kGroup, batches - g);
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<uint64_t>(0, count, 1), [&](const tbb::blocked_range<uint64_t>& r) {
        for (uint64_t b = r.begin(); b < r.end(); ++b) {
          const uint64_t p0 = (g + b) * kBatchPhotons;
          tracer.trace_batch(p0, std::min<uint64_t>(kBatchPhotons, photons - p0), bo[b]);
        }
      });
    });
    for (uint64_t b = 0; b < count; ++b) {
      for (const Hit& h : bo[b].caustic_hits) {
        if (h.texel < v.texel_offset || h.texel >= v.texel_offset + n) continue;
        const size_t t = h.texel - v.texel_offset;
        out.sum[3 * t] += h.r, out.sum[3 * t + 1] += h.g, out.sum[3 * t + 2] += h.b;
        const double a = (double(h.r) + h.g + h.b) / 3.0;
        out.sq[t] += a * a;
        out.total_sq += a * a;
        ++out.hits[t];
        ++out.total_hits;
      }
      for (const CausticPoint& p : bo[b].caustic_points)
        if (p.mesh == receiver) out.points.push_back(p);
    }
  }
  out.seconds = seconds(t0);
  return out;
}

// The engine's estimate of the caustic: the texel deposit, pooled with the
// radius of least estimated error (up to max_radius).
std::vector<double> texel_estimate(const Setup& st, uint32_t receiver, const Traced& tr, uint64_t photons,
                                   uint32_t max_radius, uint32_t* radius) {
  const Mesh& m = *st.space.views[receiver].mesh;
  ReconstructParams p;
  p.max_radius = max_radius;
  p.photons = double(photons);
  p.phantom_sq = tr.total_hits ? tr.total_sq / double(tr.total_hits) : 0.0;
  std::vector<double> value3, mse, out(tr.hits.size());
  const uint32_t r = reconstruct_indirect(st.space.areas[receiver], m.lightmap_width, m.lightmap_height,
                                          {tr.sum.data(), tr.sq.data(), tr.hits.data()}, p, value3, mse);
  if (radius) *radius = r;
  for (size_t t = 0; t < out.size(); ++t) out[t] = (value3[3 * t] + value3[3 * t + 1] + value3[3 * t + 2]) / 3.0;
  return out;
}

// A uniform grid of photon points [Purcell03] and the k nearest to a point.
class PhotonGrid {
 public:
  PhotonGrid(const std::vector<CausticPoint>& pts, float cell) : pts_(pts), cell_(cell) {
    for (uint32_t i = 0; i < pts.size(); ++i) cells_[key(cell_of(pts[i].point))].push_back(i);
  }
  // Irradiance / pi at p from the k nearest points: their flux / (pi r_k^2) / pi / photons.
  double estimate(Vec3 p, size_t k, double photons) const {
    std::priority_queue<std::pair<float, uint32_t>> heap;  // largest distance on top
    const auto c = cell_of(p);
    for (int ring = 0; ring < 64; ++ring) {
      for (int dz = -ring; dz <= ring; ++dz)
        for (int dy = -ring; dy <= ring; ++dy)
          for (int dx = -ring; dx <= ring; ++dx) {
            if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != ring) continue;
            const auto it = cells_.find(key({c[0] + dx, c[1] + dy, c[2] + dz}));
            if (it == cells_.end()) continue;
            for (const uint32_t i : it->second) {
              const Vec3 d = pts_[i].point - p;
              const float d2 = dot(d, d);
              if (heap.size() < k) heap.push({d2, i});
              else if (d2 < heap.top().first) heap.pop(), heap.push({d2, i});
            }
          }
      // Every point beyond this ring is at least ring * cell away.
      if (heap.size() == k && heap.top().first <= float(ring) * cell_ * float(ring) * cell_) break;
    }
    if (heap.empty()) return 0.0;
    const double r2 = heap.top().first;
    double flux = 0.0;
    for (; !heap.empty(); heap.pop()) {
      const CausticPoint& q = pts_[heap.top().second];
      flux += (double(q.r) + q.g + q.b) / 3.0;
    }
    return r2 > 0.0 ? flux / (kPiB * r2) / kPiB / photons : 0.0;
  }

 private:
  std::array<int, 3> cell_of(Vec3 p) const {
    return {int(std::floor(p.x / cell_)), int(std::floor(p.y / cell_)), int(std::floor(p.z / cell_))};
  }
  static uint64_t key(std::array<int, 3> c) {
    return (uint64_t(uint32_t(c[0]) & 0x1FFFFF) << 42) | (uint64_t(uint32_t(c[1]) & 0x1FFFFF) << 21) |
           uint64_t(uint32_t(c[2]) & 0x1FFFFF);
  }
  const std::vector<CausticPoint>& pts_;
  float cell_;
  std::unordered_map<uint64_t, std::vector<uint32_t>> cells_;
};

std::vector<double> knn_estimate(const Setup& st, uint32_t receiver, const Traced& tr, uint64_t photons, size_t k,
                                 tbb::task_arena& arena) {
  const TexelAreas& a = st.space.areas[receiver];
  double area = 0.0, cover = 0.0;
  for (size_t t = 0; t < a.area.size(); ++t) area += a.area[t], cover += a.coverage[t];
  const PhotonGrid grid(tr.points, float(std::sqrt(area / cover)));
  std::vector<double> out(a.area.size(), 0.0);
  arena.execute([&] {
    tbb::parallel_for(size_t(0), out.size(), [&](size_t t) {
      if (a.area[t] > 0.0) out[t] = grid.estimate(a.position[t], k, double(photons));
    });
  });
  return out;
}

// RMS of (estimate - reference) over covered texels, relative to the reference's mean over its lit texels.
double rms_error(const Setup& st, uint32_t receiver, const std::vector<double>& est, const std::vector<double>& ref) {
  const TexelAreas& a = st.space.areas[receiver];
  double se = 0.0, n = 0.0, lit = 0.0, nl = 0.0;
  for (size_t t = 0; t < est.size(); ++t) {
    if (!(a.area[t] > 0.0)) continue;
    se += (est[t] - ref[t]) * (est[t] - ref[t]);
    n += 1.0;
    if (ref[t] > 0.0) lit += ref[t], nl += 1.0;
  }
  return std::sqrt(se / n) / (lit / nl);
}

}  // namespace

int main(int argc, char** argv) {
  uint64_t max_photons = 16000000, ref_photons = 256000000;
  unsigned threads = 0;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--max-photons")) max_photons = std::strtoull(argv[i + 1], nullptr, 10);
    else if (!std::strcmp(argv[i], "--ref-photons")) ref_photons = std::strtoull(argv[i + 1], nullptr, 10);
    else if (!std::strcmp(argv[i], "--threads")) threads = unsigned(std::atoi(argv[i + 1]));
  }
  if (!threads) threads = std::max(1u, std::thread::hardware_concurrency());
  tbb::task_arena arena{int(threads)};
  for (int scene_case = 0; scene_case < 2; ++scene_case) {
    plm_demo::SceneBuilder b;
    const char* name = scene_case == 0 ? "glass ball, floor" : "mirror sun patch, wall";
    if (scene_case == 0) build_ball(b);
    else build_mirror(b);
    if (!b.ok()) return std::fprintf(stderr, "%s\n", b.error.c_str()), 1;
    Setup st(b.scene->scene, threads);
    const uint32_t receiver = 0;
    std::vector<double> ref;
    if (scene_case == 0) {
      const Traced r = trace(st, receiver, ref_photons, 1000, false, arena);
      ref = texel_estimate(st, receiver, r, ref_photons, 0, nullptr);
      std::printf("%s: reference %llu photons in %.1f s\n", name, (unsigned long long)ref_photons, r.seconds);
    } else {
      ref = mirror_reference(st.space.views[receiver].mesh->lightmap_width);
      std::printf("%s: exact reference\n", name);
    }
    std::printf("%-10s %-16s %8s %8s %8s\n", "photons", "estimate", "trace s", "est. s", "error %");
    for (uint64_t n = 250000; n <= max_photons; n *= 4) {
      const Traced tr = trace(st, receiver, n, 7, true, arena);
      for (uint32_t r_max : {0u, 2u, 4u}) {
        uint32_t radius = 0;
        const auto t0 = Clock::now();
        const std::vector<double> est = texel_estimate(st, receiver, tr, n, r_max, &radius);
        const double s = seconds(t0);
        char label[64];
        std::snprintf(label, sizeof label, "texel r<=%u (%u)", r_max, radius);
        std::printf("%-10llu %-16s %8.3f %8.4f %8.2f\n", (unsigned long long)n, label, tr.seconds, s,
                    100.0 * rms_error(st, receiver, est, ref));
      }
      for (size_t k : {8u, 32u, 128u}) {
        const auto t0 = Clock::now();
        const std::vector<double> est = knn_estimate(st, receiver, tr, n, k, arena);
        const double s = seconds(t0);
        char label[64];
        std::snprintf(label, sizeof label, "kNN k=%zu", k);
        std::printf("%-10llu %-16s %8.3f %8.4f %8.2f\n", (unsigned long long)n, label, tr.seconds, s,
                    100.0 * rms_error(st, receiver, est, ref));
      }
    }
  }
  return 0;
}

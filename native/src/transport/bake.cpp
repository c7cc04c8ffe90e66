#include "transport/bake.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <thread>

#include "accel/embree_scene.h"
#include "lightmap/dilate.h"
#include "lightmap/texel_area.h"
#include "transport/emitters.h"
#include "util/error.h"
#include "util/rng.h"

namespace plm {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Photons are traced in fixed batches; a batch's hits are merged in batch
// order, so sums are identical whatever the thread count.
constexpr uint32_t kBatchPhotons = 4096;

struct Hit {
  uint32_t texel;  // global texel index over all lightmaps
  float r, g, b;
};

struct BatchOutput {
  std::vector<Hit> hits;
  uint64_t rays = 0;
  uint64_t truncated = 0;
  double truncated_flux = 0.0;
};

// Read-only data the hot loop needs, flattened at set-up.
struct MeshView {
  const Mesh* mesh;
  uint64_t texel_offset;     // into the global texel arrays
  const double* texel_area;  // world area per texel, null without lightmap
};

struct TraceContext {
  RTCIntersectContext context;  // first member: Embree hands back this pointer
  unsigned skip_geom = RTC_INVALID_GEOMETRY_ID;
  unsigned skip_prim = RTC_INVALID_GEOMETRY_ID;
};

// A ray never hits the flat triangle it leaves: rejecting that one triangle
// removes self-intersection at any angle, so the origin offset can stay tiny.
void skip_origin_triangle(const RTCFilterFunctionNArguments* args) {
  const auto* tc = reinterpret_cast<const TraceContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    if (RTCHitN_geomID(args->hit, args->N, i) == tc->skip_geom &&
        RTCHitN_primID(args->hit, args->N, i) == tc->skip_prim)
      args->valid[i] = 0;
  }
}

class Tracer {
 public:
  Tracer(const Scene& scene, RTCScene rtc, const std::vector<MeshView>& views, const std::vector<Emitter>& emitters,
         const plm_bake_settings& settings, float scene_extent)
      : scene_(scene), rtc_(rtc), views_(views), emitters_(emitters), settings_(settings),
        offset_scale_(1e-6f * scene_extent) {
    double total = 0.0;
    for (const Emitter& e : emitters) total += average(e.flux);
    cdf_.reserve(emitters.size());
    pick_.reserve(emitters.size());
    double running = 0.0;
    for (const Emitter& e : emitters) {
      running += average(e.flux);
      cdf_.push_back(running / total);
      pick_.push_back(float(average(e.flux) / total));
    }
    cdf_.back() = 1.0;
    default_material_.albedo = {0.8f, 0.8f, 0.8f};
  }

  void trace_batch(uint64_t first, uint64_t count, BatchOutput& out) const {
    out.hits.clear();
    out.rays = out.truncated = 0;
    out.truncated_flux = 0.0;
    for (uint64_t i = first; i < first + count; ++i) trace_photon(i, out);
  }

 private:
  const Material& material(const Mesh& mesh, uint32_t tri) const {
    return scene_.materials.empty() ? default_material_ : scene_.materials[mesh.material_ids[tri]];
  }

  void trace_photon(uint64_t index, BatchOutput& out) const {
    Rng rng(settings_.seed, index);
    const double n = double(settings_.photon_count);
    // Jittered stratification of the light choice over the photon index.
    const double u_pick = (double(index) + rng.next_float()) / n;
    const size_t k = std::min<size_t>(std::upper_bound(cdf_.begin(), cdf_.end(), u_pick) - cdf_.begin(),
                                      emitters_.size() - 1);
    const float u[4] = {rng.next_float(), rng.next_float(), rng.next_float(), rng.next_float()};
    const EmitterSample s = sample_emitter(emitters_[k], u);
    Vec3 flux = s.weight * float(1.0 / (n * pick_[k]));
    if (max_component(flux) <= 0.0f) return;

    TraceContext tc;
    rtcInitIntersectContext(&tc.context);
    tc.context.filter = skip_origin_triangle;
    Vec3 org = s.origin, dir = s.direction;
    for (uint32_t depth = 0;; ++depth) {
      RTCRayHit rh;
      rh.ray.org_x = org.x;
      rh.ray.org_y = org.y;
      rh.ray.org_z = org.z;
      rh.ray.dir_x = dir.x;
      rh.ray.dir_y = dir.y;
      rh.ray.dir_z = dir.z;
      rh.ray.tnear = 0.0f;
      rh.ray.tfar = std::numeric_limits<float>::infinity();
      rh.ray.time = 0.0f;
      rh.ray.mask = 0xFFFFFFFFu;
      rh.ray.id = 0;
      rh.ray.flags = 0;
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(rtc_, &tc.context, &rh);
      ++out.rays;
      if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return;

      const MeshView& view = views_[rh.hit.geomID];
      const Mesh& mesh = *view.mesh;
      const uint32_t tri = rh.hit.primID;
      const float bu = rh.hit.u, bv = rh.hit.v, bw = 1.0f - bu - bv;
      const Vec3 p0 = mesh.vertex(tri, 0), p1 = mesh.vertex(tri, 1), p2 = mesh.vertex(tri, 2);
      const Vec3 hit = p0 * bw + p1 * bu + p2 * bv;
      if (depth == 0 && s.radius2 > 0.0f) {
        const Vec3 to_hit = hit - s.center;
        const float d2 = dot(to_hit, to_hit);
        flux *= d2 / (d2 + s.radius2);
      }
      Vec3 normal = normalize(cross(p1 - p0, p2 - p0));
      const bool front = dot(dir, normal) < 0.0f;
      if (!front) normal = -normal;  // the side the photon arrived on

      if (front && view.texel_area) {
        const float* uv = &mesh.uv[6 * size_t(tri)];
        const float tu = bw * uv[0] + bu * uv[2] + bv * uv[4];
        const float tv = bw * uv[1] + bu * uv[3] + bv * uv[5];
        const float fx = std::floor(tu * float(mesh.lightmap_width));
        const float fy = std::floor(tv * float(mesh.lightmap_height));
        if (fx >= 0.0f && fy >= 0.0f && fx < float(mesh.lightmap_width) && fy < float(mesh.lightmap_height)) {
          const uint64_t texel = uint64_t(fy) * mesh.lightmap_width + uint64_t(fx);
          if (view.texel_area[texel] > 0.0)
            out.hits.push_back({uint32_t(view.texel_offset + texel), flux.x, flux.y, flux.z});
        }
      }

      const Vec3 albedo = material(mesh, tri).albedo;
      const float q = std::fmin(1.0f, max_component(albedo));
      if (q <= 0.0f || settings_.max_bounces == 0) return;
      if (depth >= settings_.max_bounces) {
        ++out.truncated;
        out.truncated_flux += average(flux * albedo);
        return;
      }
      if (rng.next_float() >= q) return;  // Russian roulette
      flux *= albedo / q;

      const Vec3 local = cosine_hemisphere(rng.next_float(), rng.next_float());
      Vec3 t, b;
      make_frame(normal, t, b);
      dir = t * local.x + b * local.y + normal * local.z;
      org = hit + normal * (offset_scale_ + 2.5e-7f * max_abs_component(hit));
      tc.skip_geom = rh.hit.geomID;
      tc.skip_prim = tri;
    }
  }

  const Scene& scene_;
  RTCScene rtc_;
  const std::vector<MeshView>& views_;
  const std::vector<Emitter>& emitters_;
  plm_bake_settings settings_;
  float offset_scale_;
  std::vector<double> cdf_;
  std::vector<float> pick_;
  Material default_material_;
};

std::string mesh_label(const Mesh& m) { return "mesh '" + m.name + "'"; }

void add_mesh_warnings(const Mesh& mesh, const TexelAreas* areas, std::vector<std::string>& warnings) {
  uint32_t degenerate = 0, first = 0;
  for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
    const Vec3 p0 = mesh.vertex(t, 0);
    const Vec3 c = cross(mesh.vertex(t, 1) - p0, mesh.vertex(t, 2) - p0);
    if (!(length(c) > 0.0f) && degenerate++ == 0) first = t;
  }
  const std::string m = mesh_label(mesh);
  if (degenerate)
    warnings.push_back(m + ": " + std::to_string(degenerate) + " degenerate (zero-area) triangles are ignored (first: triangle " +
                       std::to_string(first) + ")");
  if (!areas) return;
  if (areas->zero_uv_triangles)
    warnings.push_back(m + ": " + std::to_string(areas->zero_uv_triangles) +
                       " triangles have zero lightmap UV area (first: triangle " +
                       std::to_string(areas->first_zero_uv_triangle) + "); light falling on them is not recorded");
  if (areas->outside_triangles)
    warnings.push_back(m + ": " + std::to_string(areas->outside_triangles) +
                       " triangles reach outside the [0, 1] lightmap UV square (first: triangle " +
                       std::to_string(areas->first_outside_triangle) + "); light falling outside it is not recorded");
  if (areas->overlapping_texels)
    warnings.push_back(m + ": lightmap UV islands overlap in " + std::to_string(areas->overlapping_texels) +
                       " texels (first: texel " + std::to_string(areas->first_overlapping_texel % mesh.lightmap_width) +
                       ", " + std::to_string(areas->first_overlapping_texel / mesh.lightmap_width) +
                       "); overlapping surfaces share one value");
}

void validate(const Scene& scene, const plm_bake_settings& s) {
  if (s.photon_count == 0) fail(PLM_ERROR_INVALID_ARGUMENT, "settings: photon_count must be > 0");
  if (s.photon_count > (uint64_t(1) << 40))
    fail(PLM_ERROR_INVALID_ARGUMENT, "settings: photon_count ", s.photon_count, " exceeds the limit 2^40");
  if (s.dilation > 4096) fail(PLM_ERROR_INVALID_ARGUMENT, "settings: dilation ", s.dilation, " exceeds 4096 texels");
  if (scene.meshes.empty()) fail(PLM_ERROR_INVALID_SCENE, "the scene has no meshes: nothing to bake");
  uint64_t texels = 0;
  for (const Mesh& m : scene.meshes) texels += uint64_t(m.lightmap_width) * m.lightmap_height;
  if (texels == 0)
    fail(PLM_ERROR_INVALID_SCENE, "no mesh has a lightmap: give at least one mesh a lightmap size and UVs");
  if (texels >= (uint64_t(1) << 31))
    fail(PLM_ERROR_INVALID_SCENE, "the lightmaps hold ", texels, " texels together; the limit is 2^31");
}

}  // namespace

plm_bake_settings default_settings() {
  plm_bake_settings s;
  s.photon_count = 1000000;
  s.max_bounces = 1024;
  s.seed = 0;
  s.thread_count = 0;
  s.dilation = 8;
  return s;
}

BakeOutput bake(const Scene& scene, const plm_bake_settings& settings, const ProgressFn& progress) {
  const auto t_start = Clock::now();
  validate(scene, settings);
  auto report = [&](double fraction, const char* stage) {
    if (progress && !progress(fraction, stage)) fail(PLM_ERROR_CANCELLED, "the bake was cancelled");
  };
  report(0.0, "building the ray-tracing scene");

  BakeOutput out;
  const unsigned threads = settings.thread_count ? settings.thread_count
                                                 : std::max(1u, std::thread::hardware_concurrency());
  EmbreeScene accel(scene, threads);
  const Vec3 lo = accel.bounds_min(), hi = accel.bounds_max();
  if (!is_finite(lo) || !is_finite(hi) || lo.x > hi.x)
    fail(PLM_ERROR_INVALID_SCENE, "the scene has no triangle with a non-zero area");
  const Vec3 center = (lo + hi) * 0.5f;
  const float extent = length(hi - lo);
  const float radius = 0.5f * extent * 1.01f + 1e-6f * max_abs_component(center) + 1e-30f;

  report(0.02, "computing texel areas");
  std::vector<TexelAreas> areas(scene.meshes.size());
  std::vector<MeshView> views(scene.meshes.size());
  uint64_t texel_count = 0;
  for (size_t i = 0; i < scene.meshes.size(); ++i) {
    const Mesh& mesh = scene.meshes[i];
    views[i] = {&mesh, texel_count, nullptr};
    if (mesh.has_lightmap()) {
      areas[i] = compute_texel_areas(mesh);
      views[i].texel_area = areas[i].area.data();
      texel_count += uint64_t(mesh.lightmap_width) * mesh.lightmap_height;
    }
    add_mesh_warnings(mesh, mesh.has_lightmap() ? &areas[i] : nullptr, out.warnings);
  }

  const std::vector<Emitter> emitters = build_emitters(scene, center, radius);
  double emitted = 0.0;
  for (const Emitter& e : emitters) emitted += average(e.flux);
  out.stats.seconds_setup = seconds_since(t_start);

  // Global accumulators in double: millions of small contributions stay exact.
  std::vector<double> sum(3 * texel_count, 0.0), sum_sq(texel_count, 0.0);
  std::vector<uint32_t> hit_count(texel_count, 0);
  const auto t_trace = Clock::now();
  if (emitters.empty()) {
    out.warnings.push_back("the scene has no lights, no emissive materials and no world light: every lightmap is black");
  } else {
    out.stats.emitted_power = emitted;
    out.stats.photons_emitted = settings.photon_count;
    Tracer tracer(scene, accel.handle(), views, emitters, settings, extent);
    const uint64_t batch_count = (settings.photon_count + kBatchPhotons - 1) / kBatchPhotons;
    std::vector<BatchOutput> batches;
    tbb::task_arena arena(static_cast<int>(threads));
    uint64_t group = threads;  // batches per group, tuned so progress comes every ~0.2 s
    double truncated_flux = 0.0;
    for (uint64_t first = 0; first < batch_count;) {
      const uint64_t n = std::min(group, batch_count - first);
      if (batches.size() < n) batches.resize(n);
      const auto t_group = Clock::now();
      arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, 1), [&](const tbb::blocked_range<uint64_t>& r) {
          for (uint64_t b = r.begin(); b < r.end(); ++b) {
            const uint64_t p0 = (first + b) * kBatchPhotons;
            tracer.trace_batch(p0, std::min<uint64_t>(kBatchPhotons, settings.photon_count - p0), batches[b]);
          }
        });
      });
      for (uint64_t b = 0; b < n; ++b) {  // merge in batch order
        const BatchOutput& bo = batches[b];
        for (const Hit& h : bo.hits) {
          sum[3 * size_t(h.texel)] += h.r;
          sum[3 * size_t(h.texel) + 1] += h.g;
          sum[3 * size_t(h.texel) + 2] += h.b;
          const double a = (double(h.r) + h.g + h.b) / 3.0;
          sum_sq[h.texel] += a * a;
          ++hit_count[h.texel];
        }
        out.stats.photon_hits += bo.hits.size();
        out.stats.rays_traced += bo.rays;
        out.stats.paths_truncated += bo.truncated;
        truncated_flux += bo.truncated_flux;
      }
      first += n;
      const double dt = seconds_since(t_group);
      if (dt < 0.1) group = std::min<uint64_t>(group * 2, 1024);
      else if (dt > 0.4 && group > threads) group = std::max<uint64_t>(threads, group / 2);
      report(std::min(0.95, 0.05 + 0.9 * double(first) / double(batch_count)), "tracing photons");
    }
    if (truncated_flux > 1e-4 * emitted)
      out.warnings.push_back(std::to_string(out.stats.paths_truncated) + " photon paths reached max_bounces (" +
                             std::to_string(settings.max_bounces) + ") and were stopped, losing " +
                             std::to_string(100.0 * truncated_flux / emitted) +
                             "% of the emitted power; raise max_bounces for albedos near 1");
  }
  out.stats.seconds_trace = seconds_since(t_trace);

  report(0.95, "writing lightmaps");
  out.lightmaps.resize(scene.meshes.size());
  for (size_t i = 0; i < scene.meshes.size(); ++i) {
    const Mesh& mesh = scene.meshes[i];
    if (!mesh.has_lightmap()) continue;
    LightmapImage& img = out.lightmaps[i];
    img.width = mesh.lightmap_width;
    img.height = mesh.lightmap_height;
    const size_t n = size_t(img.width) * img.height;
    // Pool the sums of barely covered texels with their neighbour's (see merge_sparse_texels).
    const size_t g0 = views[i].texel_offset;
    std::vector<double> pooled(5 * n);  // R, G, B, squared sum, area
    for (size_t t = 0; t < n; ++t) {
      for (int c = 0; c < 3; ++c) pooled[5 * t + c] = sum[3 * (g0 + t) + c];
      pooled[5 * t + 3] = sum_sq[g0 + t];
      pooled[5 * t + 4] = areas[i].area[t];
    }
    const std::vector<uint32_t> shown = merge_sparse_texels(areas[i], img.width, img.height);
    for (size_t t = 0; t < n; ++t) {
      if (shown[t] == t) continue;
      for (int k = 0; k < 5; ++k) pooled[5 * size_t(shown[t]) + k] += pooled[5 * t + k];
    }
    std::vector<float> values(4 * n, 0.0f);  // R, G, B, error: dilated together
    std::vector<uint8_t> filled(n, 0);
    img.hits.assign(n, 0.0f);
    img.coverage = areas[i].coverage;
    for (size_t t = 0; t < n; ++t) {
      if (!(areas[i].area[t] > 0.0)) continue;
      const double* p = &pooled[5 * size_t(shown[t])];
      const double scale = 1.0 / (p[4] * kPiD);
      for (int c = 0; c < 3; ++c) values[4 * t + c] = float(p[c] * scale);
      values[4 * t + 3] = float(std::sqrt(p[3]) * scale);
      img.hits[t] = float(hit_count[g0 + t]);
      filled[t] = 1;
    }
    dilate(values, 4, filled, img.width, img.height, settings.dilation);
    img.rgb.resize(3 * n);
    img.error.resize(n);
    for (size_t t = 0; t < n; ++t) {
      for (int c = 0; c < 3; ++c) img.rgb[3 * t + c] = values[4 * t + c];
      img.error[t] = values[4 * t + 3];
    }
  }
  out.stats.seconds_total = seconds_since(t_start);
  report(1.0, "done");
  return out;
}

}  // namespace plm

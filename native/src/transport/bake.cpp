#include "transport/bake.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <thread>

#include "accel/embree_scene.h"
#include "lightmap/dilate.h"
#include "lightmap/reconstruct.h"
#include "lightmap/texel_area.h"
#include "lsystem/lsystem_object.h"
#include "ol/area_estimation.h"
#include "ol/orientation_lightmap.h"
#include "subdiv/limit_area.h"
#include "texture/texture.h"
#include "transport/direct.h"
#include "transport/emitters.h"
#include "transport/memory.h"
#include "transport/tracing.h"
#include "util/error.h"
#include "util/rng.h"
#include "util/sobol.h"

namespace plm {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Photons are traced in fixed batches; a batch's hits are merged in batch
// order, so sums are identical whatever the thread count. The error target
// is checked at fixed batch counts, so where a bake stops is deterministic too.
constexpr uint32_t kBatchPhotons = 4096;
constexpr uint64_t kCheckBatches = 16;
// With a target error the direct pass starts with at most this many samples
// per texel and adds more where its noise is (bake(), "Direct pass").
constexpr uint32_t kFirstTargetSamples = 16;
// How fast a texel's direct-light variance falls with its sample count n
// (n^-a) in the allocation of samples: stratified samples over a shadow edge
// give n^-1.5 (open scene, 16 -> 64 samples everywhere: error 1.96 -> 0.70 %,
// n^-0.74), plain noise n^-1 (the next round then adds the rest).
constexpr double kDirectConvergence = 1.5;
// ... and gives a texel at most this many times max(16, direct_samples) in all.
constexpr double kMaxDirectGrowth = 2048.0;
// Rays per texel of the final gather (at most kMaxGatherSamples under a small target).
constexpr uint32_t kGatherSamples = 16, kMaxGatherSamples = 256;
// The final gather runs only when max_bounces does not truncate light (the default is 1024).
constexpr uint32_t kGatherMinBounces = 64;
// Radius (texels) of the local linear fit that smooths the gather (reconstruct_linear).
constexpr uint32_t kGatherRadius = 2;
// A texel's fit reaches at most kGatherReach x the harmonic mean distance of
// its gather rays' hits. Measured at the 1 % target, against no such limit:
// open / interior / Cornell 0.962 / 0.958 / 1.038 % error against 0.971 /
// 0.986 / 1.046 %; 0.5 was worse (interior at 2 %: 2.14 % against 1.78 %).
constexpr double kGatherReach = 1.0;

// A photon that reaches a smooth surface is weighted by cos(shading normal) /
// cos(geometric normal) of its arrival direction (the irradiance a texel holds
// is taken about the shading normal), at most this much: near grazing
// incidence the ratio has no bound, and its variance with it. Under a uniform
// sky this loses 0.05 % of the light of a normal tilted 10 degrees from its
// triangle's, 0.45 % at 30 degrees and 1.6 % at 60 (4 would lose 0.25, 2.1
// and 7 %).
constexpr float kMaxShadingRatio = 16.0f;

struct Hit {
  uint32_t texel;  // global texel index over all lightmaps
  float r, g, b;   // flux / pick probability; divided by the photon count at the end
};

// A hit on an OL mesh: the bin of the triangle's normal (OlMeshView::bins).
struct OlHit {
  uint32_t group, bin;
  float r, g, b;
};

// A hit on an L-system object: its root-OL bin and the stub key of the
// instance hit (LSystemObject::stub_key).
struct LsHit {
  uint32_t object, bin;
  uint64_t key;
  float r, g, b;
};

struct BatchOutput {
  std::vector<Hit> hits;
  std::vector<OlHit> ol_hits;
  std::vector<LsHit> ls_hits;
  std::vector<uint32_t> back_meshes;  // meshes whose back a photon reached (the final gather's dark backs)
  uint64_t rays = 0;
  uint64_t truncated = 0;
  double truncated_flux = 0.0;
};

constexpr uint32_t kNoBin = ~0u;

// A mesh as the photon tracer sees its OL group: group -1 for none, else the
// OL bin of each triangle's normal (kNoBin for degenerate triangles).
struct OlMeshView {
  int32_t group = -1;
  const uint32_t* bins = nullptr;
  bool backup = false;  // a backup OL: it records what the mesh's texels record (the indirect hits)
};

class PhotonTracer {
 public:
  // Hits on lightmapped meshes are recorded from depth first_recorded_depth
  // on, hits on OL meshes at every depth (they get no direct pass).
  PhotonTracer(const Scene& scene, RTCScene rtc, const std::vector<MeshView>& views,
               const std::vector<CsgView>& csg_views, const std::vector<OlMeshView>& ol_views,
               const std::vector<Emitter>& emitters, const plm_bake_settings& settings, float scene_extent,
               uint32_t first_recorded_depth, const std::vector<ol::OctGrid>& ls_grids,
               const TextureSet* textures = nullptr)
      : scene_(scene), textures_(textures), rtc_(rtc), views_(views), csg_views_(csg_views), ol_views_(ol_views),
        emitters_(emitters),
        ls_grids_(ls_grids), ls_base_(views.size() + csg_views.size()),
        settings_(settings),
        offset_scale_(1e-6f * scene_extent), first_recorded_(first_recorded_depth), table_(emitters) {
    pick_offset_ = double(Rng(settings.seed, ~0ull).next_float());
    seed_hash_ = {splitmix64(settings.seed)};
    default_material_.albedo = {0.8f, 0.8f, 0.8f};
    mesh_only_ = !textures && csg_views.empty() && scene.lsystems.empty();
    build_hit_tables();
  }

  // A triangle's material (grey 0.8 in a scene without materials).
  const Material& material(const Mesh& mesh, uint32_t tri) const { return material_by_id(mesh.material_ids[tri]); }

  void trace_batch(uint64_t first, uint64_t count, BatchOutput& out) const {
    out.hits.clear();
    out.ol_hits.clear();
    out.ls_hits.clear();
    out.back_meshes.clear();
    out.rays = out.truncated = 0;
    out.truncated_flux = 0.0;
    if (mesh_only_)
      for (uint64_t i = first; i < first + count; ++i) trace_photon<true>(i, out);
    else
      for (uint64_t i = first; i < first + count; ++i) trace_photon<false>(i, out);
  }

 private:
  const Material& material_by_id(uint32_t id) const {
    return scene_.materials.empty() ? default_material_ : scene_.materials[id];
  }

  // A photon's random numbers: group 0 = light choice + emission, group
  // 1 + depth = that bounce. Sobol points are keyed per batch of kBatchPhotons
  // (aligned), so batches are independent replicates for the error estimate.
  // By default (measured: Sobol paths do not lower texel errors, see
  // docs/benchmarks.md) the light choice follows a rotated van der Corput
  // sequence, stratified for any photon count, and the rest is pseudo-random.
  class PhotonSampler {
   public:
    PhotonSampler(uint64_t index, const plm_bake_settings& s, double pick_offset, Rng::SeedHash seed_hash)
        : rng_(seed_hash, index), global_(index), index_(uint32_t(index % kBatchPhotons)),
          key_(s.sampler == PLM_SAMPLER_SOBOL ? uint32_t(splitmix64((uint64_t(s.seed) << 32) ^ (index / kBatchPhotons))) : 0u),
          mode_(s.sampler),
          pick_offset_(pick_offset) {}
    // pick, then the four numbers of sample_emitter.
    void emission(float& pick, float u[4]) {
      if (mode_ == PLM_SAMPLER_SOBOL) {
        sobol_group(index_, key_, 0, 4, u);
        sobol_group(index_, key_ ^ 0x5bd1e995u, 0, 1, &pick);
        return;
      }
      if (mode_ == PLM_SAMPLER_RANDOM) {
        pick = rng_.next_float();
      } else {
        const double p = radical_inverse2(global_) + pick_offset_;
        pick = float(p >= 1.0 ? p - 1.0 : p);
        if (pick >= 1.0f) pick = 0.0f;  // float rounding
      }
      for (int d = 0; d < 4; ++d) u[d] = rng_.next_float();
    }
    // Two numbers for the direction, one for Russian roulette.
    void bounce(uint32_t depth, float u[3]) {
      if (mode_ == PLM_SAMPLER_SOBOL) return sobol_group(index_, key_, 1 + depth, 3, u);
      for (int d = 0; d < 3; ++d) u[d] = rng_.next_float();
    }

   private:
    Rng rng_;
    uint64_t global_;
    uint32_t index_, key_, mode_;
    double pick_offset_;
  };

  // What a photon needs at a mesh hit, flattened per triangle into one cache
  // line (HitTri) and per mesh (HitMesh), so a bounce reads one line instead
  // of the normal, material and OL-bin arrays and divides nothing. The values
  // are those the loop computed per hit, so results are bit for bit the same:
  // make_frame(-n) is exactly (t, -b) for make_frame(n) = (t, b), and
  // albedo * (1 / q) is what albedo / q evaluates.
  struct alignas(64) HitTri {
    Vec3 normal;       // unit geometric normal
    Vec3 frame_t, frame_b;  // make_frame(normal)
    Vec3 bounce;       // albedo / roulette: the flux factor of a surviving photon (untextured scenes)
    float roulette;    // survival probability min(1, max_component(albedo))
    uint32_t ol_bin;   // OL bin of the normal, kNoBin if none
    uint32_t degenerate;  // 1: the photon stops here
    uint32_t pad_;
  };
  static_assert(sizeof(HitTri) == 64, "HitTri fills one cache line");
  struct HitMesh {
    const HitTri* tris;
    const float* uv;  // 6 per triangle (Mesh::uv)
    const uint32_t* indices;
    const Vec3* positions;
    const Vec3* shading;  // 3 corner normals per triangle (Mesh::normals); null for flat meshes
    const uint8_t* contact;  // per texel: may be pressed against another surface (MeshView::contact), or null
    bool special;            // shading or contact is set: hits go through special_hit
    const uint8_t* covered;  // per texel: area > 0; null when the mesh records no texel hits
    uint64_t texel_offset;
    uint32_t width, height;
    int32_t ol_group;
    bool ol_backup;
  };

  void build_hit_tables() {
    size_t tris = 0, texels = 0;
    for (const MeshView& v : views_) {
      tris += v.mesh->triangle_count();
      if (v.texel_area) texels += size_t(v.mesh->lightmap_width) * v.mesh->lightmap_height;
    }
    hit_tris_.resize(tris);
    covered_.resize(texels);
    hit_meshes_.resize(views_.size());
    size_t t0 = 0, c0 = 0;
    for (size_t m = 0; m < views_.size(); ++m) {
      const MeshView& v = views_[m];
      const Mesh& mesh = *v.mesh;
      const OlMeshView& ol = ol_views_[m];
      HitMesh& hm = hit_meshes_[m];
      hm = {hit_tris_.data() + t0, mesh.uv.data(), mesh.indices.data(), mesh.positions.data(),
            mesh.smooth() ? mesh.normals.data() : nullptr, v.contact, mesh.smooth() || v.contact, nullptr,
            v.texel_offset, mesh.lightmap_width, mesh.lightmap_height, ol.group, ol.backup};
      for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
        HitTri& h = hit_tris_[t0 + t];
        h.normal = v.normals[t];
        h.degenerate = h.normal.x == 0.0f && h.normal.y == 0.0f && h.normal.z == 0.0f;
        if (!h.degenerate) make_frame(h.normal, h.frame_t, h.frame_b);
        const Vec3 albedo = material(mesh, t).albedo;
        h.roulette = std::fmin(1.0f, max_component(albedo));
        h.bounce = h.roulette > 0.0f ? albedo / h.roulette : Vec3{};
        h.ol_bin = ol.group >= 0 ? ol.bins[t] : kNoBin;
      }
      t0 += mesh.triangle_count();
      if (v.texel_area) {
        const size_t n = size_t(mesh.lightmap_width) * mesh.lightmap_height;
        for (size_t k = 0; k < n; ++k) covered_[c0 + k] = v.texel_area[k] > 0.0 ? 1 : 0;
        hm.covered = covered_.data() + c0;
        c0 += n;
      }
    }
  }

  // Albedo of a material where no texture UV exists (textures: their mean).
  Vec3 flat_albedo(uint32_t id) const {
    return textures_ && !scene_.materials.empty() ? textures_->flat_albedo(id) : material_by_id(id).albedo;
  }

  // kMeshOnly: no CSG solid, no L-system object, no texture (mesh_only_);
  // the compiler then drops their branches from the loop.
  template <bool kMeshOnly>
  void trace_photon(uint64_t index, BatchOutput& out) const {
    PhotonSampler sampler(index, settings_, pick_offset_, seed_hash_);
    float u_pick, u[4];
    sampler.emission(u_pick, u);
    const size_t k = table_.choose(u_pick);
    const Emitter& em = emitters_[k];
    EmitterSample s = sample_emitter(em, u);
    if (!kMeshOnly && em.textured)  // the texture at the photon's origin: flux 2 pi L(x) A, unbiased whatever the mean
      s.weight = textures_->emission(*views_[em.mesh].mesh, em.material, em.triangle, s.bu, s.bv) *
                 (2.0f * kPi * em.area);
    Vec3 flux = s.weight * (1.0f / table_.probability(k));
    if (!(flux.x > 0.0f || flux.y > 0.0f || flux.z > 0.0f)) return;  // max_component(flux) <= 0 without a libm fmaxf call

    TraceContext tc;
    Vec3 org = s.origin, dir = s.direction;
    for (uint32_t depth = 0;; ++depth) {
      RTCRayHit rh;
      rh.ray = make_ray(org, dir, std::numeric_limits<float>::infinity());
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
      // The numbers of the bounce at this ray's hit and its direction in the
      // hit's frame do not depend on the hit: drawn here, before the ray is
      // cast, their latency (two square roots, the sine) overlaps Embree's
      // traversal instead of lying between the hit and the next ray
      // (measured: +5 points of raw Embree's speed on the Cornell box,
      // docs/benchmarks.md). A path that ends here drew them for nothing;
      // the stream is the same either way, so results are bit for bit too.
      float v[3];
      sampler.bounce(depth, v);
      const Vec3 local = cosine_hemisphere(v[0], v[1]);
      rtcIntersect1(rtc_, &tc.context, &rh);
      ++out.rays;
      if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return;

      // The hit: a mesh triangle, the exact surface of a CSG solid (its
      // primitive in primID, the face id in u, the solid's outward normal),
      // or an L-system object (its GraphHit kept on this thread).
      const bool is_lsystem = !kMeshOnly && rh.hit.geomID >= ls_base_;
      const bool is_csg = !kMeshOnly && !is_lsystem && rh.hit.geomID >= views_.size();
      const uint32_t tri = rh.hit.primID;
      Vec3 normal, hit, albedo;
      float q = -1.0f;  // survival probability; set here for mesh hits, below for the others
      const HitTri* flat = nullptr;  // an untextured mesh triangle: albedo, frame and weight from the table
      const HitMesh* special = nullptr;  // a mesh hit that needs shading normals or a contact test
      float bu = 0.0f, bv = 0.0f;
      uint32_t ls_bin = 0;
      uint64_t ls_key = 0;
      if (is_lsystem) {
        const uint32_t l = rh.hit.geomID - ls_base_;
        const lsystem::LSystemObject& obj = *scene_.lsystems[l];
        const lsystem::GraphHit& gh = obj.last_hit();
        const ol::Vec3d nd = lsystem::ol_normal(gh.n);
        if (!std::isfinite(nd.x) || !std::isfinite(nd.y) || !std::isfinite(nd.z)) return;
        normal = {float(nd.x), float(nd.y), float(nd.z)};
        hit = org + dir * rh.ray.tfar;
        albedo = flat_albedo(obj.scene_material(gh.material));
        ls_bin = ls_grids_[l].bin(nd);
        ls_key = obj.stub_key(gh);
      } else if (is_csg) {
        const CsgView& cv = csg_views_[rh.hit.geomID - views_.size()];
        normal = normalize(Vec3{rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z});
        if (!is_finite(normal)) return;
        hit = org + dir * rh.ray.tfar;
        albedo = flat_albedo(cv.object->material(tri));
      } else {
        const HitMesh& hm = hit_meshes_[rh.hit.geomID];
        const HitTri& ht = hm.tris[tri];
        bu = rh.hit.u, bv = rh.hit.v;
        const float bw = 1.0f - bu - bv;
        if (ht.degenerate) return;  // the photon stops
        normal = ht.normal;
        if (hm.special) special = &hm;
        const uint32_t* ix = hm.indices + 3 * size_t(tri);
        hit = hm.positions[ix[0]] * bw + hm.positions[ix[1]] * bu + hm.positions[ix[2]] * bv;
        if (!kMeshOnly && textures_ && !scene_.materials.empty()) {
          const Mesh& mesh = *views_[rh.hit.geomID].mesh;
          albedo = textures_->albedo(mesh, mesh.material_ids[tri], tri, bu, bv);
          q = std::fmin(1.0f, max_component(albedo));
        } else {
          flat = &ht;
          q = ht.roulette;
        }
      }
      if (depth == 0 && s.radius2 > 0.0f) {
        const Vec3 to_hit = hit - s.center;
        const float d2 = dot(to_hit, to_hit);
        flux *= d2 / (d2 + s.radius2);
      }
      const bool front = dot(dir, normal) < 0.0f;
      if (!front) normal = -normal;  // the side the photon arrived on
      if (special && !special_hit(*special, rh.hit.geomID, tri, bu, bv, dir, front, normal, hit, flux)) return;
      if (front && is_lsystem)
        out.ls_hits.push_back({rh.hit.geomID - uint32_t(ls_base_), ls_bin, ls_key, flux.x, flux.y, flux.z});
      if (front && !is_lsystem && depth >= first_recorded_) record(rh, is_csg, hit, flux, out);
      if (!front && !is_csg && !is_lsystem && (out.back_meshes.empty() || out.back_meshes.back() != rh.hit.geomID))
        out.back_meshes.push_back(rh.hit.geomID);
      if (front && !is_csg && !is_lsystem) {
        const HitMesh& hm = hit_meshes_[rh.hit.geomID];
        const uint32_t bin = hm.tris[tri].ol_bin;
        if (bin != kNoBin && (!hm.ol_backup || depth >= first_recorded_))
          out.ol_hits.push_back({uint32_t(hm.ol_group), bin, flux.x, flux.y, flux.z});
      }

      if (q < 0.0f) q = std::fmin(1.0f, max_component(albedo));
      if (q <= 0.0f || settings_.max_bounces == 0) return;
      if (depth >= settings_.max_bounces) {
        if (flat) albedo = material(*views_[rh.hit.geomID].mesh, tri).albedo;
        ++out.truncated;
        out.truncated_flux += average(flux * albedo);
        return;
      }
      if (v[2] >= q) return;  // Russian roulette
      flux *= flat ? flat->bounce : albedo / q;

      Vec3 t, b;
      if (flat) {
        t = flat->frame_t;
        b = front ? flat->frame_b : -flat->frame_b;
      } else {
        make_frame(normal, t, b);
      }
      dir = t * local.x + b * local.y + normal * local.z;
      org = offset_origin(hit, normal, offset_scale_);
      // Leaving a triangle, skip it; leaving a CSG or L-system surface, only
      // the offset (a ray may rightly hit the primitive it leaves: the inside
      // of a bowl, a neighbouring branch).
      const bool analytic = is_csg || is_lsystem;
      tc.skip_geom = analytic ? RTC_INVALID_GEOMETRY_ID : rh.hit.geomID;
      tc.skip_prim = analytic ? RTC_INVALID_GEOMETRY_ID : tri;
    }
  }

  // A hit on a smooth mesh, or on a triangle that may be pressed against
  // another surface. A photon that finds a face in contact came through the
  // other surface (both lie at the same distance): it is absorbed. On a smooth
  // mesh the flux is weighted by cos(shading) / cos(geometric) at the hit
  // (normal: the geometric normal turned to the side the photon arrived on).
  // Returns false where the photon stops.
  bool special_hit(const HitMesh& hm, unsigned geom, uint32_t tri, float bu, float bv, Vec3 dir, bool front,
                   Vec3 normal, Vec3 hit, Vec3& flux) const {
    if (front && hm.contact) {
      const int64_t texel = uv_texel(hm.uv + 6 * size_t(tri), bu, bv, hm.width, hm.height);
      if (texel >= 0 && hm.contact[texel] && in_contact(rtc_, views_, hit, normal, geom, tri, offset_scale_))
        return false;
    }
    if (!hm.shading) return true;
    const Vec3* c = hm.shading + 3 * size_t(tri);
    const Vec3 shading = c[0] * (1.0f - bu - bv) + c[1] * bu + c[2] * bv;
    const float len = length(shading);
    if (!(len > 0.0f)) return true;
    const float cos_s = -dot(dir, front ? shading : -shading) / len, cos_g = -dot(dir, normal);
    const float w = cos_s > 0.0f ? std::fmin(cos_s / cos_g, kMaxShadingRatio) : 0.0f;
    flux *= w;
    return w > 0.0f;  // light from behind the shading normal: no irradiance about it
  }

  // A front-side hit into the texel (or CSG sub-texel) it falls in, if any.
  void record(const RTCRayHit& rh, bool is_csg, Vec3 hit, Vec3 flux, BatchOutput& out) const {
    if (is_csg) {
      const CsgView& cv = csg_views_[rh.hit.geomID - views_.size()];
      if (!cv.lightmap) return;
      const int64_t sub = cv.lightmap->sub_texel_of_hit(rh.hit.primID, int(rh.hit.u), to_double(hit));
      if (sub >= 0) out.hits.push_back({uint32_t(cv.texel_offset + uint64_t(sub)), flux.x, flux.y, flux.z});
      return;
    }
    const HitMesh& hm = hit_meshes_[rh.hit.geomID];
    if (!hm.covered) return;
    // Outside the lightmap, and for NaN, nothing is recorded.
    const int64_t texel = uv_texel(hm.uv + 6 * size_t(rh.hit.primID), rh.hit.u, rh.hit.v, hm.width, hm.height);
    if (texel >= 0) {
      if (hm.covered[texel]) {
        // Fields stored in place: a Hit built on the stack and copied is
        // reloaded as one 16-byte word right after four 4-byte stores, which
        // store forwarding cannot serve (measured: the loop's largest stall).
        const Hit zero{};
        out.hits.push_back(zero);  // an lvalue: the inlined push_back (an rvalue calls emplace_back)
        Hit& h = out.hits.back();
        h.texel = uint32_t(hm.texel_offset + texel);
        h.r = flux.x;
        h.g = flux.y;
        h.b = flux.z;
      }
    }
  }

  const Scene& scene_;
  const TextureSet* textures_;  // null for an untextured scene
  RTCScene rtc_;
  const std::vector<MeshView>& views_;
  const std::vector<CsgView>& csg_views_;
  const std::vector<OlMeshView>& ol_views_;
  const std::vector<Emitter>& emitters_;
  const std::vector<ol::OctGrid>& ls_grids_;  // per L-system object: its OLs' grid
  size_t ls_base_;                            // Embree id of the first L-system object
  plm_bake_settings settings_;
  float offset_scale_;
  uint32_t first_recorded_;
  EmitterTable table_;
  double pick_offset_ = 0.0;
  Material default_material_;
  std::vector<HitTri> hit_tris_;    // all meshes' triangles, mesh after mesh
  std::vector<HitMesh> hit_meshes_;  // per mesh (Embree geometry id)
  std::vector<uint8_t> covered_;     // per texel of the meshes that record hits
  bool mesh_only_ = false;           // trace_photon<true> applies
  Rng::SeedHash seed_hash_{};        // of settings_.seed, for the photons' Rng
};

// Runs work(first, count) over [0, total) in groups that take about 0.2 s, so
// that after(done) -- progress, cancel, steering -- runs several times a
// second on the calling thread. after returns false to stop early.
// max_group (0: granule * 1024) caps a group's size.
template <typename Work, typename After>
void run_in_groups(tbb::task_arena& arena, uint64_t total, uint64_t granule, Work&& work, After&& after,
                   uint64_t max_group = 0) {
  const uint64_t limit = max_group ? std::max(max_group, granule) : granule * 1024;
  uint64_t group = granule;
  for (uint64_t first = 0; first < total;) {
    const uint64_t n = std::min(group, total - first);
    const auto t0 = Clock::now();
    arena.execute([&] { work(first, n); });
    first += n;
    const double dt = seconds_since(t0);
    if (dt < 0.1) group = std::min<uint64_t>(group * 2, limit);
    else if (dt > 0.4 && group > granule) group = std::max<uint64_t>(granule, group / 2);
    if (!after(first)) return;
  }
}

std::string mesh_label(const Mesh& m) { return "mesh '" + m.name + "'"; }

void add_mesh_warnings(const Mesh& mesh, const TexelAreas* areas, std::vector<std::string>& warnings) {
  uint32_t degenerate = 0, first = 0;
  for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
    if (degenerate_triangle(mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2)) && degenerate++ == 0) first = t;
  }
  const std::string m = mesh_label(mesh);
  if (degenerate)
    warnings.push_back(m + ": " + std::to_string(degenerate) + " degenerate (zero-area or needle) triangles are ignored (first: triangle " +
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
  const bool steered = s.target_error > 0.0 || s.time_budget > 0.0;
  if (s.photon_count == 0 && !steered)
    fail(PLM_ERROR_INVALID_ARGUMENT, "settings: photon_count must be > 0 unless target_error or time_budget is set");
  if (s.photon_count > (uint64_t(1) << 40))
    fail(PLM_ERROR_INVALID_ARGUMENT, "settings: photon_count ", s.photon_count, " exceeds the limit 2^40");
  if (!(s.target_error >= 0.0 && s.target_error < 1.0))
    fail(PLM_ERROR_INVALID_ARGUMENT, "settings: target_error ", s.target_error, " must be in [0, 1) (e.g. 0.02 for 2%)");
  if (!(s.time_budget >= 0.0 && s.time_budget < 1e7))
    fail(PLM_ERROR_INVALID_ARGUMENT, "settings: time_budget ", s.time_budget, " must be a number of seconds >= 0");
  if (s.direct_samples > 65536)
    fail(PLM_ERROR_INVALID_ARGUMENT, "settings: direct_samples ", s.direct_samples, " exceeds 65536");
  if (s.filter_radius > 64) fail(PLM_ERROR_INVALID_ARGUMENT, "settings: filter_radius ", s.filter_radius, " exceeds 64 texels");
  if (s.texel_value > PLM_TEXEL_AREA)
    fail(PLM_ERROR_INVALID_ARGUMENT, "settings: texel_value ", s.texel_value, " is not PLM_TEXEL_CYCLES (0) or PLM_TEXEL_AREA (1)");
  if (s.sampler > PLM_SAMPLER_SOBOL)
    fail(PLM_ERROR_INVALID_ARGUMENT, "settings: sampler ", s.sampler, " is not PLM_SAMPLER_DEFAULT (0), _RANDOM (1) or _SOBOL (2)");
  if (s.dilation > 4096) fail(PLM_ERROR_INVALID_ARGUMENT, "settings: dilation ", s.dilation, " exceeds 4096 texels");
  if (scene.meshes.empty() && scene.lsystems.empty())
    fail(PLM_ERROR_INVALID_SCENE, "the scene has no meshes: nothing to bake");
  uint64_t texels = 0;
  bool ol_meshes = false;
  for (const Mesh& m : scene.meshes) {
    if (m.ol_group < 0 || scene.ol_groups[size_t(m.ol_group)].backup)
      texels += uint64_t(m.lightmap_width) * m.lightmap_height;
    ol_meshes = ol_meshes || m.ol_group >= 0;
  }
  if (texels == 0 && !ol_meshes && scene.lsystems.empty())
    fail(PLM_ERROR_INVALID_SCENE, "no mesh has a lightmap or an OL group: give at least one mesh a lightmap size and "
         "UVs, or put it into an orientation-lightmap group");
  if (texels == 0 && s.target_error > 0.0 && s.photon_count == 0 && s.time_budget <= 0.0)
    fail(PLM_ERROR_INVALID_ARGUMENT, "settings: target_error is measured over ordinary lightmap texels, and no "
         "mesh has one (orientation lightmaps do not steer the bake): set photon_count or time_budget");
  if (texels >= (uint64_t(1) << 31))
    fail(PLM_ERROR_INVALID_SCENE, "the lightmaps hold ", texels, " texels together; the limit is 2^31");
}

// The OL of each group, its area per bin from the exact areas of its meshes'
// triangles (ol/area_estimation.h) or, for subdivision meshes of a group that
// asks for it (OlGroup::limit_area), from samples of their limit surface
// (subdiv/limit_area.h), and each OL mesh's triangle bins.
// Area and hits use the same double-precision normal, so a hit never lands
// in a bin its triangle's area missed.
std::vector<ol::OrientationLightmap> build_ols(const Scene& scene, std::vector<std::vector<uint32_t>>& bins,
                                               std::vector<uint32_t>& mesh_counts,
                                               std::vector<std::string>& warnings) {
  constexpr size_t kChunk = 1 << 16;  // triangles per estimate_area call: bounds the Patch buffer
  std::vector<ol::OrientationLightmap> ols;
  bins.assign(scene.meshes.size(), {});
  mesh_counts.assign(scene.ol_groups.size(), 0);
  for (size_t g = 0; g < scene.ol_groups.size(); ++g) {
    const OlGroup& group = scene.ol_groups[g];
    ols.emplace_back(group.resolution ? group.resolution : kAutoOlResolution, kOlBatches);
    ol::OrientationLightmap& map = ols.back();
    std::vector<double> area(map.bins(), 0.0), area_var(map.bins(), 0.0);
    std::vector<ol::Patch> parts;
    auto flush = [&] {
      if (parts.empty()) return;
      const ol::AreaEstimate e = ol::estimate_area(map.grid(), parts);
      for (size_t b = 0; b < area.size(); ++b) area[b] += e.area[b];
      parts.clear();
    };
    for (size_t i = 0; i < scene.meshes.size(); ++i) {
      const Mesh& mesh = scene.meshes[i];
      if (mesh.ol_group != int32_t(g)) continue;
      ++mesh_counts[g];
      bins[i].assign(mesh.triangle_count(), kNoBin);
      const bool limit = group.limit_area && mesh.cage;
      std::vector<double> cage_tri_area(limit ? map.bins() : 0, 0.0);
      for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
        const ol::Vec3d p0(mesh.vertex(t, 0)), p1(mesh.vertex(t, 1)), p2(mesh.vertex(t, 2));
        // The normal exactly as estimate_area's exact-triangle path computes it.
        const ol::Vec3d n = cross(p1 - p0, p2 - p0);
        const double len = length(n);
        if (len > 0.0) bins[i][t] = map.grid().bin(n * (1.0 / len));
        if (limit) {
          if (len > 0.0) cage_tri_area[bins[i][t]] += 0.5 * len;
          continue;
        }
        parts.push_back(ol::Patch::triangle(p0, p1, p2));
        if (parts.size() == kChunk) flush();
      }
      if (limit) {  // a subdivision mesh: the areas of its limit surface (subdiv/limit_area.h)
        const ol::AreaEstimate e = subdiv::mesh_limit_area("mesh '" + mesh.name + "' (" + std::to_string(i) + ")",
                                                           *mesh.cage, map.grid(), cage_tri_area,
                                                           {subdiv::kLimitAreaSamples, i + 1});
        for (size_t b = 0; b < area.size(); ++b) area[b] += e.area[b], area_var[b] += e.variance[b];
      }
    }
    flush();
    map.set_area(std::move(area), std::move(area_var));
    if (mesh_counts[g] == 0)
      warnings.push_back("OL group '" + group.name + "' (" + std::to_string(g) +
                         ") has no meshes: its orientation lightmap is black");
  }
  return ols;
}

// A texel that holds a value (area > 0): the direct pass works through these.
struct CoveredTexel {
  uint32_t mesh, texel;  // local texel of that mesh
};

// Sobol points make the direct pass's pair-difference variance conservative
// (a pair straddles the strata of the light choice). The true variance is
// measured on a quarter of the texels (at most 1024) spread over all lightmaps by one more,
// independent round (a Sobol key of its own): for two independent means a, b,
// E[(a - b)^2] = Var a + Var b. Returns true / pair-difference variance; the
// extra samples join those texels' sums.
double calibrate_direct(tbb::task_arena& arena, const DirectPass& pass, const std::vector<CoveredTexel>& covered,
                        std::vector<DirectSums>& direct, uint32_t samples) {
  constexpr uint32_t kCalibrationRound = 0xFF;  // a key no refinement round uses
  const size_t step = std::max<size_t>(4, covered.size() / 1024);
  const size_t m = covered.size() / step;
  std::vector<DirectSums> extra(m);
  arena.execute([&] {
    tbb::parallel_for(size_t(0), m, [&](size_t k) {
      const CoveredTexel& c = covered[k * step];
      pass.sample_texel(c.mesh, c.texel, kCalibrationRound, samples, extra[k]);
    });
  });
  double measured = 0.0, estimated = 0.0;
  size_t used = 0;
  for (size_t k = 0; k < m; ++k) {
    DirectSums& a = direct[k * step];
    const DirectSums& b = extra[k];
    if (a.paired && b.paired) {
      const double d = a.mean() - b.mean();
      measured += d * d;
      estimated += a.pair_variance_of_mean() + b.pair_variance_of_mean();
      ++used;
    }
    a.add(b);
  }
  if (used < 32 || !(estimated > 0.0)) return 1.0;
  return std::clamp(measured / estimated, 1e-4, 4.0);
}

// Photon sums per texel over all lightmaps, merged batch by batch in order.
class Accumulators {
 public:
  Accumulators(uint64_t texels, size_t meshes)
      : sum(3 * texels, 0.0), sum_sq(texels, 0.0), hits(texels, 0), back_lit(meshes, 0) {}
  std::vector<double> sum, sum_sq;  // flux / pick probability (not yet divided by the photon count)
  std::vector<uint32_t> hits;
  std::vector<uint8_t> back_lit;  // per mesh: a photon reached its back
  double total_sq = 0.0;
  uint64_t total_hits = 0;

  void merge(const BatchOutput& bo) {
    // Locals: the stores through the arrays could otherwise alias total_sq
    // (a loop-carried sum kept in memory). Same operations, same order.
    double* const s = sum.data();
    double* const s2 = sum_sq.data();
    uint32_t* const n = hits.data();
    double total = total_sq;
    for (const Hit& h : bo.hits) {
      const size_t t = h.texel;
      s[3 * t] += h.r;
      s[3 * t + 1] += h.g;
      s[3 * t + 2] += h.b;
      const double a = (double(h.r) + h.g + h.b) / 3.0;
      s2[t] += a * a;
      total += a * a;
      ++n[t];
    }
    total_sq = total;
    total_hits += bo.hits.size();
    for (const uint32_t m : bo.back_meshes) back_lit[m] = 1;
  }
};

// Everything the final estimate of a texel needs, shared by the error checks
// during the bake and the final images.
struct Estimator {
  const std::vector<TexelAreas>& areas;
  const std::vector<MeshView>& views;
  const std::vector<CsgView>& csgs;
  const std::vector<size_t>& covered_begin;  // per mesh: index of its first covered texel
  const std::vector<DirectSums>& direct;     // per covered texel, or empty
  const Accumulators& acc;
  uint32_t filter_radius;
  DirectNoise direct_noise;
  // The final gather per covered texel (empty without it), what its rays met
  // and its phantom sample (see "Final gather" in bake()).
  const std::vector<DirectSums>* gather = nullptr;
  const std::vector<DirectPass::GatherInfo>* gather_info = nullptr;
  const DirectNoise* gather_noise = nullptr;

  // Sub-texel `sub` of CSG solid c: irradiance / pi (3 values) and its
  // estimated mean squared error. No pooling: the photon estimate of the
  // sub-texel alone (cut sub-texels may be tiny, and their neighbours on
  // other faces or primitives), plus its direct light.
  double csg_texel(size_t c, uint32_t sub, uint64_t photons, double value3[3]) const {
    const size_t g = csgs[c].texel_offset + sub;
    const double k = 1.0 / (kPiD * double(std::max<uint64_t>(photons, 1)) * csgs[c].lightmap->area(sub));
    const double phantom_sq = acc.total_hits ? acc.total_sq / double(acc.total_hits) : 0.0;
    double variance = 0.0;
    for (int ch = 0; ch < 3; ++ch) value3[ch] = photons ? acc.sum[3 * g + ch] * k : 0.0;
    if (photons) variance = (acc.sum_sq[g] + phantom_sq) * k * k;
    if (!direct.empty()) {
      const DirectSums& d = direct[covered_begin[views.size() + c] + sub];
      if (d.count)
        for (int ch = 0; ch < 3; ++ch) value3[ch] += d.rgb[ch] / d.count;
      variance += d.variance_of_mean(direct_noise);
    }
    return variance;
  }

  // Two estimates of a texel's indirect light: the photons' (A, its own
  // hits) and the final gather's (G: albedo x radiosity of the texels its
  // rays hit), weighed by inverse variance: w A + (1 - w) G, w = var G /
  // (var A + var G). The gather's texel means are first smoothed by a local
  // linear fit over neighbours of similar direct light (reconstruct_linear):
  // near a wall's foot, where the bounce light changes fastest, a mean over
  // one side would be biased; the fit reaches no further than the gather's
  // hits are near (kGatherReach). Texels whose gather met something it
  // cannot look up keep A, and pool with no other (a negative guide), as do
  // texels whose rays met dark backs (their G is their own). Where the fit is
  // narrowed, A (a mean over the whole texel, G over its central square) is
  // tested against G for bias.
  // Adds the gather's part of the texels' variances, (1 - w)^2 var G, to *gather_part.
  void combine_gather(size_t i, std::vector<double>& value3, std::vector<double>& variance,
                      double* gather_part) const {
    const Mesh& mesh = *views[i].mesh;
    const size_t n = variance.size();
    std::vector<double> g_mean(3 * n, 0.0), g_var(n, 0.0), g_value, g_fit_var;
    std::vector<double> guide(n, -1.0), lookup_sq(n, 0.0);
    std::vector<uint8_t> usable(n, 0), radius(n, uint8_t(kGatherRadius));
    const double width = texel_width(areas[i]);
    size_t k = covered_begin[i];
    for (size_t t = 0; t < n; ++t) {
      if (!(areas[i].area[t] > 0.0)) continue;
      const DirectPass::GatherInfo& info = (*gather_info)[k];
      const DirectSums& g = (*gather)[k];
      const DirectSums& d = direct[k++];
      // The fit reaches no further than kGatherReach x the harmonic mean
      // distance of the texel's gather hits: near a wall the bounce light
      // changes faster than a plane follows. A texel whose rays met dark
      // backs (partly under a box) keeps its own gather and pools with none:
      // its neighbours' light is not its own.
      radius[t] = uint8_t(std::min(double(kGatherRadius), std::floor(kGatherReach * info.hit_distance / width)));
      if (info.dark) radius[t] = 0;
      if (info.unknown || g.count == 0) continue;
      usable[t] = 1;
      guide[t] = info.dark ? -1.0 : d.mean();
      for (int c = 0; c < 3; ++c) g_mean[3 * t + c] = g.rgb[c] / g.count;
      // Every ray met a dark back (the texel's points are under a box): no
      // light reaches them.
      g_var[t] = info.dark == g.count ? 0.0 : g.variance_of_mean(*gather_noise);
      lookup_sq[t] = info.lookup_error * info.lookup_error;
    }
    reconstruct_linear(areas[i], mesh.lightmap_width, mesh.lightmap_height, g_mean.data(), g_var.data(), guide.data(),
                       kGatherRadius, g_value, g_fit_var, radius.data());
    for (size_t t = 0; t < n; ++t) {
      if (!usable[t]) continue;
      // The lookups' errors are shared by neighbouring texels (their rays hit
      // the same texels): the fit does not average them down.
      double v_photons = variance[t];
      const double v_gather = g_fit_var[t] + lookup_sq[t];
      if (radius[t] < kGatherRadius) {
        // Near a wall the photons' mean over the whole texel is biased
        // against the value over the points the direct light and the gather
        // sample (the central square): where the two disagree by more than
        // their noise, the excess squared difference (an unbiased estimate of
        // the squared bias) joins the photons' variance.
        const double* pv = &value3[3 * t];
        const double* gv = &g_value[3 * t];
        const double diff = (pv[0] + pv[1] + pv[2] - gv[0] - gv[1] - gv[2]) / 3.0;
        v_photons += std::max(0.0, diff * diff - v_photons - v_gather);
      }
      const double w = v_photons + v_gather > 0.0 ? v_gather / (v_photons + v_gather) : 0.0;
      for (int c = 0; c < 3; ++c) value3[3 * t + c] = w * value3[3 * t + c] + (1.0 - w) * g_value[3 * t + c];
      variance[t] = w * w * v_photons + (1.0 - w) * (1.0 - w) * v_gather;
      if (gather_part) *gather_part += (1.0 - w) * (1.0 - w) * v_gather;
    }
  }

  // Per texel: irradiance / pi (3 values) and its estimated mean squared
  // error; the final gather's part of the variances is added to *gather_part.
  void texels(size_t i, uint64_t photons, std::vector<double>& value3, std::vector<double>& variance,
              double* gather_part = nullptr) const {
    const Mesh& mesh = *views[i].mesh;
    const size_t g0 = views[i].texel_offset;
    ReconstructParams params;
    params.max_radius = filter_radius;
    params.photons = double(std::max<uint64_t>(photons, 1));
    params.phantom_sq = acc.total_hits ? acc.total_sq / double(acc.total_hits) : 0.0;
    std::vector<double> guide;
    if (!direct.empty()) {  // the direct light guides the reconstruction
      guide.assign(areas[i].area.size(), 0.0);
      size_t k = covered_begin[i];
      for (size_t t = 0; t < guide.size(); ++t)
        if (areas[i].area[t] > 0.0) guide[t] = direct[k++].mean();
      params.guide = guide.data();
    }
    if (photons > 0) {
      reconstruct_indirect(areas[i], mesh.lightmap_width, mesh.lightmap_height,
                           {&acc.sum[3 * g0], &acc.sum_sq[g0], &acc.hits[g0]}, params, value3, variance);
    } else {
      value3.assign(3 * size_t(mesh.lightmap_width) * mesh.lightmap_height, 0.0);
      variance.assign(size_t(mesh.lightmap_width) * mesh.lightmap_height, 0.0);
    }
    if (photons > 0 && gather && !gather->empty()) combine_gather(i, value3, variance, gather_part);
    if (direct.empty()) return;
    size_t k = covered_begin[i];
    for (size_t t = 0; t < variance.size(); ++t) {
      if (!(areas[i].area[t] > 0.0)) continue;
      const DirectSums& d = direct[k++];
      if (d.count)
        for (int c = 0; c < 3; ++c) value3[3 * t + c] += d.rgb[c] / d.count;
      variance[t] += d.variance_of_mean(direct_noise);
    }
  }
};

// Texel t of a lightmap image (R, G, B, error: 4 floats a texel) from an
// estimate's value3 / variance.
void store_texel(const std::vector<double>& value3, const std::vector<double>& variance, size_t t, float* image) {
  for (int c = 0; c < 3; ++c) image[4 * t + c] = float(value3[3 * t + c]);
  image[4 * t + 3] = float(std::sqrt(variance[t]));
}

double percentile(std::vector<double>& v, double q) {
  if (v.empty()) return 0.0;
  const size_t k = std::min(v.size() - 1, size_t(q * double(v.size())));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

// Estimated error over all covered texels: sqrt(mean variance) / mean value,
// texels weighted equally.
struct ErrorEstimate {
  double relative = 0.0;
  double direct = 0.0;  // the same with the direct variance alone
  double gather = 0.0;  // ... with the final gather's part alone (photons do not lower it)
  double median = 0.0, p95 = 0.0;  // of the per-texel relative errors
  std::vector<double> per_texel;    // the per-texel relative errors (of texels with light)
  size_t dark_texels = 0;           // covered texels with no light (no relative error)
};

// The ordinary lightmaps' texels at one state of the bake: per mesh with own
// texels R, G, B and error per texel (the images before dilation, 0 where
// uncovered), and the error over all texels. One estimate serves the error
// check, the final gather's lookups and the final images: each costs a
// reconstruction of every lightmap (open scene at 2 %: five took a fifth of
// the bake).
struct Estimate {
  uint64_t photons = ~uint64_t(0);  // the state it was made from (~0: none yet)
  size_t gather_size = 0;
  ErrorEstimate error;
  std::vector<std::vector<float>> values;

  bool current(uint64_t p, const std::vector<DirectSums>& gather) const {
    return photons == p && gather_size == gather.size();
  }
};

void estimate(tbb::task_arena& arena, const Estimator& est, uint64_t photons, Estimate& out) {
  out.photons = photons;
  out.gather_size = est.gather ? est.gather->size() : 0;
  out.values.resize(est.views.size());
  ErrorEstimate& e = out.error;
  e = ErrorEstimate{};
  double var_sum = 0.0, value_sum = 0.0, var_direct = 0.0, var_gather = 0.0, count = 0.0;
  std::vector<double> value3, variance, per_texel;
  for (size_t i = 0; i < est.views.size(); ++i) {
    if (!est.views[i].texel_area) continue;
    arena.execute([&] { est.texels(i, photons, value3, variance, &var_gather); });
    std::vector<float>& img = out.values[i];
    img.assign(4 * variance.size(), 0.0f);
    for (size_t t = 0; t < variance.size(); ++t) {
      if (!(est.areas[i].area[t] > 0.0)) continue;
      store_texel(value3, variance, t, img.data());
      const double v = (value3[3 * t] + value3[3 * t + 1] + value3[3 * t + 2]) / 3.0;
      value_sum += v;
      var_sum += variance[t];
      count += 1.0;
      if (v > 0.0) per_texel.push_back(std::sqrt(variance[t]) / v);
      else ++e.dark_texels;
    }
  }
  for (size_t c = 0; c < est.csgs.size(); ++c) {
    if (!est.csgs[c].lightmap) continue;
    for (uint32_t sub = 0; sub < est.csgs[c].lightmap->sub_texel_count(); ++sub) {
      double v3[3];
      const double var = est.csg_texel(c, sub, photons, v3);
      const double v = (v3[0] + v3[1] + v3[2]) / 3.0;
      value_sum += v;
      var_sum += var;
      count += 1.0;
      if (v > 0.0) per_texel.push_back(std::sqrt(var) / v);
      else ++e.dark_texels;
    }
  }
  for (const DirectSums& d : est.direct) var_direct += d.variance_of_mean(est.direct_noise);
  if (count > 0.0 && value_sum > 0.0) {
    const double mean = value_sum / count;
    e.relative = std::sqrt(var_sum / count) / mean;
    e.direct = std::sqrt(var_direct / count) / mean;
    e.gather = std::sqrt(var_gather / count) / mean;
  }
  e.median = percentile(per_texel, 0.5);
  e.p95 = percentile(per_texel, 0.95);
  e.per_texel.swap(per_texel);
}

// The share of texels whose relative error is above `threshold` (dark texels count as below).
double share_above(const ErrorEstimate& e, double threshold) {
  const size_t n = e.per_texel.size() + e.dark_texels;
  if (n == 0) return 0.0;
  return double(std::count_if(e.per_texel.begin(), e.per_texel.end(), [&](double r) { return r > threshold; })) /
         double(n);
}

// A lightmap resolved from an OL: each covered texel shows the OL at its
// normal (bilinear over the bins), with that bin's error and hit count.
void resolve_ol(const ol::OrientationLightmap& map, const TexelAreas& areas, std::vector<float>& values,
                std::vector<float>& hits, std::vector<uint8_t>& filled) {
  for (size_t t = 0; t < areas.area.size(); ++t) {
    if (!(areas.area[t] > 0.0)) continue;
    const Vec3 n = areas.normal[t];
    filled[t] = 1;
    if (!map.finalized() || !(dot(n, n) > 0.0f)) continue;  // no photons, or no normal: black
    const Vec3 v = map.lookup(n);
    const uint32_t b = map.bin_of(n);
    for (int c = 0; c < 3; ++c) values[4 * t + c] = v[c];
    values[4 * t + 3] = float(map.radiosity_error(b));
    hits[t] = float(map.hits(b));
  }
}

// The side of the CSG solid's own texels: the carrier's texel side (its
// surface area per covered texel), so that both hold about as many photons.
double carrier_texel_size(const TexelAreas& areas, csg::DVec3 extent) {
  double area = 0.0, cover = 0.0;
  for (size_t t = 0; t < areas.area.size(); ++t) area += areas.area[t], cover += areas.coverage[t];
  if (area > 0.0 && cover > 0.0) return std::sqrt(area / cover);
  return 0.01 * std::max({extent.x, extent.y, extent.z, 1e-30});
}

// A carrier's lightmap: each covered texel averages the solid's sub-texels
// found at four points around its centre (a quarter texel out along the
// surface, then to the nearest point of the exact surface along the normal):
// a box filter over the texel's footprint, which resamples the solid's texels
// with less error and noise than one point. The search reaches 2% of the
// solid's size: the tessellation's distance from the exact surface (a
// 32-segment circle: 0.5% of its radius).
void transfer_csg(const Estimator& est, size_t c, uint64_t photons, const TexelAreas& areas, const Accumulators& acc,
                  std::vector<float>& values, std::vector<float>& hits, std::vector<uint8_t>& filled,
                  std::vector<std::string>& warnings, const Mesh& mesh) {
  const CsgView& cv = est.csgs[c];
  const csg::DVec3 size = cv.object->bounds_hi() - cv.object->bounds_lo();
  const double tolerance = 0.02 * std::max({size.x, size.y, size.z});
  uint32_t missed = 0;
  for (size_t t = 0; t < areas.area.size(); ++t) {
    if (!(areas.area[t] > 0.0)) continue;
    const Vec3 n = areas.normal[t];
    Vec3 tu, tv;
    make_frame(n, tu, tv);
    const float quarter = 0.25f * float(std::sqrt(areas.area[t] / std::max(double(areas.coverage[t]), 1e-3)));
    int64_t subs[4];
    int found = 0;
    for (int k = 0; k < 4; ++k) {
      const Vec3 p = areas.position[t] + tu * (k & 1 ? quarter : -quarter) + tv * (k & 2 ? quarter : -quarter);
      const int64_t sub = cv.lightmap->lookup(to_double(p), to_double(n), tolerance);
      if (sub < 0) continue;
      bool seen = false;
      for (int j = 0; j < found; ++j) seen = seen || subs[j] == sub;
      if (!seen) subs[found++] = sub;
    }
    if (found == 0) {
      ++missed;
      continue;  // filled by dilation from its neighbours
    }
    double sum3[3] = {0, 0, 0}, var = 0.0, hit_count = 0.0;
    for (int j = 0; j < found; ++j) {
      double v3[3];
      var += est.csg_texel(c, uint32_t(subs[j]), photons, v3);
      for (int ch = 0; ch < 3; ++ch) sum3[ch] += v3[ch];
      hit_count += acc.hits[cv.texel_offset + uint64_t(subs[j])];
    }
    for (int ch = 0; ch < 3; ++ch) values[4 * t + ch] = float(sum3[ch] / found);
    values[4 * t + 3] = float(std::sqrt(var) / found);  // the mean of `found` independent sub-texels
    hits[t] = float(hit_count);
    filled[t] = 1;
  }
  if (missed)
    warnings.push_back("mesh '" + mesh.name + "': " + std::to_string(missed) + " texels found no point of CSG solid '" +
                       cv.object->name() + "' within " + std::to_string(tolerance) +
                       " m (the mesh does not follow the solid there); they take their neighbours' values");
}

// A lightmap backed up by an OL (plm_scene_set_ol_group_backup): each
// texel's indirect part (its estimate minus its direct light) and the OL at
// its normal are combined by inverse variance, the OL's variance including its
// squared bias against the texel: the larger of the lightmap's mean of
// (texel - OL)^2 - both variances (unbiased for the mean squared bias) and the
// texel's own such difference where it exceeds two standard deviations.
void blend_backup(const ol::OrientationLightmap& map, const TexelAreas& areas, const std::vector<DirectSums>& direct,
                  size_t first_covered, const DirectNoise& noise, std::vector<double>& value3,
                  std::vector<double>& variance) {
  struct Parts {
    size_t t;
    double ind[3], var_ind, ol[3], var_ol, var_direct, direct[3], diff_sq;
  };
  std::vector<Parts> parts;
  size_t k = first_covered;
  double bias_sum = 0.0;
  for (size_t t = 0; t < areas.area.size(); ++t) {
    if (!(areas.area[t] > 0.0)) continue;
    Parts p{t, {0, 0, 0}, 0.0, {0, 0, 0}, 0.0, 0.0, {0, 0, 0}, 0.0};
    if (!direct.empty()) {
      const DirectSums& d = direct[k++];
      for (int c = 0; c < 3; ++c) p.direct[c] = d.count ? d.rgb[c] / d.count : 0.0;
      p.var_direct = d.variance_of_mean(noise);
    }
    for (int c = 0; c < 3; ++c) p.ind[c] = value3[3 * t + c] - p.direct[c];
    p.var_ind = std::max(0.0, variance[t] - p.var_direct);
    const Vec3 n = areas.normal[t];
    if (!(dot(n, n) > 0.0f)) continue;  // no normal: the texel keeps its own estimate
    const Vec3 o = map.lookup(n);
    for (int c = 0; c < 3; ++c) p.ol[c] = o[c];
    const double e = map.radiosity_error(map.bin_of(n));
    p.var_ol = e * e;
    const double diff = (p.ind[0] + p.ind[1] + p.ind[2] - p.ol[0] - p.ol[1] - p.ol[2]) / 3.0;
    p.diff_sq = diff * diff;
    bias_sum += diff * diff - p.var_ind - p.var_ol;
    parts.push_back(p);
  }
  if (parts.empty()) return;
  const double bias_sq = std::max(0.0, bias_sum / double(parts.size()));
  for (const Parts& p : parts) {
    // The texel's own evidence of bias counts too: where it differs from the OL by
    // more than both noises explain, the OL is biased there (a corner, a box top
    // sharing the floor's normal), and the texel keeps more of its own estimate.
    const double noise = p.var_ind + p.var_ol;
    const double local = p.diff_sq > 4.0 * noise ? p.diff_sq - noise : 0.0;  // beyond 2 sigma: evidence
    const double var_o = p.var_ol + std::max(bias_sq, local);
    // Weights 1/var; a texel with no variance estimate (or an exact OL) keeps the better one alone.
    const double wt = p.var_ind > 0.0 ? 1.0 / p.var_ind : 1e300, wo = var_o > 0.0 ? 1.0 / var_o : 1e300;
    const double a = wt / (wt + wo);
    for (int c = 0; c < 3; ++c) value3[3 * p.t + c] = p.direct[c] + a * p.ind[c] + (1.0 - a) * p.ol[c];
    variance[p.t] = p.var_direct + a * a * p.var_ind + (1.0 - a) * (1.0 - a) * var_o;
  }
}

}  // namespace

plm_bake_settings default_settings() {
  plm_bake_settings s;
  s.photon_count = 1000000;
  s.max_bounces = 1024;
  s.seed = 0;
  s.thread_count = 0;
  s.dilation = 8;
  s.target_error = 0.0;
  s.time_budget = 0.0;
  s.direct_samples = 64;
  s.filter_radius = 2;
  s.texel_value = PLM_TEXEL_CYCLES;
  s.sampler = PLM_SAMPLER_DEFAULT;
  return s;
}

BakeOutput bake(const Scene& scene, const plm_bake_settings& requested, const ProgressFn& progress) {
  const auto t_start = Clock::now();
  validate(scene, requested);
  BakeOutput out;
  // Refuse a bake that cannot fit before allocating for it.
  const MemoryEstimate memory = estimate_bake_memory(scene);
  out.stats.memory_estimate = memory.bytes;
  if (const uint64_t free = available_memory()) {
    // The largest lightmap, if any (a scene of L-system objects alone has no mesh).
    std::string where, which;
    if (memory.largest_bytes > 0) {
      const Mesh& largest = scene.meshes[memory.largest_mesh];
      where = " (mesh '" + largest.name + "', " + std::to_string(largest.lightmap_width) + " x " +
              std::to_string(largest.lightmap_height) + " texels: about " + format_bytes(memory.largest_bytes) + ")";
      which = " of '" + largest.name + "'";
    }
    if (memory.bytes > free)
      fail(PLM_ERROR_OUT_OF_MEMORY, "the bake would need about ", format_bytes(memory.bytes), " of memory", where,
           " but only ", format_bytes(free), " are free: lower the lightmap resolution", which,
           " or bake fewer objects at once");
    if (double(memory.bytes) > 0.6 * double(free))
      out.warnings.push_back("the bake may need about " + format_bytes(memory.bytes) + " of memory" + where +
                             ", close to the " + format_bytes(free) + " free");
  }
  // Orientation lightmaps do not steer: with no ordinary texel, the photon
  // count (or the time budget) decides.
  plm_bake_settings settings = requested;
  bool ordinary_texels = false;
  for (const Mesh& m : scene.meshes)
    ordinary_texels = ordinary_texels || scene.own_texels(m) || (m.has_lightmap() && m.csg_carrier >= 0);
  if (!ordinary_texels && settings.target_error > 0.0) {
    settings.target_error = 0.0;
    out.warnings.push_back("target_error ignored: it is measured over ordinary lightmap texels and every mesh "
                           "is lit through an orientation lightmap; the photon count or time budget decides");
  }
  double reported = 0.0;  // progress never goes back (the final gather reports from inside the photon pass)
  auto report = [&](double fraction, const char* stage) {
    reported = std::max(reported, std::min(1.0, fraction));
    if (progress && !progress(reported, stage)) fail(PLM_ERROR_CANCELLED, "the bake was cancelled");
  };
  auto over_budget = [&](double share) {
    return settings.time_budget > 0.0 && seconds_since(t_start) >= share * settings.time_budget;
  };
  report(0.0, "building the ray-tracing scene");

  const unsigned threads = settings.thread_count ? settings.thread_count
                                                 : std::max(1u, std::thread::hardware_concurrency());
  EmbreeScene accel(scene, threads);
  tbb::task_arena arena(static_cast<int>(threads));
  const Vec3 lo = accel.bounds_min(), hi = accel.bounds_max();
  if (!is_finite(lo) || !is_finite(hi) || lo.x > hi.x)
    fail(PLM_ERROR_INVALID_SCENE, "the scene has no triangle with a non-zero area");
  const Vec3 center = (lo + hi) * 0.5f;
  const float extent = length(hi - lo);
  const float radius = 0.5f * extent * 1.01f + 1e-6f * max_abs_component(center) + 1e-30f;

  report(0.02, "computing texel areas");
  std::vector<TexelAreas> areas(scene.meshes.size());
  std::vector<MeshView> views(scene.meshes.size());
  std::vector<std::vector<Vec3>> normals(scene.meshes.size());
  std::vector<CoveredTexel> covered;
  std::vector<size_t> covered_begin(scene.meshes.size(), 0);
  uint64_t texel_count = 0;
  for (size_t i = 0; i < scene.meshes.size(); ++i) {
    const Mesh& mesh = scene.meshes[i];
    normals[i] = triangle_normals(mesh);
    views[i] = {&mesh, texel_count, nullptr, normals[i].data()};
    covered_begin[i] = covered.size();
    if (mesh.has_lightmap()) areas[i] = compute_texel_areas(mesh);
    // OL meshes' lightmaps are resolved from their OL, CSG carriers' from their solid.
    if (scene.own_texels(mesh)) {
      views[i].texel_area = areas[i].area.data();
      const uint32_t n = mesh.lightmap_width * mesh.lightmap_height;
      for (uint32_t t = 0; t < n; ++t)
        if (areas[i].area[t] > 0.0) covered.push_back({uint32_t(i), t});
      texel_count += n;
    }
    add_mesh_warnings(mesh, mesh.has_lightmap() ? &areas[i] : nullptr, out.warnings);
  }
  // CSG solids: texels on their primitives' faces (split where the solid's
  // boundary cuts them) for those with a carrier, at the carrier's texel size.
  std::vector<std::unique_ptr<csg::CsgLightmap>> csg_maps(scene.csgs.size());
  std::vector<CsgView> csg_views(scene.csgs.size());
  for (size_t c = 0; c < scene.csgs.size(); ++c) {
    const CsgSolid& solid = scene.csgs[c];
    csg_views[c] = {solid.object.get(), nullptr, texel_count};
    covered_begin.push_back(covered.size());
    for (const std::string& w : solid.object->warnings()) out.warnings.push_back(w);
    if (solid.carrier < 0) continue;
    csg::CsgLightmapSettings ls;
    ls.texel_size = carrier_texel_size(areas[size_t(solid.carrier)], solid.object->bounds_hi() - solid.object->bounds_lo());
    // The solid's texels cover every face of every primitive, also the parts
    // its carrier never shows: at most 4 texels per covered carrier texel (at
    // least 4096 in all), so that a solid far larger than its carrier does not
    // make the classification at set-up run for minutes.
    double face_area = 0.0, cover = 0.0;
    for (uint32_t k = 0; k < solid.object->primitive_count(); ++k)
      for (double a : solid.object->primitive(k).area)
        if (std::isfinite(a) && a > 0.0) face_area += a;
    for (float cv : areas[size_t(solid.carrier)].coverage) cover += cv;
    const double budget_side = std::sqrt(face_area / std::max(4096.0, 4.0 * cover));
    if (budget_side > ls.texel_size) {
      ls.texel_size = budget_side;
      out.warnings.push_back("CSG solid '" + solid.object->name() + "': its primitives' faces (" +
                             std::to_string(face_area) + " m^2) are far larger than its carrier shows; its texels "
                             "are coarsened to " + std::to_string(budget_side) + " m");
    }
    csg_maps[c] = std::make_unique<csg::CsgLightmap>(*solid.object, ls);
    csg_views[c].lightmap = csg_maps[c].get();
    const uint32_t subs = csg_maps[c]->sub_texel_count();
    for (uint32_t t = 0; t < subs; ++t) covered.push_back({uint32_t(scene.meshes.size() + c), t});
    texel_count += subs;
  }
  std::vector<std::vector<uint32_t>> ol_bins;
  std::vector<uint32_t> ol_mesh_counts;
  std::vector<ol::OrientationLightmap> ols = build_ols(scene, ol_bins, ol_mesh_counts, out.warnings);
  std::vector<OlMeshView> ol_views(scene.meshes.size());
  for (size_t i = 0; i < scene.meshes.size(); ++i)
    if (scene.meshes[i].ol_group >= 0)
      ol_views[i] = {scene.meshes[i].ol_group, ol_bins[i].data(),
                     scene.ol_groups[size_t(scene.meshes[i].ol_group)].backup};

  // L-system objects: root OL areas and stub areas from the flattened object.
  if (!scene.lsystems.empty()) report(0.03, "estimating L-system OL areas");
  std::vector<ol::OctGrid> ls_grids;
  std::vector<lsystem::OlAreas> ls_areas;
  out.lsystems.resize(scene.lsystems.size());
  for (size_t l = 0; l < scene.lsystems.size(); ++l) {
    const lsystem::LSystemObject& obj = *scene.lsystems[l];
    ls_grids.emplace_back(obj.ol_resolution());
    LSystemOutput& lo = out.lsystems[l];
    lo.object = scene.lsystems[l];
    lo.root = std::make_unique<ol::OrientationLightmap>(obj.ol_resolution(), kOlBatches);
    arena.execute([&] { ls_areas.push_back(obj.estimate_areas(ls_grids.back(), out.warnings)); });
    lo.root->set_area(ls_areas.back().root, ls_areas.back().root_variance);
    lo.stats.resolution = obj.ol_resolution();
    lo.stats.primitives = ls_areas.back().primitives;
    lo.stats.truncated = ls_areas.back().truncated ? 1u : 0u;
    lo.stats.stub_instances = ls_areas.back().stub_instances;
    lo.stats.area = lo.root->total_area();
  }

  // Image textures: a TextureSet only when a material names one.
  std::unique_ptr<TextureSet> textures;
  if (scene.has_textures()) {
    report(0.04, "loading textures");
    textures = std::make_unique<TextureSet>(scene);
    for (const std::string& w : textures->warnings) out.warnings.push_back(w);
  }
  const std::vector<Emitter> emitters = build_emitters(scene, center, radius, textures.get());
  double emitted = 0.0;
  for (const Emitter& e : emitters) emitted += average(e.flux);
  if (!std::isfinite(emitted) || emitted > 1e30)
    fail(PLM_ERROR_INVALID_SCENE, "the lights emit ", emitted, " W together, beyond the engine's range "
         "(1e30 W): check light powers, colours and emission strengths");
  if (emitters.empty())
    fail(PLM_ERROR_INVALID_SCENE, "nothing lights the scene: it has no light with power, no emissive material and "
         "no world light, so every lightmap would be black");
  out.stats.seconds_setup = seconds_since(t_start);
  out.stats.emitted_power = emitted;

  // Faces pressed against other surfaces (tracing.h: in_contact).
  report(0.05, "finding faces in contact");
  std::vector<std::vector<uint8_t>> contact;  // per mesh: texels that may be pressed against another surface
  arena.execute([&] { contact = contact_candidates(accel.handle(), scene, views, 1e-6f * extent); });
  for (size_t i = 0; i < views.size(); ++i)
    if (!contact[i].empty()) views[i].contact = contact[i].data();

  const bool two_pass = settings.direct_samples > 0;
  const bool photon_pass = !two_pass || settings.max_bounces > 0;
  const double direct_end = photon_pass ? 0.35 : 0.95;

  // ---- Direct pass --------------------------------------------------------
  std::vector<DirectSums> direct;
  DirectNoise direct_noise;
  std::vector<DirectSums> gather;  // final gather per covered texel, if any
  std::vector<DirectPass::GatherInfo> gather_info;
  DirectNoise gather_noise;
  const auto t_direct = Clock::now();
  std::unique_ptr<DirectPass> direct_pass;
  if (two_pass) {
    direct.resize(covered.size());
    direct_pass = std::make_unique<DirectPass>(accel.handle(), views, csg_views, areas, emitters, settings, extent,
                                               textures.get());
    const DirectPass& pass = *direct_pass;
    std::vector<uint32_t> todo(covered.size());
    for (uint32_t i = 0; i < todo.size(); ++i) todo[i] = i;
    // Round 0 gives every texel direct_samples (with a target at most
    // kFirstTargetSamples, and if that is not enough and the phantom sample
    // dominates the estimate, round 1 the rest of direct_samples: loose
    // targets are met sooner). Later rounds:
    // texels without two samples yet get direct_samples * 2^round (texels
    // that see a light rarely, the sky through a window, need thousands);
    // with a target, while the direct part's RMS error is above 0.7 x target
    // (the rest of the budget is the photons'), each texel gets its share of
    // the fewest samples that reach it, re-estimated after each round. A
    // texel's variance v_i after n_i samples is taken to fall as
    // n^-kDirectConvergence (stratified samples over a shadow edge: n^-1.5;
    // plain noise: n^-1), so sum_i v_i (n_i / m_i)^a = budget is met with
    // the fewest samples by m_i = c w_i, w_i = (v_i n_i^a)^(1 / (a + 1)),
    // c = (sum_j w_j / budget)^(1 / a) (for a = 1: m_i ~ the per-sample
    // deviation). Where the noise is plainer, the next round adds the rest.
    const bool targeted = settings.target_error > 0.0;
    const uint32_t first = targeted ? std::min(settings.direct_samples, kFirstTargetSamples) : settings.direct_samples;
    std::vector<uint32_t> want(covered.size(), first);
    std::vector<double> weight(covered.size());
    const double max_total = double(std::max(first, settings.direct_samples)) * kMaxDirectGrowth;
    const uint32_t max_rounds = 16;
    for (uint32_t round = 0; round < max_rounds && !todo.empty(); ++round) {
      const double r0 = 0.05 + (direct_end - 0.05) * round / max_rounds;
      const double r1 = 0.05 + (direct_end - 0.05) * (round + 1) / max_rounds;
      run_in_groups(
          arena, todo.size(), 64,
          [&](uint64_t first_texel, uint64_t n) {
            tbb::parallel_for(tbb::blocked_range<uint64_t>(first_texel, first_texel + n, 16), [&](const auto& r) {
              for (uint64_t k = r.begin(); k < r.end(); ++k) {
                const CoveredTexel& c = covered[todo[k]];
                pass.sample_texel(c.mesh, c.texel, round, want[todo[k]], direct[todo[k]]);
              }
            });
          },
          [&](uint64_t done) {
            report(r0 + (r1 - r0) * double(done) / double(todo.size()), "direct light");
            return !over_budget(photon_pass ? 0.5 : 0.95);
          });
      // typical: a sample's RMS in a typical texel (each texel weighs the
      // same, however many samples the allocation gave it).
      double mean = 0.0, texel_sq = 0.0, sampled = 0.0, mean_var = 0.0;
      for (const DirectSums& d : direct) {
        mean += d.mean();
        if (d.count == 0) continue;
        texel_sq += d.sum_sq / d.count;
        sampled += 1.0;
      }
      const double texels = double(std::max<size_t>(direct.size(), 1));
      mean /= texels;
      direct_noise.typical = sampled > 0.0 ? std::sqrt(texel_sq / sampled) : 0.0;
      if (round == 0 && settings.sampler != PLM_SAMPLER_RANDOM) direct_noise.scale = calibrate_direct(arena, pass, covered, direct, first);
      double phantom_var = 0.0, sum_weight = 0.0;
      for (size_t i = 0; i < direct.size(); ++i) {
        const DirectSums& d = direct[i];
        const double v = d.variance_of_mean(direct_noise);
        mean_var += v;
        phantom_var += d.phantom_variance_of_mean(direct_noise);
        weight[i] = std::pow(v * std::pow(double(std::max(d.count, 1u)), kDirectConvergence),
                             1.0 / (kDirectConvergence + 1.0));
        sum_weight += weight[i];
      }
      mean_var /= texels;
      phantom_var /= texels;
      const double allowed = 0.7 * settings.target_error * mean;
      const bool refine = targeted && std::sqrt(mean_var) > allowed;
      // Far from the target a round aims at twice the allowed variance (the
      // rest is left to the next round's new estimate).
      const double aim = mean_var > 4.0 * allowed * allowed ? 2.0 : 1.0;
      const double budget = aim * allowed * allowed * texels;
      std::vector<uint32_t> next;
      // First up to direct_samples everywhere where the phantom sample
      // (variance_of_mean) is most of the estimate: it is no measure of a
      // texel's own noise to allocate by (dark texels of an interior).
      const bool top_up = refine && round == 0 && first < settings.direct_samples && phantom_var > 0.5 * mean_var;
      for (uint32_t i = 0; i < direct.size(); ++i) {
        const DirectSums& d = direct[i];
        double extra = 0.0;
        if (top_up) {
          extra = double(settings.direct_samples - first);
        } else if (refine) {
          extra = weight[i] * std::pow(sum_weight / budget, 1.0 / kDirectConvergence) - double(d.count);
          // At most 5x a texel's samples per round (rounds stay short, so the
          // time budget and cancelling are checked often) and kMaxDirectGrowth
          // x direct_samples in all (a target far out of reach ends).
          extra = std::min({extra, 4.0 * std::max(d.count, first), max_total - double(d.count)});
          if (extra < 1.0) extra = 0.0;
        }
        if (d.count < 2) extra = std::max(extra, double(settings.direct_samples) * double(1u << std::min(round + 1, 8u)));
        if (extra > 0.0) {
          want[i] = uint32_t(std::min(std::ceil(extra), 65536.0));
          next.push_back(i);
        }
      }
      todo.swap(next);
      if (over_budget(photon_pass ? 0.5 : 0.95)) break;
    }
    for (const DirectSums& d : direct) out.stats.direct_samples += d.count;
  }
  out.stats.seconds_direct = seconds_since(t_direct);

  // ---- Photon pass ----------------------------------------------------------
  Accumulators acc(texel_count, scene.meshes.size());
  const Estimator estimator{areas, views,        csg_views,     covered_begin,   direct, acc, settings.filter_radius,
                            direct_noise, &gather, &gather_info, &gather_noise};
  uint64_t photons = 0;
  Estimate last;  // the latest estimate
  const auto t_trace = Clock::now();
  if (photon_pass) {
    const bool steered = settings.target_error > 0.0 || settings.time_budget > 0.0;
    const uint64_t cap = settings.photon_count ? settings.photon_count : (uint64_t(1) << 40);
    const uint64_t batch_count = (cap + kBatchPhotons - 1) / kBatchPhotons;
    PhotonTracer tracer(scene, accel.handle(), views, csg_views, ol_views, emitters, settings, extent,
                        two_pass ? 1u : 0u, ls_grids, textures.get());
    std::vector<BatchOutput> batches;
    double truncated_flux = 0.0;
    // ---- Final gather -------------------------------------------------------
    // Where the indirect light is a small part of the light (an open sunlit
    // scene), photons pay for it with many photons per texel. A plain final
    // gather (seed 003) estimates it with few rays per texel: G = albedo x
    // radiosity (direct + photon estimate) of the texel a cosine ray from the
    // texel hits (0 for the sky: that is direct light). It runs once, after
    // kCheckBatches batches (a fixed point: deterministic), from the photon
    // estimate at that point -- under a target only if those photons alone
    // do not reach it; each texel then weighs photons and gather by
    // their variances (Estimator::combine_gather), so scenes where photons do
    // better (light through a window) lose only the gather's rays. Meshes
    // only: a CSG solid, an L-system or textures have no radiosity to look up.
    // Not with few bounces: its lookups carry every bounce, so it would add one.
    const bool gather_wanted = two_pass && scene.csgs.empty() && scene.lsystems.empty() && !textures &&
                               settings.max_bounces >= kGatherMinBounces;
    // Rays per texel: kGatherSamples, 4x as many for half the target error (2 % and above: 16).
    const uint32_t gather_samples =
        settings.target_error > 0.0
            ? uint32_t(std::clamp(kGatherSamples * std::pow(0.02 / settings.target_error, 2.0), double(kGatherSamples),
                                  double(kMaxGatherSamples)))
            : kGatherSamples;
    bool gathered = false;
    // Looks up `now`, the estimate before the gather.
    auto run_gather = [&](const Estimate& now) {
      gathered = true;
      if (over_budget(0.9)) return;
      std::vector<float> radiosity(3 * texel_count, 0.0f), error(texel_count, 0.0f);
      for (size_t i = 0; i < scene.meshes.size(); ++i) {
        const std::vector<float>& img = now.values[i];
        const size_t g0 = views[i].texel_offset;
        for (size_t t = 0; 4 * t < img.size(); ++t) {
          for (int c = 0; c < 3; ++c) radiosity[3 * (g0 + t) + c] = img[4 * t + c];
          error[g0 + t] = img[4 * t + 3];
        }
      }
      std::vector<std::vector<Vec3>> tri_albedo(scene.meshes.size());
      for (size_t i = 0; i < scene.meshes.size(); ++i) {
        const Mesh& mesh = scene.meshes[i];
        tri_albedo[i].resize(mesh.triangle_count());
        for (uint32_t t = 0; t < mesh.triangle_count(); ++t) tri_albedo[i][t] = tracer.material(mesh, t).albedo;
      }
      const DirectPass::GatherSource source{radiosity.data(), error.data(), &tri_albedo, acc.back_lit.data()};
      std::vector<DirectSums> sums(covered.size());
      std::vector<DirectPass::GatherInfo> info(covered.size());
      // In groups, so that cancelling and the time budget are checked several
      // times a second; texels left without rays keep the photon estimate.
      run_in_groups(
          arena, covered.size(), 64,
          [&](uint64_t first_texel, uint64_t n) {
            tbb::parallel_for(tbb::blocked_range<uint64_t>(first_texel, first_texel + n, 16), [&](const auto& r) {
              for (uint64_t k = r.begin(); k < r.end(); ++k)
                direct_pass->gather_texel(covered[k].mesh, covered[k].texel, 0, gather_samples, source, sums[k],
                                          info[k]);
            });
          },
          [&](uint64_t) {
            report(direct_end, "final gather");
            return !over_budget(0.9);
          });
      double texel_sq = 0.0, sampled = 0.0;
      for (const DirectSums& g : sums)
        if (g.count) texel_sq += g.sum_sq / g.count, sampled += 1.0;
      gather_noise.typical = sampled > 0.0 ? std::sqrt(texel_sq / sampled) : 0.0;
      gather.swap(sums);
      gather_info.swap(info);
    };
    uint64_t ol_hits = 0;
    uint64_t merged = 0, next_check = kCheckBatches;
    bool done = false;
    auto last_report = t_trace - std::chrono::seconds(1);
    run_in_groups(
        arena, batch_count, threads,
        [&](uint64_t first, uint64_t n) {
          if (batches.size() < n) batches.resize(n);
          tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, 1), [&](const tbb::blocked_range<uint64_t>& r) {
            for (uint64_t b = r.begin(); b < r.end(); ++b) {
              const uint64_t p0 = (first + b) * kBatchPhotons;
              tracer.trace_batch(p0, std::min<uint64_t>(kBatchPhotons, cap - p0), batches[b]);
            }
          });
        },
        [&](uint64_t end) {
          // Merge in batch order; with a target, check it at fixed batch counts.
          double fraction = double(end) / double(batch_count);
          for (uint64_t b = merged; b < end && !done; ++b) {
            const BatchOutput& bo = batches[b - merged];
            acc.merge(bo);
            for (const OlHit& h : bo.ol_hits) {
              ol::OrientationLightmap& map = ols[h.group];
              const ol::Vec3d c = map.grid().centre(h.bin);  // falls back into bin h.bin
              map.add_hit({float(c.x), float(c.y), float(c.z)}, {h.r, h.g, h.b}, uint32_t(b % kOlBatches));
            }
            ol_hits += bo.ol_hits.size();
            for (const LsHit& h : bo.ls_hits) {
              LSystemOutput& lo = out.lsystems[h.object];
              const ol::Vec3d c = lo.root->grid().centre(h.bin);  // falls back into bin h.bin
              const Vec3 n{float(c.x), float(c.y), float(c.z)}, rgb{h.r, h.g, h.b};
              const uint32_t batch = uint32_t(b % kOlBatches);
              lo.root->add_hit(n, rgb, batch);
              ++lo.stats.hits;
              const auto& areas = ls_areas[h.object];
              if (lo.object->ol_level() == 0 || areas.stubs_dropped) continue;
              auto it = lo.stubs.find(h.key);
              if (it == lo.stubs.end()) {
                it = lo.stubs.emplace(h.key, ol::OrientationLightmap(lo.root->resolution(), kOlBatches)).first;
                const auto a = areas.stubs.find(h.key);
                if (a != areas.stubs.end()) it->second.set_area(a->second, std::vector<double>(a->second.size(), 0.0));
              }
              it->second.add_hit(n, rgb, batch);
            }
            ol_hits += bo.ls_hits.size();
            out.stats.rays_traced += bo.rays;
            out.stats.paths_truncated += bo.truncated;
            truncated_flux += bo.truncated_flux;
            photons = std::min(cap, (b + 1) * kBatchPhotons);
            const bool targeted = settings.target_error > 0.0;
            if (gather_wanted && !gathered && b + 1 == kCheckBatches && !targeted) {
              estimate(arena, estimator, photons, last);
              run_gather(last);
            }
            if (targeted && b + 1 == next_check) {
              next_check = std::max(next_check + kCheckBatches, (next_check * 5 / 4) / kCheckBatches * kCheckBatches);
              // Photons cannot lower the direct part nor the gather's: once
              // theirs is under half the target, more photons would not reach
              // a target the other parts missed (the warning says so). Under a
              // target the gather runs only where the first photons do not
              // reach it (loose targets stay as fast as photons alone).
              const ErrorEstimate& e = last.error;
              for (int pass = 0; pass < 2; ++pass) {
                estimate(arena, estimator, photons, last);
                const double photon_err =
                    std::sqrt(std::max(0.0, e.relative * e.relative - e.direct * e.direct - e.gather * e.gather));
                done = e.relative <= settings.target_error || photon_err <= 0.5 * settings.target_error;
                if (done || !gather_wanted || gathered) break;
                run_gather(last);
              }
              fraction = std::max(fraction, std::min(1.0, std::pow(settings.target_error / std::max(e.relative, 1e-12), 2.0)));
            }
          }
          merged = end;
          if (settings.time_budget > 0.0)
            fraction = std::max(fraction, seconds_since(t_start) / settings.time_budget);
          done = done || over_budget(0.97);
          if (seconds_since(last_report) >= 0.1) {  // groups are small: progress a few times a second
            last_report = Clock::now();
            report(direct_end + (0.95 - direct_end) * std::min(fraction, 1.0), steered ? "tracing photons to the target" : "tracing photons");
          }
          return !done;
        },
        // One batch a thread per group: the batches' hits are merged while
        // they are still in cache (measured: +3 % rays/s on one thread against
        // groups of up to 1024 batches a thread, whose hits had left the cache).
        threads);
    // Fewer photons than kCheckBatches batches, no target: the gather comes last.
    if (gather_wanted && !gathered && photons > 0 && settings.target_error <= 0.0) {
      estimate(arena, estimator, photons, last);
      run_gather(last);
    }
    out.stats.photons_emitted = photons;
    out.stats.photon_hits = acc.total_hits + ol_hits;
    if (truncated_flux > 1e-4 * emitted * double(photons))
      out.warnings.push_back(std::to_string(out.stats.paths_truncated) + " photon paths reached max_bounces (" +
                             std::to_string(settings.max_bounces) + ") and were stopped, losing " +
                             std::to_string(100.0 * truncated_flux / (emitted * double(photons))) +
                             "% of the emitted power; raise max_bounces for albedos near 1");
  }
  out.stats.seconds_trace = seconds_since(t_trace);

  if (!last.current(photons, gather)) estimate(arena, estimator, photons, last);
  const ErrorEstimate& err = last.error;
  out.stats.error_estimate = err.relative;
  out.stats.error_direct = err.direct;
  out.stats.error_median = err.median;
  out.stats.error_p95 = err.p95;
  out.stats.error_above = share_above(err, 2.0 * (settings.target_error > 0.0 ? settings.target_error : err.relative));
  if (settings.target_error > 0.0 && err.relative > settings.target_error)
    out.warnings.push_back("the target error " + std::to_string(100.0 * settings.target_error) +
                           "% was not reached (estimated " + std::to_string(100.0 * err.relative) + "% after " +
                           std::to_string(photons) + " photons" + (over_budget(0.97) ? ", time budget spent" : "") +
                           "); lower the lightmap resolution or allow more time");

  // ---- Orientation lightmaps ------------------------------------------------
  out.ols.resize(ols.size());
  for (size_t g = 0; g < ols.size(); ++g) {
    ol::OrientationLightmap& map = ols[g];
    OlImage& img = out.ols[g];
    img.name = scene.ol_groups[g].name;
    img.resolution = map.resolution();
    const size_t n = map.bins();
    img.rgb.assign(3 * n, 0.0f);
    img.error.assign(n, 0.0f);
    img.area.resize(n);
    img.hits.resize(n);
    img.stats.resolution = img.resolution;
    img.stats.mesh_count = ol_mesh_counts[g];
    img.stats.area = map.total_area();
    if (photons > 0) map.finalize(photons);
    for (uint32_t b = 0; b < n; ++b) {
      img.area[b] = float(map.area(b));
      img.hits[b] = float(map.hits(b));
      img.stats.hits += map.hits(b);
      if (!map.finalized()) continue;
      double mean = 0.0;
      for (int c = 0; c < 3; ++c) {
        img.rgb[3 * b + c] = float(map.radiosity(b, c));
        mean += map.radiosity(b, c) / 3.0;
      }
      img.error[b] = float(map.radiosity_error(b));
      img.stats.flux += mean * kPiD * map.area(b);
    }
    if (photons > 0) img.stats.orphan_flux = map.orphan_flux() / double(photons);
  }
  // ---- L-system OLs ---------------------------------------------------------
  for (LSystemOutput& lo : out.lsystems) {
    if (photons > 0) {
      lo.root->finalize(photons);
      for (auto& [key, stub] : lo.stubs)
        if (stub.total_area() > 0.0) stub.finalize(photons);
    }
    lo.stats.stubs = lo.stubs.size();
    if (lo.root->finalized())
      for (uint32_t b = 0; b < lo.root->bins(); ++b) {
        double mean = 0.0;
        for (int c = 0; c < 3; ++c) mean += lo.root->radiosity(b, c) / 3.0;
        lo.stats.flux += mean * kPiD * lo.root->area(b);
      }
    const lsystem::GraphStats gs = lo.object->graph().stats();
    lo.stats.classes = gs.classes;
    lo.stats.cache_hits = gs.cache_hits;
    lo.stats.cache_misses = gs.cache_misses;
    lo.stats.cache_bytes = gs.peak_cached_bytes;
    lo.stats.class_bytes = gs.class_bytes;
  }
  // ---- Lightmaps ------------------------------------------------------------
  report(0.95, "writing lightmaps");
  out.lightmaps.resize(scene.meshes.size());
  std::vector<double> value3, variance;
  for (size_t i = 0; i < scene.meshes.size(); ++i) {
    const Mesh& mesh = scene.meshes[i];
    if (!mesh.has_lightmap()) continue;
    LightmapImage& img = out.lightmaps[i];
    img.width = mesh.lightmap_width;
    img.height = mesh.lightmap_height;
    const size_t n = size_t(img.width) * img.height;
    std::vector<float> values(4 * n, 0.0f);  // R, G, B, error: dilated together
    std::vector<uint8_t> filled(n, 0);
    img.hits.assign(n, 0.0f);
    img.coverage = areas[i].coverage;
    const bool backed_up = mesh.ol_group >= 0 && scene.ol_groups[size_t(mesh.ol_group)].backup;
    if (mesh.ol_group >= 0 && !backed_up) {
      resolve_ol(ols[size_t(mesh.ol_group)], areas[i], values, img.hits, filled);
    } else if (mesh.csg_carrier >= 0) {
      transfer_csg(estimator, size_t(mesh.csg_carrier), photons, areas[i], acc, values, img.hits, filled,
                   out.warnings, mesh);
    } else {
      if (backed_up && ols[size_t(mesh.ol_group)].finalized()) {
        arena.execute([&] { estimator.texels(i, photons, value3, variance); });
        blend_backup(ols[size_t(mesh.ol_group)], areas[i], direct, covered_begin[i], direct_noise, value3, variance);
        for (size_t t = 0; t < n; ++t)
          if (areas[i].area[t] > 0.0) store_texel(value3, variance, t, values.data());
      } else {
        values.swap(last.values[i]);  // the final estimate's texels
      }
      for (size_t t = 0; t < n; ++t) {
        if (!(areas[i].area[t] > 0.0)) continue;
        img.hits[t] = float(acc.hits[views[i].texel_offset + t]);
        filled[t] = 1;
      }
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

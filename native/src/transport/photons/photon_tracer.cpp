#include "transport/photons/photon_tracer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

#include "transport/materials/spectrum.h"
#include "transport/photons/photon_sampler.h"
#include "transport/rays/passage.h"

namespace plm {
namespace {

// A photon that reaches a smooth surface is weighted by cos(shading normal) /
// cos(geometric normal) of its arrival direction (the irradiance a texel holds
// is taken about the shading normal), at most this much: near grazing
// incidence the ratio has no bound, and its variance with it (what the cap
// loses: docs/design/texels.md, "Shading normals").
constexpr float kMaxShadingRatio = 16.0f;

// The base-3 radical inverse of i: the dispersed photons' wavelengths, stratified over the photon index.
double radical_inverse3(uint64_t i) {
  double r = 0.0, f = 1.0 / 3.0;
  for (; i; i /= 3, f /= 3.0) r += double(i % 3) * f;
  return r;
}

}  // namespace

PhotonTracer::PhotonTracer(const BakeScene& ctx)
    : scene_(ctx.scene), textures_(ctx.textures.get()), rtc_(ctx.rtc), views_(ctx.space.views),
      csg_views_(ctx.space.csg_views), ol_views_(ctx.ol_views), emitters_(ctx.emitters), ls_grids_(ctx.ls_ols.grids),
      settings_(ctx.settings), offset_scale_(1e-6f * ctx.extent), first_recorded_(ctx.settings.two_pass ? 1u : 0u),
      table_(ctx.emitters) {
  pick_offset_ = double(Rng(settings_.seed, ~0ull).next_float());
  seed_hash_ = {splitmix64(settings_.seed)};
  default_material_.albedo = {0.8f, 0.8f, 0.8f};
  mesh_only_ = !textures_ && csg_views_.empty() && scene_.lsystems.empty();
  layered_ = !ctx.layers.empty();
  directional_ = ctx.split.directional;
  if (ctx.lobes.any_lobes()) {
    lobes_ = &ctx.lobes;
    lambda_offset_ = double(Rng(settings_.seed, ~0ull - 1).next_float());
  }
  build_hit_tables();
  const TexelSpace& space = ctx.space;
  judged_groups_ = space.judged_groups;
  for (size_t u = 0; u < space.judged.size(); ++u) {
    if (space.judged[u] == kNoGroup) continue;
    const uint64_t first = u < views_.size() ? views_[u].texel_offset : csg_views_[u - views_.size()].texel_offset;
    unit_texels_.push_back({first, space.judged[u]});
  }
  std::sort(unit_texels_.begin(), unit_texels_.end());
}

uint32_t PhotonTracer::group_of_texel(uint32_t texel) const {
  auto it = std::upper_bound(unit_texels_.begin(), unit_texels_.end(), std::pair<uint64_t, uint32_t>{texel, kNoGroup});
  return it == unit_texels_.begin() ? kNoGroup : std::prev(it)->second;
}

template <bool kMeshOnly, bool kLobes>
void PhotonTracer::trace_counted(uint64_t index, lsystem::GraphHit& graph_hit, BatchOutput& out) const {
  const size_t h0 = out.hits.size(), c0 = out.caustic_hits.size();
  trace_photon<kMeshOnly, kLobes>(index, graph_hit, out);
  if (judged_groups_ == 0 || (out.hits.size() == h0 && out.caustic_hits.size() == c0)) return;
  constexpr uint32_t kMaxGroups = 8;  // a photon's first groups (a path seldom crosses more)
  uint32_t group[kMaxGroups], hits[kMaxGroups], n = 0;
  auto note = [&](const std::vector<Hit>& recorded, size_t first) {
    for (size_t k = first; k < recorded.size(); ++k) {
      const uint32_t g = group_of_texel(recorded[k].texel);
      if (g == kNoGroup) continue;
      const uint32_t i = uint32_t(std::find(group, group + n, g) - group);
      if (i < n) ++hits[i];
      else if (n < kMaxGroups) group[n] = g, hits[n++] = 1;
    }
  };
  note(out.hits, h0);
  note(out.caustic_hits, c0);
  for (uint32_t i = 0; i < n; ++i) {
    out.group_hits[group[i]] += hits[i];
    out.group_hits_sq[group[i]] += uint64_t(hits[i]) * hits[i];
  }
}

std::vector<std::vector<Vec3>> PhotonTracer::triangle_albedos() const {
  std::vector<std::vector<Vec3>> albedo(scene_.meshes.size());
  for (size_t i = 0; i < scene_.meshes.size(); ++i) {
    const Mesh& mesh = scene_.meshes[i];
    albedo[i].resize(mesh.triangle_count());
    for (uint32_t t = 0; t < mesh.triangle_count(); ++t) albedo[i][t] = material(mesh, t).albedo;
  }
  return albedo;
}

void PhotonTracer::trace_batch(uint64_t first, uint64_t count, BatchOutput& out) const {
  out.hits.clear();
  out.caustic_hits.clear();
  out.caustic_points.clear();
  out.ol_hits.clear();
  out.ls_hits.clear();
  out.back_meshes.clear();
  out.hit_layers.clear();
  out.caustic_layers.clear();
  out.hit_u.clear();
  out.caustic_u.clear();
  out.rays = out.truncated = 0;
  out.truncated_flux = 0.0;
  out.group_hits.assign(judged_groups_, 0);
  out.group_hits_sq.assign(judged_groups_, 0);
  lsystem::GraphHit graph_hit;
  if (layered_) return trace_layered_batch(first, count, graph_hit, out);
  if (lobes_) return trace_lobe_batch(first, count, graph_hit, out);
  if (mesh_only_)
    for (uint64_t i = first; i < first + count; ++i) trace_counted<true, false>(i, graph_hit, out);
  else
    for (uint64_t i = first; i < first + count; ++i) trace_counted<false, false>(i, graph_hit, out);
}

// Scenes with lobes: a function of its own, so that the plain loop above is compiled as without them.
__attribute__((noinline)) void PhotonTracer::trace_lobe_batch(uint64_t first, uint64_t count,
                                                               lsystem::GraphHit& graph_hit, BatchOutput& out) const {
  if (mesh_only_)
    for (uint64_t i = first; i < first + count; ++i) trace_counted<true, true>(i, graph_hit, out);
  else
    for (uint64_t i = first; i < first + count; ++i) trace_counted<false, true>(i, graph_hit, out);
}

// Scenes with light groups: each photon's hits tagged with its layer.
__attribute__((noinline)) void PhotonTracer::trace_layered_batch(uint64_t first, uint64_t count,
                                                                  lsystem::GraphHit& graph_hit, BatchOutput& out) const {
  for (uint64_t i = first; i < first + count; ++i) {
    if (lobes_) mesh_only_ ? trace_counted<true, true>(i, graph_hit, out) : trace_counted<false, true>(i, graph_hit, out);
    else mesh_only_ ? trace_counted<true, false>(i, graph_hit, out) : trace_counted<false, false>(i, graph_hit, out);
    out.hit_layers.resize(out.hits.size(), out.layer);
    out.caustic_layers.resize(out.caustic_hits.size(), out.layer);
  }
}

void PhotonTracer::build_hit_tables() {
  size_t tris = 0, texels = 0;
  for (const MeshView& v : views_) {
    tris += v.mesh->triangle_count();
    if (v.texel_area) texels += size_t(v.mesh->lightmap_width) * v.mesh->lightmap_height;
  }
  hit_tris_.resize(tris);
  covered_.resize(texels);
  hit_meshes_.resize(views_.size());
  std::vector<const Vec3*> normals(views_.size());
  size_t t0 = 0, c0 = 0;
  for (size_t m = 0; m < views_.size(); ++m) {
    const MeshView& v = views_[m];
    const Mesh& mesh = *v.mesh;
    const OlMeshView& ol = ol_views_[m];
    HitMesh& hm = hit_meshes_[m];
    hm = {hit_tris_.data() + t0, mesh.uv.data(), mesh.smooth() ? mesh.normals.data() : nullptr, v.contact,
          mesh.smooth() || v.contact, nullptr, v.texel_offset, mesh.lightmap_width, mesh.lightmap_height, ol.backup};
    normals[m] = &hit_tris_[t0].normal;
    for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
      HitTri& h = hit_tris_[t0 + t];
      h.normal = v.normals[t];
      h.degenerate = h.normal.x == 0.0f && h.normal.y == 0.0f && h.normal.z == 0.0f;
      if (!h.degenerate) make_frame(h.normal, h.frame_t, h.frame_b);
      const Vec3 albedo = material(mesh, t).albedo;
      h.roulette = std::fmin(1.0f, max_component(albedo));
      h.bounce = h.roulette > 0.0f ? albedo / h.roulette : Vec3{};
      h.ol_bin = ol.group >= 0 ? ol.splats[t].nearest : kNoBin;
    }
    t0 += mesh.triangle_count();
    if (v.texel_area) {
      const size_t n = size_t(mesh.lightmap_width) * mesh.lightmap_height;
      for (size_t k = 0; k < n; ++k) covered_[c0 + k] = v.texel_area[k] > 0.0 ? 1 : 0;
      hm.covered = covered_.data() + c0;
      c0 += n;
    }
  }
  surfaces_ = SurfaceMap(scene_, normals, sizeof(HitTri));
}

Vec3 PhotonTracer::flat_albedo(uint32_t id) const {
  return textures_ && !scene_.materials.empty() ? textures_->flat_albedo(id) : material_by_id(id).albedo;
}

template <bool kMeshOnly, bool kLobes>
void PhotonTracer::trace_photon(uint64_t index, lsystem::GraphHit& graph_hit, BatchOutput& out) const {
  PhotonSampler sampler(index, settings_, pick_offset_, seed_hash_);
  float u_pick, u[4];
  sampler.emission(u_pick, u);
  const size_t k = table_.choose(u_pick);
  const Emitter& em = emitters_[k];
  out.layer = em.layer;
  EmitterSample s = sample_emitter(em, u);
  if (!kMeshOnly && em.textured)  // the texture at the photon's origin: flux 2 pi L(x) A, unbiased whatever the mean
    s.weight = textures_->emission(*views_[em.mesh].mesh, em.material, em.triangle, s.bu, s.bv) *
               (2.0f * kPi * em.area);
  Vec3 flux = s.weight * (1.0f / table_.probability(k));
  if (!(flux.x > 0.0f || flux.y > 0.0f || flux.z > 0.0f)) return;  // max_component(flux) <= 0 without a libm fmaxf call

  TraceContext tc;
  if (!kMeshOnly) tc.hits.graph_hits = &graph_hit;
  Vec3 org = s.origin, dir = s.direction;
  struct NoPath {};
  [[maybe_unused]] std::conditional_t<kLobes, PathState, NoPath> path;
  for (uint32_t depth = 0;; ++depth) {
    RTCRayHit rh;
    rh.ray = make_ray(org, dir, std::numeric_limits<float>::infinity());
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    // The numbers of the bounce at this ray's hit and its direction in the
    // hit's frame do not depend on the hit: drawn here, before the ray is
    // cast, their latency (two square roots, the sine) overlaps Embree's
    // traversal instead of lying between the hit and the next ray. A path
    // that ends here drew them for nothing; the stream is the same either way.
    float v[3];
    sampler.bounce(depth, v);
    const Vec3 local = cosine_hemisphere(v[0], v[1]);
    rtcIntersect1(rtc_, tc.context(), &rh);
    ++out.rays;

    // The hit: a mesh triangle, the exact surface of a CSG solid, or an
    // L-system object (with what its GraphHit gives).
    const SurfaceHit h = surfaces_.hit<kMeshOnly>(rh, kMeshOnly ? nullptr : &graph_hit);
    Vec3 normal = h.normal, albedo;
    const Vec3 hit = h.point;
    float q = -1.0f;  // survival probability; set here for mesh hits, below for the others
    const HitTri* flat = nullptr;  // an untextured mesh triangle: albedo, frame and weight from the table
    const HitMesh* special = nullptr;  // a mesh hit that needs shading normals or a contact test
    switch (h.kind) {
      case SurfaceKind::None:
        return;
      case SurfaceKind::Triangle: {
        const HitMesh& hm = hit_meshes_[h.index];
        const HitTri& ht = hm.tris[h.prim];
        if (ht.degenerate) return;  // the photon stops
        if (hm.special) special = &hm;
        if (!kMeshOnly && textures_ && !scene_.materials.empty()) {
          const Mesh& mesh = *views_[h.index].mesh;
          albedo = textures_->albedo(mesh, mesh.material_ids[h.prim], h.prim, h.u, h.v);
          q = std::fmin(1.0f, max_component(albedo));
        } else {
          flat = &ht;
          q = ht.roulette;
        }
        break;
      }
      case SurfaceKind::CsgFace:
      case SurfaceKind::LSystem:
        if (!is_finite(normal)) return;
        albedo = flat_albedo(h.material);
        break;
    }
    if (depth == 0 && s.radius2 > 0.0f) {
      const Vec3 to_hit = hit - s.center;
      const float d2 = dot(to_hit, to_hit);
      flux *= d2 / (d2 + s.radius2);
    }
    const bool front = dot(dir, normal) < 0.0f;
    if (!front) normal = -normal;  // the side the photon arrived on
    if constexpr (kLobes) {
      if (special && pressed(*special, h, front, normal)) return;
      if (flat) albedo = material(*views_[h.index].mesh, h.prim).albedo;
      if (!lobe_hit(index, h, special, dir, front, normal, albedo, v, depth, flux, org, path, tc, out)) return;
      continue;
    }
    if (special && !special_hit(*special, h, dir, front, normal, flux)) return;
    if (h.kind == SurfaceKind::LSystem) {
      if (front)
        out.ls_hits.push_back({h.index, ls_grids_[h.index].bin(h.ol_normal), h.stub_key, flux.x, flux.y, flux.z});
    } else {
      if (front && depth >= first_recorded_) record(h, flux, out, dir, normal);
      if (h.kind == SurfaceKind::Triangle) {
        const uint32_t mesh = h.index;  // a copy: push_back takes a reference, which would keep h in memory
        if (!front && (out.back_meshes.empty() || out.back_meshes.back() != mesh)) out.back_meshes.push_back(mesh);
        if (front) {
          const HitMesh& hm = hit_meshes_[h.index];
          const uint32_t bin = hm.tris[h.prim].ol_bin;
          if (bin != kNoBin && (!hm.ol_backup || depth >= first_recorded_))
            out.ol_hits.push_back({mesh, h.prim, flux.x, flux.y, flux.z});
        }
      }
    }

    if (q < 0.0f) q = std::fmin(1.0f, max_component(albedo));
    if (q <= 0.0f || settings_.max_bounces == 0) return;
    if (depth >= settings_.max_bounces) {
      if (flat) albedo = material(*views_[h.index].mesh, h.prim).albedo;
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
    const bool triangle = h.kind == SurfaceKind::Triangle;
    tc.skip_geom = triangle ? SurfaceMap::mesh_geometry(h.index) : RTC_INVALID_GEOMETRY_ID;
    tc.skip_prim = triangle ? h.prim : RTC_INVALID_GEOMETRY_ID;
  }
}

// A hit in a scene with lobes. The hit is recorded by its path's class
// (PathState), then one part of the material goes on: the diffuse part or
// one lobe, chosen in proportion to their estimated reflectance seen from
// the photon, the photon surviving with probability min(1, their sum)
// (Russian roulette on the expected throughput [Arvo90], as pbrt's and
// Mitsuba's particle tracers pick a component by its albedo), so that the
// flux of the largest channel stays about constant. Lobes scatter about the
// shading normal (Cycles' closures do); the diffuse part as the plain loop
// does, with the shading ratio special_hit weighs it by.
inline bool PhotonTracer::lobe_hit(uint64_t index, const SurfaceHit& h, const HitMesh* special, Vec3& dir, bool front,
                                   Vec3 normal, Vec3 albedo, const float v[3], uint32_t depth, Vec3& flux, Vec3& org,
                                   PathState& path, TraceContext& tc, BatchOutput& out) const {
  Vec3 seen = flux;  // what the surface's irradiance records (about its shading normal)
  if (special && special->shading) seen *= shading_ratio(*special, h, dir, front, normal);
  Vec3 record = seen;  // what the texel gets: a Burley surface weighs light by its direction (bsdf::burley_receive)
  if (h.kind == SurfaceKind::Triangle && views_[h.index].burley) {
    const float r = views_[h.index].burley[h.prim];
    if (r >= 0.0f) record *= bsdf::burley_receive(-dot(dir, normal), r);
  }
  const PathClass cls = path.recorded();
  const bool wanted = cls != kDirect || first_recorded_ == 0;
  if (h.kind == SurfaceKind::LSystem) {
    if (front) out.ls_hits.push_back({h.index, ls_grids_[h.index].bin(h.ol_normal), h.stub_key, seen.x, seen.y, seen.z});
  } else {
    if (front && wanted) {
      const bool caustic = cls == kCaustic;
      record_into(h, record, caustic ? out.caustic_hits : out.hits, caustic ? out.caustic_u : out.hit_u, dir, normal);
    }
    if (keep_points_ && front && wanted && cls == kCaustic && h.kind == SurfaceKind::Triangle &&
        hit_meshes_[h.index].covered)
      out.caustic_points.push_back({h.point, record.x, record.y, record.z, h.index});
    if (h.kind == SurfaceKind::Triangle) {
      const uint32_t mesh = h.index;
      if (!front && (out.back_meshes.empty() || out.back_meshes.back() != mesh)) out.back_meshes.push_back(mesh);
      if (front) {
        const HitMesh& hm = hit_meshes_[h.index];
        const uint32_t bin = hm.tris[h.prim].ol_bin;
        if (bin != kNoBin && (!hm.ol_backup || wanted))
          out.ol_hits.push_back({mesh, h.prim, seen.x, seen.y, seen.z});
      }
    }
  }
  if (settings_.max_bounces == 0) return false;

  const uint32_t material = h.kind == SurfaceKind::Triangle ? views_[h.index].mesh->material_ids[h.prim] : h.material;
  const MaterialLobes& ml = lobes_->material(scene_.materials.empty() ? ~0u : material);
  const Vec3 wi = -dir;
  // The lobes' frame: the shading normal on smooth meshes (turned to the
  // photon's side; where the photon comes from behind it, the geometric one).
  Vec3 n = normal;
  if (ml.count && h.kind == SurfaceKind::Triangle && views_[h.index].mesh->smooth()) {
    const Vec3 ns = views_[h.index].mesh->shading_normal(h.prim, h.u, h.v, h.normal);
    const Vec3 side = front ? ns : -ns;
    if (dot(side, wi) > 0.0f) n = side;
  }
  const float cos_i = dot(wi, n);
  float e[1 + kMaxLobes];
  // Under SPECULAR layers the diffuse part is estimated by its scale's mean,
  // the layers by their tabulated albedo.
  // A Burley diffuse part by its directional albedo at the photon's incidence.
  e[0] = max_component(albedo) * ml.layer_mean;
  if (ml.burley >= 0.0f) e[0] *= lobes_->burley_albedo(ml.burley_albedo, dot(wi, normal));
  float total = e[0];
  for (uint32_t k = 0; k < ml.count; ++k) {
    const bsdf::LobeParams& lp = lobes_->lobe(ml.first + k);
    total += e[1 + k] = lp.type == PLM_LOBE_SPECULAR ? lp.tint.x * lobes_->layer(ml.first + k).albedo(cos_i)
                                                     : bsdf::lobe_albedo_estimate(lp, cos_i);
  }
  if (!(total > 0.0f)) return false;
  if (depth >= settings_.max_bounces) {
    ++out.truncated;
    out.truncated_flux += average(flux) * std::fmin(total, 1.0f);
    return false;
  }
  const float q = std::fmin(1.0f, total);
  if (v[2] >= q) return false;  // Russian roulette
  // The part: u in [0, total) over the parts' intervals; what is left of u
  // in its interval is a fresh uniform number (the lobe's reflect-or-refract).
  float u = v[2] / q * total;
  uint32_t c = 0;
  while (c < ml.count && u >= e[c]) u -= e[c++];
  if (!(e[c] > 0.0f)) return false;  // rounding onto an empty part
  const float u3 = std::fmin(u / e[c], 0.99999994f);
  const float scale = total / (q * e[c]);
  bool through = false;
  if (c == 0) {  // the diffuse part
    if (!(max_component(seen) > 0.0f)) return false;  // from behind the shading normal: no light, as special_hit
    flux = seen * albedo * scale;
    Vec3 t, b;
    make_frame(normal, t, b);
    const Vec3 local = cosine_hemisphere(v[0], v[1]);
    dir = t * local.x + b * local.y + normal * local.z;
    if (ml.layer_scale != MaterialLobes::kNoLayer)  // the layer's albedo towards where the photon leaves
      flux *= lobes_->diffuse_scale(ml.layer_scale, dot(dir, n));
    if (ml.burley >= 0.0f)  // Burley's law over Lambert's for this pair of directions
      flux *= bsdf::burley_factor(dot(wi, normal), local.z, dot(wi, dir), ml.burley);
    path.pane = false;
    path.cls = kIndirect;
  } else {
    const uint32_t li = ml.first + c - 1;
    const bsdf::LobeParams& lobe = lobes_->lobe(li);
    float ior = lobe.ior;
    if (lobes_->cauchy(li).b != 0.0f) {
      if (path.lambda_um == 0.0f) {  // the photon becomes one wavelength
        double x = radical_inverse3(index) + lambda_offset_;
        if (x >= 1.0) x -= 1.0;
        const float nm = kLambdaMinNm + float(x) * (kLambdaMaxNm - kLambdaMinNm);
        flux *= rgb_weight(nm);
        path.lambda_um = 1e-3f * nm;
      }
      ior = lobes_->cauchy(li).at(path.lambda_um);
    }
    Vec3 t, b;
    make_frame(n, t, b);
    const bsdf::LobeSample ls =
        bsdf::sample_lobe(lobe, {dot(wi, t), dot(wi, b), cos_i}, front, ior, v[0], v[1], u3);
    if (ls.event == bsdf::Event::Absorbed) return false;
    const Vec3 wo = t * ls.wo.x + b * ls.wo.y + n * ls.wo.z;
    through = ls.event != bsdf::Event::Reflected;
    // Leaving on the wrong side of the geometric surface (shading normals): lost, as in Cycles.
    if (through ? !(dot(wo, normal) < 0.0f) : !(dot(wo, normal) > 0.0f)) return false;
    flux *= ls.weight * scale;
    if (lobe.type == PLM_LOBE_SPECULAR) flux *= lobes_->layer(li).compensation(ls.wo.z);
    dir = wo;
    // The path's class: passages keep it, every other lobe event makes it a caustic.
    if (ls.event == bsdf::Event::Transparent && ml.passage == Passage::Transparent) {
      if (path.pane) path.specular();
    } else if (ls.event == bsdf::Event::Refracted && ml.passage == Passage::Pane &&
               h.kind == SurfaceKind::Triangle) {
      if (!path.pane) {
        path.pane = true;
        path.pane_front = front;
        path.pane_ior = ml.pane_ior;
        path.pane_normal = h.normal;
      } else if (PassageTracer::pane_pair(path.pane_normal, path.pane_front, path.pane_ior, h.normal, front,
                                          ml.pane_ior)) {
        path.pane = false;
      } else {
        path.specular();
      }
    } else {
      path.specular();
    }
  }
  org = offset_origin(h.point, through ? -normal : normal, offset_scale_);
  const bool triangle = h.kind == SurfaceKind::Triangle;
  tc.skip_geom = triangle ? SurfaceMap::mesh_geometry(h.index) : RTC_INVALID_GEOMETRY_ID;
  tc.skip_prim = triangle ? h.prim : RTC_INVALID_GEOMETRY_ID;
  return true;
}

// A hit on a smooth mesh, or on a triangle that may be pressed against
// another surface. A photon that finds a face in contact came through the
// other surface (both lie at the same distance): it is absorbed. On a smooth
// mesh the flux is weighted by cos(shading) / cos(geometric) at the hit
// (normal: the geometric normal turned to the side the photon arrived on).
// Returns false where the photon stops.
inline bool PhotonTracer::pressed(const HitMesh& hm, const SurfaceHit& h, bool front, Vec3 normal) const {
  if (!front || !hm.contact) return false;
  const int64_t texel = uv_texel(hm.uv + 6 * size_t(h.prim), h.u, h.v, hm.width, hm.height);
  return texel >= 0 && hm.contact[texel] && in_contact(rtc_, surfaces_, h.point, normal, h.index, h.prim, offset_scale_);
}

inline bool PhotonTracer::special_hit(const HitMesh& hm, const SurfaceHit& h, Vec3 dir, bool front, Vec3 normal,
                                      Vec3& flux) const {
  const float bu = h.u, bv = h.v;
  if (front && hm.contact) {
    const int64_t texel = uv_texel(hm.uv + 6 * size_t(h.prim), bu, bv, hm.width, hm.height);
    if (texel >= 0 && hm.contact[texel] && in_contact(rtc_, surfaces_, h.point, normal, h.index, h.prim, offset_scale_))
      return false;
  }
  if (!hm.shading) return true;
  const Vec3* c = hm.shading + 3 * size_t(h.prim);
  const Vec3 shading = c[0] * (1.0f - bu - bv) + c[1] * bu + c[2] * bv;
  const float len = length(shading);
  if (!(len > 0.0f)) return true;
  const float cos_s = -dot(dir, front ? shading : -shading) / len, cos_g = -dot(dir, normal);
  const float w = cos_s > 0.0f ? std::fmin(cos_s / cos_g, kMaxShadingRatio) : 0.0f;
  flux *= w;
  return w > 0.0f;  // light from behind the shading normal: no irradiance about it
}

// special_hit's weight alone (the lobe loop tests contact apart): cos(shading) / cos(geometric)
// of the arrival direction, at most kMaxShadingRatio, 0 from behind the shading normal.
inline float PhotonTracer::shading_ratio(const HitMesh& hm, const SurfaceHit& h, Vec3 dir, bool front,
                                         Vec3 normal) const {
  const Vec3* c = hm.shading + 3 * size_t(h.prim);
  const Vec3 shading = c[0] * (1.0f - h.u - h.v) + c[1] * h.u + c[2] * h.v;
  const float len = length(shading);
  if (!(len > 0.0f)) return 1.0f;
  const float cos_s = -dot(dir, front ? shading : -shading) / len, cos_g = -dot(dir, normal);
  return cos_s > 0.0f ? std::fmin(cos_s / cos_g, kMaxShadingRatio) : 0.0f;
}

// A front-side hit on a mesh or CSG solid into the texel (or CSG sub-texel)
// it falls in, if any.
inline void PhotonTracer::record(const SurfaceHit& h, Vec3 flux, BatchOutput& out, Vec3 dir, Vec3 normal) const {
  record_into(h, flux, out.hits, out.hit_u, dir, normal);
}

void PhotonTracer::add_direction(const SurfaceHit& h, Vec3 dir, Vec3 normal, std::vector<float>& u) const {
  Vec3 n = normal;
  if (h.kind == SurfaceKind::Triangle && views_[h.index].mesh->smooth()) {
    const Vec3 s = views_[h.index].mesh->shading_normal(h.prim, h.u, h.v, h.normal);
    n = dot(s, normal) < 0.0f ? -s : s;
  }
  const Vec3 w = direction_weight(-dir, n);
  u.insert(u.end(), {w.x, w.y, w.z});
}

inline void PhotonTracer::record_into(const SurfaceHit& h, Vec3 flux, std::vector<Hit>& hits, std::vector<float>& u,
                                      Vec3 dir, Vec3 normal) const {
  if (h.kind == SurfaceKind::CsgFace) {
    const CsgView& cv = csg_views_[h.index];
    if (!cv.lightmap) return;
    const int64_t sub = cv.lightmap->sub_texel_of_hit(h.prim, int(h.face), to_double(h.point));
    if (sub >= 0) {
      hits.push_back({uint32_t(cv.texel_offset + uint64_t(sub)), flux.x, flux.y, flux.z});
      if (directional_) add_direction(h, dir, normal, u);
    }
    return;
  }
  const HitMesh& hm = hit_meshes_[h.index];
  if (!hm.covered) return;
  // Outside the lightmap, and for NaN, nothing is recorded.
  const int64_t texel = uv_texel(hm.uv + 6 * size_t(h.prim), h.u, h.v, hm.width, hm.height);
  if (texel >= 0) {
    if (hm.covered[texel]) {
      // Fields stored in place: a Hit built on the stack and copied is
      // reloaded as one 16-byte word right after four 4-byte stores, which
      // store forwarding cannot serve (the loop's largest stall).
      const Hit zero{};
      hits.push_back(zero);  // an lvalue: the inlined push_back (an rvalue calls emplace_back)
      Hit& rec = hits.back();
      rec.texel = uint32_t(hm.texel_offset + texel);
      rec.r = flux.x;
      rec.g = flux.y;
      rec.b = flux.z;
      if (directional_) add_direction(h, dir, normal, u);
    }
  }
}

}  // namespace plm

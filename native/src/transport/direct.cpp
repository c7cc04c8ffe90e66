#include "transport/direct.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "util/rng.h"
#include "util/sobol.h"

namespace plm {

namespace {

// p_cos / p_light for the balance heuristic, as a finite ratio: cosine
// sampling's density cos_s / pi against light sampling's pick * d^2 /
// (cos_l * area). Written this way round, needle-thin emitters (cos_l * area
// underflowing to 0) give 0 instead of inf / inf = NaN weights.
float cos_weight_ratio(float cos_s, float cos_l_area, float pick, float distance) {
  const float r = (cos_s / kPi) * cos_l_area / (pick * distance * distance);
  if (!(r > 0.0f)) return 0.0f;  // 0 or NaN
  return std::fmin(r, 1e30f);
}

// Barycentric coordinates (b1, b2 of corners 1 and 2) of texel coordinates
// (x, y) in triangle t's lightmap UVs; false if the triangle has no UV area.
bool uv_barycentric(const Mesh& mesh, uint32_t t, double x, double y, double& b1, double& b2) {
  const float* uv = &mesh.uv[6 * size_t(t)];
  const double w = mesh.lightmap_width, h = mesh.lightmap_height;
  const double ax = uv[0] * w, ay = uv[1] * h;
  const double e1x = uv[2] * w - ax, e1y = uv[3] * h - ay, e2x = uv[4] * w - ax, e2y = uv[5] * h - ay;
  const double det = e1x * e2y - e2x * e1y;
  if (det == 0.0) return false;
  b1 = ((x - ax) * e2y - e2x * (y - ay)) / det;
  b2 = (e1x * (y - ay) - (x - ax) * e1y) / det;
  return true;
}

// The shading normal at point p of triangle tri of a smooth mesh, from p's
// barycentric coordinates.
Vec3 shading_normal_at(const Mesh& mesh, uint32_t tri, Vec3 p, Vec3 geometric) {
  const Vec3 p0 = mesh.vertex(tri, 0), e1 = mesh.vertex(tri, 1) - p0, e2 = mesh.vertex(tri, 2) - p0, d = p - p0;
  const float d11 = dot(e1, e1), d12 = dot(e1, e2), d22 = dot(e2, e2), d1 = dot(d, e1), d2 = dot(d, e2);
  const float det = d11 * d22 - d12 * d12;
  if (!(det > 0.0f)) return geometric;
  const float b1 = (d22 * d1 - d12 * d2) / det, b2 = (d11 * d2 - d12 * d1) / det;
  return mesh.shading_normal(tri, std::clamp(b1, 0.0f, 1.0f), std::clamp(b2, 0.0f, 1.0f), geometric);
}

// A light's unoccluded irradiance at p, 0 where the guess is not a finite
// non-negative number.
float irradiance_guess(const Emitter& e, Vec3 p, Vec3 n) {
  const float g = unoccluded_irradiance(e, p, n);
  return g >= 0.0f && g < 1e30f ? g : 0.0f;
}

}  // namespace

double DirectSums::pair_variance_of_mean() const {
  if (paired == 0) return 0.0;
  const double n = double(count);
  return (pair_sq * (n / double(paired)) + choice_sq) / (n * n);
}

void DirectSums::add(const DirectSums& o) {
  for (int c = 0; c < 3; ++c) rgb[c] += o.rgb[c];
  sum_sq += o.sum_sq;
  pair_sq += o.pair_sq;
  choice_sq += o.choice_sq;
  paired += o.paired;
  count += o.count;
}

double DirectSums::phantom_variance_of_mean(const DirectNoise& noise) const {
  if (paired == 0) return variance_of_mean(noise);
  const double m = mean(), n = double(count), typical = noise.typical;
  return noise.scale * (typical - m) * (typical - m) / (n * n);
}

double DirectSums::variance_of_mean(const DirectNoise& noise) const {
  const double typical = noise.typical;
  if (count == 0) return typical * typical;
  const double m = mean();
  if (paired == 0) return std::max(m * m, typical * typical);
  // Stratified samples: neighbouring strata differ by noise plus a little
  // gradient, so sum (a - b)^2 over pairs bounds the sum of the samples'
  // variances (Var(a) + Var(b) + (mean difference)^2) without counting the
  // texel's smooth variation as noise, as a plain sample variance would.
  const double n = double(count);
  return noise.scale * (pair_sq * (n / double(paired)) + choice_sq + (typical - m) * (typical - m)) / (n * n);
}

DirectPass::DirectPass(RTCScene rtc, const std::vector<MeshView>& views, const std::vector<CsgView>& csgs,
                       const std::vector<TexelAreas>& areas, const std::vector<Emitter>& emitters,
                       const plm_bake_settings& settings, float scene_extent, const TextureSet* textures)
    : rtc_(rtc), views_(views), csgs_(csgs), areas_(areas), emitters_(emitters), textures_(textures),
      seed_(settings.seed),
      cycles_window_(settings.texel_value == PLM_TEXEL_CYCLES), sobol_(settings.sampler != PLM_SAMPLER_RANDOM),
      offset_scale_(1e-6f * scene_extent), table_(emitters),
      all_lights_(emitters.size() <= kAllLights),
      local_choice_(!all_lights_ && emitters.size() <= kMaxLocalChoice) {
  if (!all_lights_ && emitters.size() <= kCandidates)
    for (uint32_t k = 0; k < emitters.size(); ++k) all_candidates_.push_back(k);
  triangle_emitter_.resize(views.size());
  for (size_t k = 0; k < emitters.size(); ++k) {
    if (emitters[k].kind != EmitterKind::Triangle) continue;
    std::vector<int32_t>& map = triangle_emitter_[emitters[k].mesh];
    if (map.empty()) map.assign(views[emitters[k].mesh].mesh->triangle_count(), -1);
    map[emitters[k].triangle] = int32_t(k);
    has_triangle_emitters_ = true;
    if (emitters[k].textured) has_textured_emitters_ = true;
  }
}

// The surface point at texel coordinates (x, y) (texel units), if a triangle covers it.
bool DirectPass::surface_point(uint32_t mesh_id, uint32_t texel, float x, float y, Vec3& p, Vec3& n,
                               uint32_t& tri) const {
  const Mesh& mesh = *views_[mesh_id].mesh;
  const TexelAreas& ta = areas_[mesh_id];
  for (uint32_t k = ta.tri_begin[texel]; k < ta.tri_begin[texel + 1]; ++k) {
    const uint32_t t = ta.tri_ids[k];
    double b1, b2;
    const double eps = -1e-6;
    if (!uv_barycentric(mesh, t, x, y, b1, b2) || b1 < eps || b2 < eps || b1 + b2 > 1.0 - eps) continue;
    const Vec3 p0 = mesh.vertex(t, 0), p1 = mesh.vertex(t, 1), p2 = mesh.vertex(t, 2);
    p = p0 + (p1 - p0) * float(b1) + (p2 - p0) * float(b2);
    n = views_[mesh_id].normals[t];
    tri = t;
    return true;
  }
  return false;
}

// A point uniform over the part of texel (tx, ty) that the mesh covers:
// clip each touching triangle to the texel square, pick a piece by area, then
// a fan triangle of it by area, then a uniform point. For barely covered
// texels, where stratified points in the square would almost all miss.
bool DirectPass::point_in_pieces(uint32_t mesh_id, uint32_t texel, const float u[3], Vec3& p, Vec3& n,
                                 uint32_t& tri) const {
  const Mesh& mesh = *views_[mesh_id].mesh;
  const TexelAreas& ta = areas_[mesh_id];
  const double w = mesh.lightmap_width, h = mesh.lightmap_height;
  const double tx = texel % mesh.lightmap_width, ty = texel / mesh.lightmap_width;
  double pieces[16][2 * detail::kMaxPolygon];
  int sizes[16];
  double piece_area[16];
  uint32_t piece_tri[16];
  int count = 0;
  double total = 0.0;
  for (uint32_t k = ta.tri_begin[texel]; k < ta.tri_begin[texel + 1] && count < 16; ++k) {
    const uint32_t t = ta.tri_ids[k];
    const float* uv = &mesh.uv[6 * size_t(t)];
    const double corners[6] = {uv[0] * w, uv[1] * h, uv[2] * w, uv[3] * h, uv[4] * w, uv[5] * h};
    double a[2 * detail::kMaxPolygon], b[2 * detail::kMaxPolygon];
    int m = detail::clip_polygon(corners, 3, 0, tx, -1.0, a);
    m = detail::clip_polygon(a, m, 0, tx + 1.0, 1.0, b);
    m = detail::clip_polygon(b, m, 1, ty, -1.0, a);
    m = detail::clip_polygon(a, m, 1, ty + 1.0, 1.0, pieces[count]);
    if (m < 3) continue;
    const double area = polygon_area(pieces[count], m);
    if (!(area > 0.0)) continue;
    sizes[count] = m;
    piece_area[count] = area;
    piece_tri[count] = t;
    total += area;
    ++count;
  }
  if (count == 0) return false;
  double pick = u[0] * total;
  int c = 0;
  while (c + 1 < count && pick > piece_area[c]) pick -= piece_area[c++];
  const double* poly = pieces[c];
  // Fan triangle (0, i, i + 1) chosen by area, reusing the remainder of the pick.
  double fan_pick = pick;
  int i = 1;
  double fan[6];
  for (;; ++i) {
    fan[0] = poly[0], fan[1] = poly[1], fan[2] = poly[2 * i], fan[3] = poly[2 * i + 1];
    fan[4] = poly[2 * i + 2], fan[5] = poly[2 * i + 3];
    const double a = polygon_area(fan, 3);
    if (i + 2 >= sizes[c] || fan_pick <= a) break;
    fan_pick -= a;
  }
  double s = u[1], t = u[2];
  if (s + t > 1.0) {
    s = 1.0 - s;
    t = 1.0 - t;
  }
  const float x = float(fan[0] + s * (fan[2] - fan[0]) + t * (fan[4] - fan[0]));
  const float y = float(fan[1] + s * (fan[3] - fan[1]) + t * (fan[5] - fan[1]));
  // Barycentric coordinates in the chosen triangle, clamped against rounding.
  const uint32_t tt = piece_tri[c];
  const float* uv = &mesh.uv[6 * size_t(tt)];
  const float ax = uv[0] * float(w), ay = uv[1] * float(h);
  const float e1x = uv[2] * float(w) - ax, e1y = uv[3] * float(h) - ay;
  const float e2x = uv[4] * float(w) - ax, e2y = uv[5] * float(h) - ay;
  const float det = e1x * e2y - e2x * e1y;
  float b1 = ((x - ax) * e2y - e2x * (y - ay)) / det, b2 = (e1x * (y - ay) - (x - ax) * e1y) / det;
  b1 = std::clamp(b1, 0.0f, 1.0f);
  b2 = std::clamp(b2, 0.0f, 1.0f - b1);
  const Vec3 p0 = mesh.vertex(tt, 0), p1 = mesh.vertex(tt, 1), p2 = mesh.vertex(tt, 2);
  p = p0 + (p1 - p0) * b1 + (p2 - p0) * b2;
  n = views_[mesh_id].normals[tt];
  tri = tt;
  return true;
}

// The triangle Blender's bake rasterizer gives a texel: the last one (in
// triangle order) that covers its centre, edges included; -1 for none.
int64_t DirectPass::centre_owner(uint32_t mesh_id, uint32_t texel) const {
  const Mesh& mesh = *views_[mesh_id].mesh;
  const TexelAreas& ta = areas_[mesh_id];
  const double x = double(texel % mesh.lightmap_width) + 0.5, y = double(texel / mesh.lightmap_width) + 0.5;
  int64_t owner = -1;
  for (uint32_t k = ta.tri_begin[texel]; k < ta.tri_begin[texel + 1]; ++k) {
    const uint32_t t = ta.tri_ids[k];
    double b1, b2;
    const double eps = 1e-9;
    if (uv_barycentric(mesh, t, x, y, b1, b2) && b1 >= -eps && b2 >= -eps && b1 + b2 <= 1.0 + eps) owner = t;
  }
  return owner;
}

// The point Cycles 3.4 bakes for texel coordinates (x, y) of a texel owned by
// triangle tri: the barycentric coordinates (u of corner 0, v of corner 1) of
// (x, y), folded back into the triangle by mirror repeat, u into [0, 1] and
// then v into [0, 1 - u] (Cycles' bake_clamp_mirror_repeat). Inside the
// triangle this is the point itself; a window that crosses an edge samples
// the owner's side twice instead of the neighbour's.
Vec3 DirectPass::mirrored_point(uint32_t mesh_id, uint32_t tri, float x, float y) const {
  const Mesh& mesh = *views_[mesh_id].mesh;
  double b1 = 0.0, b2 = 0.0;
  uv_barycentric(mesh, tri, x, y, b1, b2);  // the owner has UV area: it covers the centre
  auto mirror = [](double t, double range) {
    if (!(range > 0.0)) return 0.0;
    const double q = t / range, f = std::floor(q), r = q - f;
    return (int64_t(f) & 1 ? 1.0 - r : r) * range;
  };
  const double u = mirror(1.0 - b1 - b2, 1.0);
  const double v = mirror(b1, 1.0 - u);
  const Vec3 p0 = mesh.vertex(tri, 0), p1 = mesh.vertex(tri, 1), p2 = mesh.vertex(tri, 2);
  return p0 * float(u) + p1 * float(v) + p2 * float(1.0 - u - v);
}

bool DirectPass::window_map(uint32_t mesh_id, uint32_t tri, float ox, float oy, float size, Vec3& base, Vec3& du,
                            Vec3& dv) const {
  const Mesh& mesh = *views_[mesh_id].mesh;
  double a1, a2, x1, x2, y1, y2;  // barycentrics at (ox, oy), (ox + 1, oy), (ox, oy + 1)
  if (!uv_barycentric(mesh, tri, ox, oy, a1, a2) || !uv_barycentric(mesh, tri, double(ox) + 1.0, oy, x1, x2) ||
      !uv_barycentric(mesh, tri, ox, double(oy) + 1.0, y1, y2))
    return false;
  const double d1x = x1 - a1, d2x = x2 - a2, d1y = y1 - a1, d2y = y2 - a2;
  for (int c = 0; c < 4; ++c) {
    const double cx = c & 1 ? size : 0.0, cy = c & 2 ? size : 0.0;
    const double b1 = a1 + d1x * cx + d1y * cy, b2 = a2 + d2x * cx + d2y * cy;
    if (!(b1 >= 0.0 && b2 >= 0.0 && b1 + b2 <= 1.0)) return false;
  }
  const Vec3 p0 = mesh.vertex(tri, 0), p1 = mesh.vertex(tri, 1), p2 = mesh.vertex(tri, 2);
  const csg::DVec3 q0 = to_double(p0), e1 = to_double(p1) - q0, e2 = to_double(p2) - q0;
  base = to_float(q0 + e1 * a1 + e2 * a2);
  du = to_float(e1 * d1x + e2 * d2x);
  dv = to_float(e1 * d1y + e2 * d2y);
  return true;
}

DirectPass::TexelWindow DirectPass::texel_window(uint32_t mesh_id, uint32_t texel, uint32_t m) const {
  const uint32_t width = views_[mesh_id].mesh->lightmap_width;
  const float x0 = float(texel % width), y0 = float(texel / width);
  TexelWindow tw;
  tw.owner = cycles_window_ && areas_[mesh_id].coverage[texel] >= 0.5f ? centre_owner(mesh_id, texel) : -1;
  const bool window = tw.owner >= 0;
  tw.origin_x = window ? x0 + 0.25f : x0, tw.origin_y = window ? y0 + 0.25f : y0;
  tw.side = window ? 0.5f / float(m) : 1.0f / float(m);
  tw.sparse = !window && areas_[mesh_id].coverage[texel] < 0.5f;
  tw.affine = window && window_map(mesh_id, uint32_t(tw.owner), tw.origin_x, tw.origin_y, 0.5f, tw.base, tw.du, tw.dv);
  return tw;
}

bool DirectPass::texel_point(const TexelWindow& tw, uint32_t mesh_id, uint32_t texel, float x, float y,
                             const float w[3], Vec3& p, Vec3& n, uint32_t& tri) const {
  if (tw.sparse) return point_in_pieces(mesh_id, texel, w, p, n, tri);
  if (tw.owner < 0) return surface_point(mesh_id, texel, x, y, p, n, tri);
  tri = uint32_t(tw.owner);
  p = tw.affine ? tw.base + tw.du * (x - tw.origin_x) + tw.dv * (y - tw.origin_y) : mirrored_point(mesh_id, tri, x, y);
  n = views_[mesh_id].normals[tri];
  return true;
}

float DirectPass::local_shares(Vec3 p, Vec3 n, const uint32_t* candidates, size_t count, float* share) const {
  float total = 0.0f;
  for (size_t i = 0; i < count; ++i) {
    share[i] = irradiance_guess(emitters_[candidates[i]], p, n);
    total += share[i];
  }
  if (!(total > 0.0f)) return 0.0f;
  const float scale = 0.9f / total;
  for (size_t i = 0; i < count; ++i) share[i] *= scale;
  return 0.9f;
}

void DirectPass::select_candidates(Vec3 p, Vec3 n, uint32_t* chosen, ChoiceScratch& scratch) const {
  std::vector<float>& guess = scratch.guess;
  std::vector<uint32_t>& order = scratch.order;
  guess.resize(emitters_.size());
  order.resize(emitters_.size());
  for (uint32_t i = 0; i < emitters_.size(); ++i) {
    guess[i] = irradiance_guess(emitters_[i], p, n);
    order[i] = i;
  }
  std::nth_element(order.begin(), order.begin() + kCandidates, order.end(), [&](uint32_t a, uint32_t b) {
    return guess[a] > guess[b] || (guess[a] == guess[b] && a < b);
  });
  std::sort(order.begin(), order.begin() + kCandidates);
  for (uint32_t i = 0; i < kCandidates; ++i) {
    chosen[i] = order[i];
    scratch.slot_of[order[i]] = int32_t(i);
  }
  scratch.others.clear();
  scratch.others_cdf.clear();
  double sum = 0.0;
  for (uint32_t k = 0; k < emitters_.size(); ++k) {
    if (scratch.slot_of[k] >= 0 || !(table_.probability(k) > 0.0f)) continue;
    sum += table_.probability(k);
    scratch.others.push_back(k);
    scratch.others_cdf.push_back(sum);
  }
}

void DirectPass::sample_texel(uint32_t mesh_id, uint32_t texel, uint32_t round, uint32_t samples,
                              DirectSums& sums) const {
  if (emitters_.empty()) return;
  // A CSG sub-texel: points from its lightmap; rays leave the exact surface by
  // the origin offset alone (a ray may rightly hit the primitive it leaves).
  const CsgView* csg = mesh_id >= views_.size() ? &csgs_[mesh_id - views_.size()] : nullptr;
  const uint64_t global = (csg ? csg->texel_offset : views_[mesh_id].texel_offset) + texel;
  Rng rng(seed_ ^ 0x9E3779B9u, (global << 8) | (round & 0xFF));
  const uint32_t m = std::max(1u, uint32_t(std::ceil(std::sqrt(double(samples)))));
  const uint32_t n = m * m;
  TraceContext tc;
  tc.skip_geom = csg ? RTC_INVALID_GEOMETRY_ID : mesh_id;
  TexelWindow tw;  // a CSG sub-texel: strata over [0, 1]^2 of its lightmap
  if (csg) tw.side = 1.0f / float(m);
  else tw = texel_window(mesh_id, texel, m);
  const bool sparse = tw.sparse;
  const float origin_x = tw.origin_x, origin_y = tw.origin_y, side = tw.side;
  const uint32_t pick_key = rng.next_u32();
  const uint32_t sobol_key = rng.next_u32();
  const Mesh* smooth = !csg && views_[mesh_id].mesh->smooth() ? views_[mesh_id].mesh : nullptr;
  const uint8_t* contact = csg ? nullptr : views_[mesh_id].contact;
  const SobolGroup light_dims(sobol_key, 0), mis_dims(sobol_key, 1), piece_dims(sobol_key, 2), surface_dims(sobol_key, 3);
  uint32_t previous = ~0u;  // the last accepted stratum, and its value
  double previous_value = 0.0;
  // With the local choice, pairs are two successive samples of the same
  // light: the choice is stratified, so pairs of different lights would count
  // the lights' differences as noise (11 lights: 80x the variance). (With the
  // choice by power, beyond kMaxLocalChoice lights, a texel has fewer samples
  // than lights: pairs of neighbouring strata, as with all lights.)
  // What the choice does add is the spread of each light's sample count n_k
  // around n p_k: the stratum of u_pick that holds the boundary between two
  // lights' intervals gives its one sample to either (variance f (1 - f),
  // 1/6 on average), which moves the estimate by the difference of the two
  // lights' sample means / n. So choice_sq gets (mean_a - mean_b)^2 / 6 for
  // each two lights with samples that follow each other in u_pick (lights
  // without samples between them have narrow intervals: skipped).
  // Per-light tallies live in per-thread scratch (no allocation per texel
  // once it has grown to the light count).
  thread_local ChoiceScratch scratch;
  if (local_choice_ && scratch.tallies.size() < emitters_.size()) scratch.tallies.resize(emitters_.size());
  // The candidates of the local choice: all lights, or with more than
  // kCandidates the brightest (by unoccluded irradiance) at the texel's first
  // point, scratch.slot_of[k] their place (-1: not a candidate).
  const bool select = local_choice_ && emitters_.size() > kCandidates;
  // The local choice's shares, from the lights' unoccluded irradiance at the
  // texel's first point: per point they cost 2.5x the direct pass's time
  // with 48-100 lights for no lower error.
  bool chosen_here = false;
  float share[kCandidates], local = 0.0f;
  uint32_t chosen[kCandidates];
  const uint32_t* const candidates = select ? chosen : all_candidates_.data();
  const size_t candidate_count = select ? kCandidates : all_candidates_.size();
  if (select && scratch.slot_of.size() < emitters_.size()) scratch.slot_of.resize(emitters_.size(), -1);
  // Every light is sampled with probability 1 in all-lights mode.
  auto probability = [&](size_t i) {
    if (all_lights_) return 1.0f;
    if (!local_choice_) return table_.probability(i);
    const int32_t slot = select ? scratch.slot_of[i] : int32_t(i);
    return (slot >= 0 ? share[slot] : 0.0f) + (1.0f - local) * table_.probability(i);
  };
  // Samples go in chunks: first their shadow rays, traced in packets, then
  // each sample in turn (the MIS ray, the sums), so every sum adds the same
  // numbers in the same order as sample by sample.
  constexpr uint32_t kChunk = 8;
  struct Pending {
    Vec3 origin, normal, shading, e;  // normal: geometric; shading: the interpolated one (smooth meshes)
    float v[2];
    size_t k;
    uint32_t tri;
    bool inside, contact;
  };
  Pending chunk[kChunk];
  RayPacket packet;
  Vec3 lane_value[RayPacket::kLanes];  // a lane's irradiance if nothing blocks it
  uint32_t lane_sample[RayPacket::kLanes];
  auto trace_packet = [&] {
    const unsigned lanes = packet.size;
    packet.occluded(rtc_);
    for (unsigned l = 0; l < lanes; ++l)
      if (!packet.blocked(l)) chunk[lane_sample[l]].e += lane_value[l];
  };
  for (uint32_t j0 = 0; j0 < n; j0 += kChunk) {
    const uint32_t chunk_size = std::min(kChunk, n - j0);
    for (uint32_t c = 0; c < chunk_size; ++c) {
      const uint32_t j = j0 + c;
      Pending& ps = chunk[c];
      ps.inside = ps.contact = false;
      ps.e = {0, 0, 0};
      float x = origin_x + (float(j % m) + rng.next_float()) * side;
      float y = origin_y + (float(j / m) + rng.next_float()) * side;
      Vec3 p, normal;
      uint32_t tri;
      // Light choice and light sample: a 4D Sobol point per sample (random
      // otherwise, with the choice stratified through a permutation: tied to j
      // it would follow the strata's rows, so each light would be sampled in
      // one band of the texel only -- a shifted shadow). Sobol's index shuffle
      // does the same. With the local choice, the choice and the point in the
      // texel are one 3D Sobol point: each light's samples then cover the
      // texel evenly (on the jittered grid they fell on a random subset of
      // strata: 11 point lights over a plane, 1.7x the RMS error).
      float u_pick, u[3], w[3] = {0, 0, 0};  // w: point in sparse texels; ps.v: cosine direction (MIS)
      if (sobol_) {
        float g[4];
        if (!local_choice_) {
          light_dims.point(j, 4, g);
          u_pick = g[0], u[0] = g[1], u[1] = g[2], u[2] = g[3];
        } else {
          light_dims.point(j, 3, g);
          u_pick = g[0];
          x = origin_x + g[1] * float(m) * side;
          y = origin_y + g[2] * float(m) * side;
          surface_dims.point(j, 3, u);
        }
        if (has_triangle_emitters_) mis_dims.point(j, 2, ps.v);
        if (sparse) piece_dims.point(j, 3, w);
      } else {
        u_pick = (float(permute(j, n, pick_key)) + rng.next_float()) / float(n);
        for (float& r : u) r = rng.next_float();
        for (float& r : ps.v) r = rng.next_float();
        for (float& r : w) r = rng.next_float();  // drawn always: streams stay as they were
      }
      if (csg) {
        csg::DVec3 dp, dn;
        csg->lightmap->sample_point(texel, x, y, dp, dn);
        p = to_float(dp), normal = to_float(dn), tri = RTC_INVALID_GEOMETRY_ID;
      } else if (!texel_point(tw, mesh_id, texel, x, y, w, p, normal, tri)) {
        continue;  // outside the islands
      }
      ps.inside = true;
      ps.normal = normal;
      ps.shading = smooth ? shading_normal_at(*smooth, tri, p, normal) : normal;
      ps.tri = tri;
      ps.k = 0;
      // A point pressed against another surface gets no light (in_contact).
      if (contact && contact[texel] && in_contact(rtc_, views_, p, normal, mesh_id, tri, offset_scale_)) {
        ps.contact = true;
        continue;
      }
      const Vec3 shading = ps.shading;
      size_t k = 0;
      if (local_choice_) {
        if (!chosen_here) {
          if (select) select_candidates(p, shading, chosen, scratch);
          local = local_shares(p, shading, candidates, candidate_count, share);
          chosen_here = true;
        }
        // One interval of u_pick per light (the choice's stratification then
        // leaves each light's sample count within about one of n p_k):
        // candidates first, then the others by power.
        float rest = u_pick;
        size_t i = 0, last = 0;
        for (; i < candidate_count; ++i) {
          const float q = share[i] + (1.0f - local) * table_.probability(candidates[i]);
          if (rest < q) break;
          rest -= q;
          if (q > 0.0f) last = i;
        }
        if (i < candidate_count) {
          k = candidates[i];
        } else if (select && !scratch.others.empty()) {
          const std::vector<double>& cdf = scratch.others_cdf;
          const double target = double(rest) / (1.0f - local);
          const size_t o = size_t(std::upper_bound(cdf.begin(), cdf.end(), target) - cdf.begin());
          k = scratch.others[std::min(o, scratch.others.size() - 1)];
        } else {
          k = candidates[last];  // rounding past the end
        }
      } else if (!all_lights_) {
        k = table_.choose(u_pick);
      }
      ps.k = k;
      ps.origin = offset_origin(p, normal, offset_scale_);
      for (size_t kk = all_lights_ ? 0 : k, end = all_lights_ ? emitters_.size() : k + 1; kk < end; ++kk) {
        const Emitter& em = emitters_[kk];
        DirectSample ds = sample_direct(em, p, shading, u);
        // Light from below the triangle's own plane does not count (Cycles' reflection test on Ng).
        if (smooth && !(dot(normal, ds.dir) > 0.0f)) continue;
        if (em.textured && ds.geometry > 0.0f)  // the texture at the sampled point (0: skip the shadow ray)
          ds.irradiance = textures_->emission(*views_[em.mesh].mesh, em.material, em.triangle, ds.bu, ds.bv) *
                          ds.geometry;
        if (!(ds.irradiance.x > 0.0f || ds.irradiance.y > 0.0f || ds.irradiance.z > 0.0f)) continue;  // no fmaxf calls
        float weight = 1.0f;
        if (em.kind == EmitterKind::Triangle) {  // balance heuristic against cosine sampling
          const float cos_l = std::fabs(dot(em.normal, ds.dir)), cos_s = dot(shading, ds.dir);
          weight = 1.0f / (1.0f + cos_weight_ratio(cos_s, cos_l * em.area, probability(kk), ds.distance));
        }
        lane_value[packet.size] = ds.irradiance * (weight / (kPi * probability(kk)));
        lane_sample[packet.size] = c;
        const bool triangle = em.kind == EmitterKind::Triangle;
        packet.add(ps.origin, ds.dir, std::isinf(ds.distance) ? ds.distance : ds.distance * (1.0f - 1e-4f), tc.skip_geom,
                   tri, triangle ? em.mesh : RTC_INVALID_GEOMETRY_ID, triangle ? em.triangle : RTC_INVALID_GEOMETRY_ID);
        if (packet.full()) trace_packet();
      }
    }
    if (packet.size > 0) trace_packet();
    for (uint32_t c = 0; c < chunk_size; ++c) {
      const uint32_t j = j0 + c;
      Pending& ps = chunk[c];
      if (!ps.inside) continue;
      const size_t k = ps.k;
      Vec3& e = ps.e;
      if (has_triangle_emitters_ && !ps.contact) {
        const Vec3 local = cosine_hemisphere(ps.v[0], ps.v[1]);
        Vec3 t, b;
        make_frame(ps.shading, t, b);
        const Vec3 dir = t * local.x + b * local.y + ps.shading * local.z;
        tc.skip_prim = ps.tri;
        RTCRayHit rh;
        rh.ray = make_ray(ps.origin, dir, std::numeric_limits<float>::infinity());
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        if (smooth && !(dot(ps.normal, dir) > 0.0f)) rh.ray.tfar = -1.0f;  // below the triangle's plane: no light
        else rtcIntersect1(rtc_, &tc.context, &rh);
        if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
          const bool mesh_hit = rh.hit.geomID < triangle_emitter_.size();  // not a CSG solid
          const int32_t hit_emitter =
              mesh_hit && !triangle_emitter_[rh.hit.geomID].empty() ? triangle_emitter_[rh.hit.geomID][rh.hit.primID] : -1;
          if (hit_emitter >= 0) {
            const Emitter& he = emitters_[size_t(hit_emitter)];
            const float cos_l = std::fabs(dot(he.normal, dir)), cos_s = local.z;
            // Irradiance estimate L cos / p_cos = pi L, weighted; stored as irradiance / pi.
            const float r = cos_weight_ratio(cos_s, cos_l * he.area, probability(size_t(hit_emitter)), rh.ray.tfar);
            if (cos_l > 0.0f && cos_s > 0.0f && r > 0.0f) {
              const Vec3 L = he.textured ? textures_->emission(*views_[rh.hit.geomID].mesh, he.material, he.triangle,
                                                               rh.hit.u, rh.hit.v)
                                         : he.radiance;
              e += L * (r / (1.0f + r));
            }
          }
        }
      }
      for (int ch = 0; ch < 3; ++ch) sums.rgb[ch] += e[ch];
      const double a = (double(e.x) + e.y + e.z) / 3.0;
      sums.sum_sq += a * a;
      if (!local_choice_) {
        if (j % 2 == 1 && previous == j - 1) {  // strata 2i and 2i + 1 are neighbours
          sums.pair_sq += (a - previous_value) * (a - previous_value);
          sums.paired += 2;
        }
        previous = j;
        previous_value = a;
      } else {
        ChoiceScratch::Tally& t = scratch.tallies[k];
        if (t.count == 0) scratch.touched.push_back(uint32_t(k));
        if (t.count % 2 == 1) {
          sums.pair_sq += (a - t.unpaired) * (a - t.unpaired);
          sums.paired += 2;
        }
        t.unpaired = a;
        t.sum += a;
        ++t.count;
      }
      ++sums.count;
    }
  }
  // The lights in the order of their intervals of u_pick: candidates, then
  // the others, each by index.
  std::vector<uint32_t>& touched = scratch.touched;
  if (select && chosen_here) {  // candidates were selected
    auto place = [&](uint32_t k) { return scratch.slot_of[k] >= 0 ? uint64_t(scratch.slot_of[k]) : kCandidates + uint64_t(k); };
    std::sort(touched.begin(), touched.end(), [&](uint32_t a, uint32_t b) { return place(a) < place(b); });
    for (const uint32_t k : chosen) scratch.slot_of[k] = -1;
  } else {
    std::sort(touched.begin(), touched.end());
  }
  double previous_mean = 0.0;
  for (size_t i = 0; i < touched.size(); ++i) {
    ChoiceScratch::Tally& t = scratch.tallies[touched[i]];
    const double mean_k = t.sum / t.count;
    if (i > 0) sums.choice_sq += (mean_k - previous_mean) * (mean_k - previous_mean) / 6.0;
    previous_mean = mean_k;
    t = ChoiceScratch::Tally{};
  }
  touched.clear();
}

void DirectPass::gather_texel(uint32_t mesh_id, uint32_t texel, uint32_t round, uint32_t samples,
                              const GatherSource& source, DirectSums& sums, GatherInfo& info) const {
  const uint64_t global = views_[mesh_id].texel_offset + texel;
  // A stream of its own: (round | 0x100) is no round of sample_texel's.
  Rng rng(seed_ ^ 0x7F4A7C15u, (global << 9) | 0x100u | (round & 0xFF));
  const uint32_t m = std::max(1u, uint32_t(std::ceil(std::sqrt(double(samples)))));
  const uint32_t n = m * m;
  const TexelWindow tw = texel_window(mesh_id, texel, m);
  const SobolGroup dir_dims(rng.next_u32(), 3), piece_dims(rng.next_u32(), 4);
  uint32_t previous = ~0u, back = 0, rays = 0;
  double error_sum = 0.0, inverse_distance = 0.0;
  double previous_value = 0.0;
  const Mesh* smooth = views_[mesh_id].mesh->smooth() ? views_[mesh_id].mesh : nullptr;
  const uint8_t* contact = views_[mesh_id].contact;
  // Rays go in packets of eight points; then each is looked up in turn.
  // Points pressed against another surface (in_contact) and, on smooth
  // meshes, directions below the triangle's plane are known zeros: their
  // lanes are marked with a negative tfar and not traced.
  RayPacket packet;
  uint32_t lane_sample[RayPacket::kLanes];
  Vec3 lane_dir[RayPacket::kLanes];
  for (uint32_t j0 = 0; j0 < n; j0 += RayPacket::kLanes) {
    uint32_t zero_lanes = 0, contact_lanes = 0;  // bit l: lane l is a known zero; ... a point in contact
    for (uint32_t j = j0; j < std::min(n, j0 + RayPacket::kLanes); ++j) {
      const float x = tw.origin_x + (float(j % m) + rng.next_float()) * tw.side;
      const float y = tw.origin_y + (float(j / m) + rng.next_float()) * tw.side;
      Vec3 p, normal;
      uint32_t tri;
      float v[2], w[3] = {0, 0, 0};
      dir_dims.point(j, 2, v);
      if (tw.sparse) piece_dims.point(j, 3, w);
      if (!texel_point(tw, mesh_id, texel, x, y, w, p, normal, tri)) continue;
      const Vec3 shading = smooth ? shading_normal_at(*smooth, tri, p, normal) : normal;
      const Vec3 local = cosine_hemisphere(v[0], v[1]);
      Vec3 t, b;
      make_frame(shading, t, b);
      lane_sample[packet.size] = j;
      lane_dir[packet.size] = t * local.x + b * local.y + shading * local.z;
      if (contact && contact[texel] && in_contact(rtc_, views_, p, normal, mesh_id, tri, offset_scale_))
        contact_lanes |= 1u << packet.size;
      if (smooth && !(dot(normal, lane_dir[packet.size]) > 0.0f)) zero_lanes |= 1u << packet.size;
      packet.add(offset_origin(p, normal, offset_scale_), lane_dir[packet.size], std::numeric_limits<float>::infinity(),
                 mesh_id, tri);
    }
    const unsigned lanes = packet.size;
    zero_lanes |= contact_lanes;
    if (lanes > 0) packet.intersect(rtc_, zero_lanes);
    const RTCHit8& hit = packet.rh.hit;
    for (unsigned l = 0; l < lanes; ++l) {
      const uint32_t j = lane_sample[l], geom = hit.geomID[l], prim = hit.primID[l];
      Vec3 e{0, 0, 0};
      if (contact_lanes & (1u << l)) {
        ++info.dark;
      } else if (geom != RTC_INVALID_GEOMETRY_ID) {
        inverse_distance += 1.0 / std::max(double(packet.rh.ray.tfar[l]), 1e-30);
        // The texel the ray lands in, as the photon pass records a hit.
        bool known = false;
        const bool is_mesh = geom < views_.size(), mesh_hit = is_mesh && views_[geom].texel_area;
        if (is_mesh && !(dot(lane_dir[l], views_[geom].normals[prim]) < 0.0f)) {
          // The back of a surface: 0, exactly where no photon reached the
          // mesh's backs (the inside of a box standing on the ground).
          if (!source.back_lit[geom]) {
            ++info.dark;
            known = true;
          } else if (mesh_hit) {
            ++back;
            known = true;
          }
        } else if (mesh_hit) {
          const MeshView& hv = views_[geom];
          const Mesh& hm = *hv.mesh;
          const int64_t ht = uv_texel(&hm.uv[6 * size_t(prim)], hit.u[l], hit.v[l], hm.lightmap_width, hm.lightmap_height);
          // A texel that other objects may be pressed against may be partly
          // in contact, and its value (its central square's, or the mean over
          // it) then says little of the lit part next to them: a ray that
          // lands within a texel's width of its origin there is not looked up
          // (the wall of a box at the box's foot sees the floor right beside it).
          const bool unreliable = ht >= 0 && hv.contact && hv.contact[ht] &&
                                  double(packet.rh.ray.tfar[l]) * double(packet.rh.ray.tfar[l]) *
                                          std::max(double(areas_[geom].coverage[ht]), 1e-3) <
                                      hv.texel_area[ht];
          if (ht >= 0 && !unreliable) {
            if (hv.texel_area[ht] > 0.0) {
              const float* d = source.radiosity + 3 * (hv.texel_offset + ht);
              const Vec3 a = (*source.albedo)[geom][prim];
              e = {a.x * d[0], a.y * d[1], a.z * d[2]};
              error_sum += double(average(a)) * source.error[hv.texel_offset + ht];
              known = true;
            }
          }
        }
        if (!known) ++info.unknown;
      }
      ++rays;
      for (int c = 0; c < 3; ++c) sums.rgb[c] += e[c];
      const double a = (double(e.x) + e.y + e.z) / 3.0;
      sums.sum_sq += a * a;
      if (j % 2 == 1 && previous == j - 1) {
        sums.pair_sq += (a - previous_value) * (a - previous_value);
        sums.paired += 2;
      }
      previous = j;
      previous_value = a;
      ++sums.count;
    }
  }
  // Many backs lit from behind are a surface whose light no lightmap holds
  // (lightmaps are one-sided).
  if (4 * back > rays) info.unknown += back;
  info.lookup_error = rays ? error_sum / rays : 0.0;
  if (inverse_distance > 0.0) info.hit_distance = float(rays / inverse_distance);
}

}  // namespace plm

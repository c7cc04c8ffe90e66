#include "transport/direct/direct.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "transport/materials/bsdf.h"
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

// A light's unoccluded irradiance at p, 0 where the guess is not a finite
// non-negative number.
float irradiance_guess(const Emitter& e, Vec3 p, Vec3 n) {
  const float g = unoccluded_irradiance(e, p, n);
  return g >= 0.0f && g < 1e30f ? g : 0.0f;
}

// DirectPass::distant_ for these emitters.
std::vector<uint32_t> distant_lights(const std::vector<Emitter>& emitters, size_t all_lights, size_t max_choice) {
  if (emitters.size() <= all_lights || emitters.size() > max_choice) return {};
  std::vector<uint32_t> out;
  for (uint32_t k = 0; k < emitters.size(); ++k)
    if (emitters[k].kind == EmitterKind::Sun || emitters[k].kind == EmitterKind::World) out.push_back(k);
  if (out.size() > all_lights || out.size() == emitters.size()) return {};
  return out;
}

std::vector<uint8_t> emitter_flags(size_t count, const std::vector<uint32_t>& set) {
  if (set.empty()) return {};
  std::vector<uint8_t> flags(count, 0);
  for (uint32_t k : set) flags[k] = 1;
  return flags;
}

}  // namespace

double DirectSums::pair_variance_of_mean() const { return pairs_of_mean(pair_sq, choice_sq); }

double DirectSums::sky_pair_variance_of_mean() const { return pairs_of_mean(sky_pair_sq); }

double DirectSums::other_pair_variance_of_mean() const { return pairs_of_mean(other_pair_sq, choice_sq); }

void DirectSums::merge(const DirectSums& o) {
  for (int c = 0; c < 3; ++c) rgb[c] += o.rgb[c], sky_rgb[c] += o.sky_rgb[c];
  sky_pair_sq += o.sky_pair_sq;
  other_pair_sq += o.other_pair_sq;
  sky_inv_distance += o.sky_inv_distance;
  sky_rays += o.sky_rays;
  sky_blocked += o.sky_blocked;
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

DirectPass::DirectPass(const BakeScene& ctx)
    : rtc_(ctx.rtc), surfaces_(ctx.surfaces), views_(ctx.space.views), csgs_(ctx.space.csg_views),
      emitters_(ctx.emitters), textures_(ctx.textures.get()), passage_(ctx.passage.get()),
      points_(ctx.space.views, ctx.space.areas, ctx.settings), seed_(ctx.settings.seed), sobol_(ctx.settings.sobol),
      offset_scale_(1e-6f * ctx.extent), distant_(distant_lights(ctx.emitters, kAllLights, kMaxLocalChoice)),
      is_distant_(emitter_flags(ctx.emitters.size(), distant_)), table_(ctx.emitters, is_distant_),
      all_lights_(ctx.emitters.size() <= kAllLights),
      local_choice_(!all_lights_ && ctx.emitters.size() <= kMaxLocalChoice), split_(ctx.split) {
  const std::vector<Emitter>& emitters = ctx.emitters;
  const std::vector<MeshView>& views = ctx.space.views;
  if (!all_lights_ && emitters.size() - distant_.size() <= kCandidates) {
    all_slot_.assign(emitters.size(), -1);
    for (uint32_t k = 0; k < emitters.size(); ++k)
      if (is_distant_.empty() || !is_distant_[k]) {
        all_slot_[k] = int32_t(all_candidates_.size());
        all_candidates_.push_back(k);
      }
  }
  is_sky_.assign(emitters.size(), 0);
  for (size_t k = 0; k < emitters.size(); ++k)
    if (emitters[k].kind == EmitterKind::World && emitters[k].map_part != 1 && emitters[k].portals.empty())
      is_sky_[k] = 1, split_sky_ = true;
  split_sky_ = split_sky_ && all_lights_ && !passage_;
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
  for (uint32_t i = 0; i < emitters_.size(); ++i) {  // the distant_ lights last (-1): never candidates
    guess[i] = !is_distant_.empty() && is_distant_[i] ? -1.0f : irradiance_guess(emitters_[i], p, n);
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
                              DirectSums& sums, float* split) const {
  if (passage_) sample<true>(mesh_id, texel, round, samples, sums, split);
  else sample<false>(mesh_id, texel, round, samples, sums, split);
}

// One interval of u_pick per light (the choice's stratification then leaves
// each light's sample count within about one of n p_k): candidates first, then
// the others by power.
size_t DirectPass::choose_local(float u_pick, const uint32_t* candidates, size_t count, const float* share,
                                float local, bool select, const ChoiceScratch& scratch) const {
  float rest = u_pick;
  size_t i = 0, last = 0;
  for (; i < count; ++i) {
    const float q = share[i] + (1.0f - local) * table_.probability(candidates[i]);
    if (rest < q) break;
    rest -= q;
    if (q > 0.0f) last = i;
  }
  if (i < count) return candidates[i];
  if (select && !scratch.others.empty()) {
    const std::vector<double>& cdf = scratch.others_cdf;
    const double target = double(rest) / (1.0f - local);
    const size_t o = size_t(std::upper_bound(cdf.begin(), cdf.end(), target) - cdf.begin());
    return scratch.others[std::min(o, scratch.others.size() - 1)];
  }
  return candidates[last];  // rounding past the end
}

// The light a cosine-sampled ray from the sample's point brings back where it
// meets a triangle emitter, weighted by the balance heuristic against that
// emitter's own samples (multiple importance sampling).
template <bool kPassage, class Probability>
Vec3 DirectPass::cosine_ray_light(const PendingSample& ps, TraceContext& tc, bool smooth,
                                  const Probability& probability, float* split) const {
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
  else rtcIntersect1(rtc_, tc.context(), &rh);
  SurfaceHit h = surfaces_.hit(rh);
  Vec3 through{1, 1, 1};
  float distance = h.t;
  if constexpr (kPassage) {
    if (passage_->passable(h)) {
      h = passage_->continue_through(rtc_, h, dir, through);
      distance = length(h.point - ps.origin);
    }
  }
  const int32_t hit_emitter = h.kind == SurfaceKind::Triangle && !triangle_emitter_[h.index].empty()
                                  ? triangle_emitter_[h.index][h.prim]
                                  : -1;
  if (hit_emitter >= 0) {
    const Emitter& he = emitters_[size_t(hit_emitter)];
    const float cos_l = std::fabs(dot(he.normal, dir)), cos_s = local.z;
    // Irradiance estimate L cos / p_cos = pi L, weighted; stored as irradiance / pi.
    const float r = cos_weight_ratio(cos_s, cos_l * he.area, probability(size_t(hit_emitter)), distance);
    if (cos_l > 0.0f && cos_s > 0.0f && r > 0.0f) {
      const Vec3 L = he.textured
                         ? textures_->emission(*views_[h.index].mesh, he.material, he.triangle, h.u, h.v)
                         : he.radiance;
      float weight = r / (1.0f + r);
      if (ps.burley >= 0.0f) weight *= bsdf::burley_receive(cos_s, ps.burley);
      const Vec3 light = kPassage ? L * through * weight : L * weight;
      if (split) add_split(split, split_, he.layer, light, direction_weight(dir, ps.shading));
      return light;
    }
  }
  return {0, 0, 0};
}

// What the local choice adds to a texel's variance is the spread of each
// light's sample count n_k around n p_k: the stratum of u_pick that holds the
// boundary between two lights' intervals gives its one sample to either
// (variance f (1 - f), 1/6 on average), which moves the estimate by the
// difference of the two lights' sample means / n. So choice_sq gets
// (mean_a - mean_b)^2 / 6 for each two lights with samples that follow each
// other in u_pick (lights without samples between them have narrow
// intervals: skipped), from the tallies of the lights the texel's samples
// chose, in the order of their intervals; the tallies are cleared.
void DirectPass::add_choice_spread(ChoiceScratch& scratch, bool selected, const uint32_t* chosen, DirectSums& sums) {
  // The lights in the order of their intervals of u_pick: candidates, then
  // the others, each by index.
  std::vector<uint32_t>& touched = scratch.touched;
  if (selected) {  // candidates were selected
    auto place = [&](uint32_t k) { return scratch.slot_of[k] >= 0 ? uint64_t(scratch.slot_of[k]) : kCandidates + uint64_t(k); };
    std::sort(touched.begin(), touched.end(), [&](uint32_t a, uint32_t b) { return place(a) < place(b); });
    for (size_t i = 0; i < kCandidates; ++i) scratch.slot_of[chosen[i]] = -1;
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

// Adds sample j's light to the texel's sums and its pairs: of successive
// strata, or with the local choice of successive samples of one light (the
// choice is stratified, so pairs of different lights would count the lights'
// differences as noise; with the choice by power, beyond kMaxLocalChoice
// lights, a texel has fewer samples than lights: pairs of neighbouring strata,
// as with all lights); and where the world's part is split off, that part's
// and the rest's pairs.
[[gnu::always_inline]] inline void DirectPass::add_sample(uint32_t j, const PendingSample& ps, bool split_sky, TexelTally& tally,
                            ChoiceScratch& scratch, DirectSums& sums) const {
  const double a = sums.add(ps.e);
  if (split_sky) {  // the world's part and the rest, paired as the whole is
    const double sky = (double(ps.sky.x) + ps.sky.y + ps.sky.z) / 3.0;
    for (int ch = 0; ch < 3; ++ch) sums.sky_rgb[ch] += ps.sky[ch];  // float: ample for a texel's samples
    if (tally.split_pairs.completes(j)) {
      sums.sky_pair_sq += float((sky - tally.previous_sky) * (sky - tally.previous_sky));
      sums.other_pair_sq += float((a - sky - tally.previous_other) * (a - sky - tally.previous_other));
    }
    tally.previous_sky = sky, tally.previous_other = a - sky;
  }
  if (!local_choice_) {
    tally.pairs.add(j, a, sums);
  } else {
    ChoiceScratch::Tally& t = scratch.tallies[ps.k];
    if (t.count == 0) scratch.touched.push_back(uint32_t(ps.k));
    if (t.count % 2 == 1) sums.add_pair(a, t.unpaired);
    t.unpaired = a;
    t.sum += a;
    ++t.count;
  }
}

// Traces the shadow rays gathered in rays.packet and adds each unblocked
// ray's light to its sample in chunk (the world's part also to sky). With
// measure_reach, world rays are intersected rather than only tested, and
// their blockers' distances kept (the sky pool's reach).
template <bool kPassage>
[[gnu::always_inline]] inline void DirectPass::trace_shadow_rays(ShadowRays& rays, PendingSample* chunk, bool measure_reach,
                                   DirectSums& sums, float* split) const {
  const unsigned lanes = rays.packet.size;
  // Each ray's light also goes to the texel's split (light groups, directional lightmaps).
  auto to_layer = [&](unsigned l, Vec3 value) { add_split(split, split_, rays.layer[l], value, rays.u[l]); };
  if (measure_reach && rays.sky_lanes) {
    rays.packet.intersect(rtc_);
    for (unsigned l = 0; l < lanes; ++l) {
      PendingSample& ps = chunk[rays.sample[l]];
      const bool blocked = rays.packet.rh.hit.geomID[l] != RTC_INVALID_GEOMETRY_ID;
      if (rays.sky_lanes >> l & 1u) {
        ++sums.sky_rays;
        if (blocked) {
          ++sums.sky_blocked;
          sums.sky_inv_distance += 1.0f / std::fmax(rays.packet.rh.ray.tfar[l], offset_scale_);
        } else {
          ps.sky += rays.value[l];
        }
      }
      if (!blocked) {
        ps.e += rays.value[l];
        to_layer(l, rays.value[l]);
      }
    }
    rays.sky_lanes = 0;
    return;
  }
  if constexpr (kPassage) {
    Vec3 through[RayPacket::kLanes];
    passage_->occluded(rays.packet, rtc_, through);
    for (unsigned l = 0; l < lanes; ++l) {
      chunk[rays.sample[l]].e += rays.value[l] * through[l];
      to_layer(l, rays.value[l] * through[l]);
    }
    return;
  }
  rays.packet.occluded(rtc_);
  for (unsigned l = 0; l < lanes; ++l)
    if (!rays.packet.blocked(l)) chunk[rays.sample[l]].e += rays.value[l];
  if (split)
    for (unsigned l = 0; l < lanes; ++l)
      if (!rays.packet.blocked(l)) to_layer(l, rays.value[l]);
  if (rays.sky_lanes) {
    sums.sky_rays += uint32_t(__builtin_popcount(rays.sky_lanes));
    for (unsigned l = 0; l < lanes; ++l)
      if ((rays.sky_lanes >> l & 1u) && !rays.packet.blocked(l)) chunk[rays.sample[l]].sky += rays.value[l];
    rays.sky_lanes = 0;
  }
}

// draw, trace_shadow_rays and add_sample are steps of sample's loop, forced
// inline: as calls they cost the direct pass 7 % more instructions.
// Sample j's numbers: the light choice u_pick, the point on the light u, the
// MIS direction v and the point in a sparse texel w; with the local choice
// also the point (x, y) in the texel. Light choice and light sample are a 4D
// Sobol point per sample (random otherwise, with the choice stratified through
// a permutation: tied to j it would follow the strata's rows, so each light
// would be sampled in one band of the texel only -- a shifted shadow).
// Sobol's index shuffle does the same. With the local choice, the choice and
// the point in the texel are one 3D Sobol point: each light's samples then
// cover the texel evenly (on the jittered grid they fell on a random subset
// of strata).
[[gnu::always_inline]] inline void DirectPass::draw(const SampleNumbers& d, uint32_t j, Rng& rng, float& x, float& y, float& u_pick, float* u,
                      float* v, float* w) const {
  if (sobol_) {
    float g[4];
    if (!local_choice_) {
      d.light.point(j, 4, g);
      u_pick = g[0], u[0] = g[1], u[1] = g[2], u[2] = g[3];
    } else {
      d.light.point(j, 3, g);
      u_pick = g[0];
      x = d.origin_x + g[1] * float(d.m) * d.side;
      y = d.origin_y + g[2] * float(d.m) * d.side;
      d.surface.point(j, 3, u);
    }
    if (has_triangle_emitters_) d.mis.point(j, 2, v);
    if (d.sparse) d.piece.point(j, 3, w);
  } else {
    u_pick = (float(permute(j, d.n, d.pick_key)) + rng.next_float()) / float(d.n);
    for (int i = 0; i < 3; ++i) u[i] = rng.next_float();
    for (int i = 0; i < 2; ++i) v[i] = rng.next_float();
    for (int i = 0; i < 3; ++i) w[i] = rng.next_float();  // drawn always: streams stay as they were
  }
}

template <bool kPassage>
void DirectPass::sample(uint32_t mesh_id, uint32_t texel, uint32_t round, uint32_t samples, DirectSums& sums,
                        float* split) const {
  if (emitters_.empty()) return;
  // A CSG sub-texel: points from its lightmap; rays leave the exact surface by
  // the origin offset alone (a ray may rightly hit the primitive it leaves).
  const CsgView* csg = mesh_id >= views_.size() ? &csgs_[mesh_id - views_.size()] : nullptr;
  const uint64_t global = (csg ? csg->texel_offset : views_[mesh_id].texel_offset) + texel;
  Rng rng(seed_ ^ 0x9E3779B9u, (global << 8) | (round & 0xFF));
  const uint32_t m = std::max(1u, uint32_t(std::ceil(std::sqrt(double(samples)))));
  const uint32_t n = m * m;
  TraceContext tc;
  tc.skip_geom = csg ? RTC_INVALID_GEOMETRY_ID : SurfaceMap::mesh_geometry(mesh_id);
  TexelPoints::TexelWindow tw;  // a CSG sub-texel: strata over [0, 1]^2 of its lightmap
  if (csg) tw.side = 1.0f / float(m);
  else tw = points_.texel_window(mesh_id, texel, m);
  const bool sparse = tw.sparse;
  const float origin_x = tw.origin_x, origin_y = tw.origin_y, side = tw.side;
  const uint32_t pick_key = rng.next_u32();
  const uint32_t sobol_key = rng.next_u32();
  const Mesh* smooth = !csg && views_[mesh_id].mesh->smooth() ? views_[mesh_id].mesh : nullptr;
  const uint8_t* contact = csg ? nullptr : views_[mesh_id].contact;
  const float* burley = csg ? nullptr : views_[mesh_id].burley;
  const SampleNumbers numbers{SobolGroup(sobol_key, 0), SobolGroup(sobol_key, 1), SobolGroup(sobol_key, 2),
                              SobolGroup(sobol_key, 3), pick_key, n, m, origin_x, origin_y, side, sparse};
  TexelTally tally;
  // Per-light tallies (add_sample) live in per-thread scratch (no allocation
  // per texel once it has grown to the light count).
  thread_local ChoiceScratch scratch;
  if (local_choice_ && scratch.tallies.size() < emitters_.size()) scratch.tallies.resize(emitters_.size());
  // The candidates of the local choice: all lights, or with more than
  // kCandidates the brightest (by unoccluded irradiance) at the texel's first
  // point, scratch.slot_of[k] their place (-1: not a candidate).
  const bool select = local_choice_ && emitters_.size() - distant_.size() > kCandidates;
  // The local choice's shares, from the lights' unoccluded irradiance at the
  // texel's first point (per point they cost far more for no lower error).
  bool chosen_here = false;
  float share[kCandidates], local = 0.0f;
  uint32_t chosen[kCandidates];
  const uint32_t* const candidates = select ? chosen : all_candidates_.data();
  const size_t candidate_count = select ? kCandidates : all_candidates_.size();
  if (select && scratch.slot_of.size() < emitters_.size()) scratch.slot_of.resize(emitters_.size(), -1);
  // Every light is sampled with probability 1 in all-lights mode.
  auto probability = [&](size_t i) {
    if (all_lights_ || (!is_distant_.empty() && is_distant_[i])) return 1.0f;
    if (!local_choice_) return table_.probability(i);
    const int32_t slot = select ? scratch.slot_of[i] : all_slot_[i];
    return (slot >= 0 ? share[slot] : 0.0f) + (1.0f - local) * table_.probability(i);
  };
  // Samples go in chunks: first their shadow rays, traced in packets, then
  // each sample in turn (the MIS ray, the sums), so every sum adds the same
  // numbers in the same order as sample by sample.
  constexpr uint32_t kChunk = 8;
  PendingSample chunk[kChunk];
  ShadowRays rays;
  const bool split_sky = split_sky_ && !csg;
  // The world rays of round 0's first kReachSamples samples also bring back
  // how far their blocker is (the reach of the pooling); the others only need
  // to know whether one is there (intersecting every one cost a bake without
  // a target, all of whose samples are round 0's, 25 % more time).
  constexpr uint32_t kReachSamples = 16;
  const bool measure_reach = split_sky && round == 0;
  for (uint32_t j0 = 0; j0 < n; j0 += kChunk) {
    const bool reach_here = measure_reach && j0 < kReachSamples;
    const uint32_t chunk_size = std::min(kChunk, n - j0);
    for (uint32_t c = 0; c < chunk_size; ++c) {
      const uint32_t j = j0 + c;
      PendingSample& ps = chunk[c];
      ps.inside = ps.contact = false;
      ps.e = ps.sky = {0, 0, 0};
      ps.burley = -1.0f;
      float x = origin_x + (float(j % m) + rng.next_float()) * side;
      float y = origin_y + (float(j / m) + rng.next_float()) * side;
      Vec3 p, normal;
      uint32_t tri;
      float u_pick, u[3], w[3] = {0, 0, 0};  // w: point in sparse texels; ps.v: cosine direction (MIS)
      draw(numbers, j, rng, x, y, u_pick, u, ps.v, w);
      if (csg) {
        Vec3d dp, dn;
        csg->lightmap->sample_point(texel, x, y, dp, dn);
        p = to_float(dp), normal = to_float(dn), tri = RTC_INVALID_GEOMETRY_ID;
      } else if (!points_.texel_point(tw, mesh_id, texel, x, y, w, p, normal, tri)) {
        continue;  // outside the islands
      }
      ps.inside = true;
      ps.normal = normal;
      ps.shading = smooth ? shading_normal_at(*smooth, tri, p, normal) : normal;
      ps.tri = tri;
      ps.burley = burley ? burley[tri] : -1.0f;
      ps.k = 0;
      // A point pressed against another surface gets no light (in_contact).
      if (contact && contact[texel] && in_contact(rtc_, surfaces_, p, normal, mesh_id, tri, offset_scale_)) {
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
        k = choose_local(u_pick, candidates, candidate_count, share, local, select, scratch);
      } else if (!all_lights_) {
        k = table_.choose(u_pick);
      }
      ps.k = k;
      ps.origin = offset_origin(p, normal, offset_scale_);
      // The lights the sample sends a shadow ray to: all, or the distant_ ones and the chosen one.
      const size_t distant = distant_.size();
      for (size_t r = 0, end = all_lights_ ? emitters_.size() : distant + 1; r < end; ++r) {
        const size_t kk = all_lights_ ? r : r < distant ? distant_[r] : k;
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
        if (ps.burley >= 0.0f) weight *= bsdf::burley_receive(dot(shading, ds.dir), ps.burley);
        rays.value[rays.packet.size] = ds.irradiance * (weight / (kPi * probability(kk)));
        rays.sample[rays.packet.size] = c;
        rays.layer[rays.packet.size] = em.layer;
        if (split_.directional) rays.u[rays.packet.size] = direction_weight(ds.dir, shading);
        if (split_sky && is_sky_[kk]) rays.sky_lanes |= 1u << rays.packet.size;
        const bool triangle = em.kind == EmitterKind::Triangle;
        rays.packet.add(ps.origin, ds.dir, std::isinf(ds.distance) ? ds.distance : ds.distance * (1.0f - 1e-4f),
                        tc.skip_geom, tri, triangle ? SurfaceMap::mesh_geometry(em.mesh) : RTC_INVALID_GEOMETRY_ID,
                        triangle ? em.triangle : RTC_INVALID_GEOMETRY_ID);
        if (rays.packet.full()) trace_shadow_rays<kPassage>(rays, chunk, reach_here, sums, split);
      }
    }
    if (rays.packet.size > 0) trace_shadow_rays<kPassage>(rays, chunk, reach_here, sums, split);
    for (uint32_t c = 0; c < chunk_size; ++c) {
      const uint32_t j = j0 + c;
      PendingSample& ps = chunk[c];
      if (!ps.inside) continue;
      if (has_triangle_emitters_ && !ps.contact)
        ps.e += cosine_ray_light<kPassage>(ps, tc, smooth != nullptr, probability, split);
      add_sample(j, ps, split_sky, tally, scratch, sums);
    }
  }
  add_choice_spread(scratch, select && chosen_here, chosen, sums);
}

}  // namespace plm

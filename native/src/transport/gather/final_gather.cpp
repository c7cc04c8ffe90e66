#include "transport/gather/final_gather.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "transport/plan/scheduler.h"
#include "scene/texture.h"
#include "util/rng.h"
#include "util/sobol.h"

namespace plm {
namespace {

// The split of what a ray sees (e): each layer's part by the layers' shares
// of the global texel it looked up, the direction moment by the ray's own
// direction weight u (transport/context/split.h).
inline void add_gathered(const GatherSource& source, uint64_t texel, Vec3 e, Vec3 u, float* split) {
  const float* share = source.layer_share + 3 * texel * source.layers;
  for (uint32_t g = 0; g < 3 * source.layers; ++g) split[g] += e[g % 3] * share[g];
  if (source.directional) add_split(split + 3 * size_t(source.layers), SplitLayout{0, true}, 0, e, u);
}

// Directional lightmaps: a texel's rays' moment with the control variate of
// their directions. A cosine-sampled ray's weight u has mean n / 2, so
// sum(e u) - mean(e) sum(u - n / 2) keeps the moment's expectation and drops
// the part of its noise that comes from where the rays went, not from what
// they saw (under light alike from everywhere the moment is n / 2 exactly).
struct DirectionControl {
  double light[3] = {0, 0, 0}, control[3] = {0, 0, 0};
  // A ray (every one, zeros too): its light e, weight u and the normal n it was sampled about.
  void add(Vec3 e, Vec3 u, Vec3 n) {
    for (int c = 0; c < 3; ++c) light[c] += e[c];
    for (int a = 0; a < 3; ++a) control[a] += double(u[a]) - 0.5 * double(n[a]);
  }
  // The correction of the moment d (3 axes x RGB) the texel's `rays` rays added up.
  void apply(float* d, uint32_t rays) const {
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c < 3; ++c) d[3 * a + c] -= float(light[c] / double(rays) * control[a]);
  }
};

constexpr uint32_t kCellCapacity = kMaxGroupGatherSamples;  // rays whose cells a texel keeps apart
constexpr uint32_t kCalibrationRound = 0xFF;            // the replicates' key (the gather's rounds count from 0)
constexpr uint32_t kOpenRound = 0xFE;                   // open_share's points

// A ray's share of the local lookup error and the cell it looked up.
struct CellShare {
  uint64_t cell;
  double share;
};

// The sum over cells of each cell's share squared (the rays that look up one cell share its error).
double cell_shares_sq(CellShare* cells, uint32_t count) {
  std::sort(cells, cells + count, [](const CellShare& a, const CellShare& b) { return a.cell < b.cell; });
  double sq = 0.0;
  for (uint32_t i = 0; i < count;) {
    double share = 0.0;
    const uint64_t cell = cells[i].cell;
    for (; i < count && cells[i].cell == cell; ++i) share += cells[i].share;
    sq += share * share;
  }
  return sq;
}

}  // namespace

FinalGather::FinalGather(const BakeScene& ctx)
    : rtc_(ctx.rtc), surfaces_(ctx.surfaces), views_(ctx.space.views), areas_(ctx.space.areas),
      points_(ctx.space.views, ctx.space.areas, ctx.settings), seed_(ctx.settings.seed),
      offset_scale_(1e-6f * ctx.extent),
      // A texel's photon pool reaches filter_radius texels (at least 1 where
      // barely covered): texels within a pool's width of each other share hits.
      cell_side_(2 * std::max(ctx.settings.filter_radius, 1u) + 1), passage_(ctx.passage.get()),
      black_known_(ctx.lobes.any_lobes()), materials_(ctx.lobes.any_view_scale() ? &ctx.lobes : nullptr),
      textures_(ctx.textures.get()) {}

void FinalGather::sample_texel(uint32_t mesh_id, uint32_t texel, uint32_t round, uint32_t samples,
                               const GatherSource& source, GatherSums& sums, GatherInfo& info,
                               float* split) const {
  if (passage_) sample<true>(mesh_id, texel, round, samples, source, sums, info, split);
  else sample<false>(mesh_id, texel, round, samples, source, sums, info, split);
}

float FinalGather::open_share(uint32_t mesh_id, uint32_t texel, const uint8_t* back_lit) const {
  constexpr uint32_t kSide = 4;  // points per side: a jittered grid over the texel's window
  const uint64_t global = views_[mesh_id].texel_offset + texel;
  Rng rng(seed_ ^ 0x7F4A7C15u, (global << 9) | 0x100u | kOpenRound);
  const TexelPoints::TexelWindow tw = points_.texel_window(mesh_id, texel, kSide);
  const SobolGroup piece_dims(rng.next_u32(), 4);
  const uint8_t* contact = views_[mesh_id].contact;
  RayPacket packet;
  Vec3 lane_dir[RayPacket::kLanes];
  uint32_t points = 0, closed = 0;
  for (uint32_t j0 = 0; j0 < kSide * kSide; j0 += RayPacket::kLanes) {
    for (uint32_t j = j0; j < j0 + RayPacket::kLanes; ++j) {
      const float x = tw.origin_x + (float(j % kSide) + rng.next_float()) * tw.side;
      const float y = tw.origin_y + (float(j / kSide) + rng.next_float()) * tw.side;
      Vec3 p, normal;
      uint32_t tri;
      float w[3] = {0, 0, 0};
      if (tw.sparse) piece_dims.point(j, 3, w);
      if (!points_.texel_point(tw, mesh_id, texel, x, y, w, p, normal, tri)) continue;
      ++points;
      if (contact && contact[texel] && in_contact(rtc_, surfaces_, p, normal, mesh_id, tri, offset_scale_)) {
        ++closed;
        continue;
      }
      lane_dir[packet.size] = normal;
      packet.add(offset_origin(p, normal, offset_scale_), normal, std::numeric_limits<float>::infinity(),
                 SurfaceMap::mesh_geometry(mesh_id), tri);
    }
    const unsigned lanes = packet.size;
    if (lanes > 0) packet.intersect(rtc_);
    for (unsigned l = 0; l < lanes; ++l) {
      const SurfaceHit h = surfaces_.hit(packet.rh, l);
      if (h.kind == SurfaceKind::Triangle && !(dot(lane_dir[l], h.normal) < 0.0f) && !back_lit[h.index]) ++closed;
    }
  }
  return points > 0 ? float(points - closed) / float(points) : 1.0f;
}

template <bool kPassage>
void FinalGather::sample(uint32_t mesh_id, uint32_t texel, uint32_t round, uint32_t samples,
                         const GatherSource& source, GatherSums& sums, GatherInfo& info, float* split) const {
  const uint64_t global = views_[mesh_id].texel_offset + texel;
  // A stream of its own: (round | 0x100) is no round of the direct pass's.
  Rng rng(seed_ ^ 0x7F4A7C15u, (global << 9) | 0x100u | (round & 0xFF));
  const uint32_t m = std::max(1u, uint32_t(std::ceil(std::sqrt(double(samples)))));
  const uint32_t n = m * m;
  const TexelPoints::TexelWindow tw = points_.texel_window(mesh_id, texel, m);
  const SobolGroup dir_dims(rng.next_u32(), 3), piece_dims(rng.next_u32(), 4);
  uint32_t back = 0, rays = 0;
  double inverse_distance = 0.0, local_sum = 0.0, local_sq = 0.0, wide_sum = 0.0;
  // The rays' shares of the local lookup error, by the cell they looked up.
  CellShare cells[kCellCapacity];
  uint32_t cell_count = 0;
  StratumPairs pairs;
  const Mesh* smooth = views_[mesh_id].mesh->smooth() ? views_[mesh_id].mesh : nullptr;
  const uint8_t* contact = views_[mesh_id].contact;
  const float* burley = views_[mesh_id].burley;  // the texel's surface weighs light by direction (bsdf::burley_receive)
  // Rays go in packets of eight points; then each is looked up in turn.
  // Points pressed against another surface (in_contact) and, on smooth
  // meshes, directions below the triangle's plane are known zeros: their
  // lanes are marked with a negative tfar and not traced.
  RayPacket packet;
  uint32_t lane_sample[RayPacket::kLanes];
  Vec3 lane_dir[RayPacket::kLanes], lane_u[RayPacket::kLanes] = {}, lane_n[RayPacket::kLanes] = {};
  float lane_weight[RayPacket::kLanes];
  const bool directional = split && source.directional;
  DirectionControl control;
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
      if (!points_.texel_point(tw, mesh_id, texel, x, y, w, p, normal, tri)) continue;
      const Vec3 shading = smooth ? shading_normal_at(*smooth, tri, p, normal) : normal;
      const Vec3 local = cosine_hemisphere(v[0], v[1]);
      Vec3 t, b;
      make_frame(shading, t, b);
      lane_sample[packet.size] = j;
      lane_dir[packet.size] = t * local.x + b * local.y + shading * local.z;
      if (directional) lane_u[packet.size] = direction_weight(lane_dir[packet.size], shading);
      lane_n[packet.size] = shading;
      lane_weight[packet.size] = burley && burley[tri] >= 0.0f ? bsdf::burley_receive(local.z, burley[tri]) : 1.0f;
      if (contact && contact[texel] && in_contact(rtc_, surfaces_, p, normal, mesh_id, tri, offset_scale_))
        contact_lanes |= 1u << packet.size;
      if (smooth && !(dot(normal, lane_dir[packet.size]) > 0.0f)) zero_lanes |= 1u << packet.size;
      packet.add(offset_origin(p, normal, offset_scale_), lane_dir[packet.size], std::numeric_limits<float>::infinity(),
                 SurfaceMap::mesh_geometry(mesh_id), tri);
    }
    const unsigned lanes = packet.size;
    zero_lanes |= contact_lanes;
    if (lanes > 0) packet.intersect(rtc_, zero_lanes);
    for (unsigned l = 0; l < lanes; ++l) {
      const uint32_t j = lane_sample[l];
      // Through passable surfaces on the way (transport/rays/passage.h), with what they let through.
      Vec3 through{1, 1, 1};
      const SurfaceHit h = kPassage ? passed(packet, l, lane_dir[l], through) : surfaces_.hit(packet.rh, l);
      const uint32_t mesh = h.index, prim = h.prim;
      Vec3 e{0, 0, 0};
      if (contact_lanes & (1u << l)) {
        ++info.dark;
      } else if (h.kind != SurfaceKind::None) {
        inverse_distance += 1.0 / std::max(double(h.t), 1e-30);
        // The texel the ray lands in, as the photon pass records a hit.
        bool known = false;
        const bool is_mesh = h.kind == SurfaceKind::Triangle, mesh_hit = is_mesh && views_[mesh].texel_area;
        if (is_mesh && !(dot(lane_dir[l], h.normal) < 0.0f)) {
          // The back of a surface: 0, exactly where no photon reached the
          // mesh's backs (the inside of a box standing on the ground).
          if (!source.back_lit[mesh]) {
            ++info.dark;
            known = true;
          } else if (mesh_hit) {
            ++back;
            known = true;
          }
        } else if (mesh_hit) {
          const MeshView& hv = views_[mesh];
          const Mesh& hm = *hv.mesh;
          const int64_t ht =
              covered_uv_texel(&hm.uv[6 * size_t(prim)], h.u, h.v, hm.lightmap_width, hm.lightmap_height, hv.texel_area);
          // A texel that other objects may be pressed against may be partly
          // in contact, and its value (its central square's, or the mean over
          // it) then says little of the lit part next to them: a ray that
          // lands within a texel's width of its origin there is not looked up
          // (the wall of a box at the box's foot sees the floor right beside it).
          const bool unreliable = ht >= 0 && hv.contact && hv.contact[ht] &&
                                  double(h.t) * double(h.t) * std::max(double(areas_[mesh].coverage[ht]), 1e-3) <
                                      hv.texel_area[ht];
          if (ht >= 0 && !unreliable) {
            if (hv.texel_area[ht] > 0.0) {
              const float* d = source.radiosity + 3 * (hv.texel_offset + ht);
              // The lit part's light: the texel's mean over its open share.
              const float open = source.open ? source.open[hv.texel_offset + ht] : 1.0f;
              Vec3 a = kPassage ? albedo_at(h, source) * through : albedo_at(h, source);
              if (materials_) {  // the diffuse radiance toward the texel (layers, Burley)
                const MaterialLobes& ml = materials_->material(hm.material_ids[prim]);
                if (ml.view_scale != MaterialLobes::kNoLayer)
                  a *= materials_->view_scale(ml.view_scale, -dot(lane_dir[l], h.normal));
              }
              a *= lane_weight[l];
              if (open > 0.0f && open < 1.0f) a = a * (1.0f / open);
              e = {a.x * d[0], a.y * d[1], a.z * d[2]};
              if (split) add_gathered(source, hv.texel_offset + ht, e, lane_u[l], split);
              const double albedo = average(a), local = albedo * source.local[hv.texel_offset + ht];
              const uint32_t row = uint32_t(ht) / hm.lightmap_width, column = uint32_t(ht) % hm.lightmap_width;
              const uint64_t cell = uint64_t(mesh) << 42 | uint64_t(row / cell_side_) << 21 | column / cell_side_;
              if (cell_count < kCellCapacity) cells[cell_count++] = {cell, local};
              else cells[kCellCapacity - 1].share += local;  // (more rays than room: taken as one cell)
              local_sum += local;
              local_sq += local * local;
              wide_sum += albedo * source.wide[hv.texel_offset + ht];
              known = true;
            }
          }
        }
        // With lobes: the front of a surface without a diffuse part (glass, a mirror) reflects
        // nothing the gather covers (its light is a caustic's), lightmap or not.
        if (!known && black_known_ && is_mesh && dot(lane_dir[l], h.normal) < 0.0f) {
          const Vec3 a = (*source.albedo)[mesh][prim];
          known = a.x == 0.0f && a.y == 0.0f && a.z == 0.0f;
        }
        if (!known) ++info.unknown;
      }
      ++rays;
      pairs.add(j, sums.add(e), sums);
      if (directional) control.add(e, lane_u[l], lane_n[l]);
    }
  }
  if (directional && rays) control.apply(split + 3 * size_t(source.layers), rays);
  // Many backs lit from behind are a surface whose light no lightmap holds
  // (lightmaps are one-sided).
  if (4 * back > rays) info.unknown += back;
  if (rays) {
    const double cells_sq = cell_shares_sq(cells, cell_count);
    const double n_sq = double(rays) * double(rays);
    info.lookup_all = local_sum * local_sum / n_sq;
    info.lookup_cells = cells_sq / n_sq;
    info.lookup_rays = local_sq / n_sq;
    info.lookup_wide = wide_sum * wide_sum / n_sq;
  }
  if (inverse_distance > 0.0) info.hit_distance = float(rays / inverse_distance);
}

Vec3 FinalGather::albedo_at(const SurfaceHit& h, const GatherSource& source) const {
  if (!textures_) return (*source.albedo)[h.index][h.prim];
  const Mesh& mesh = *views_[h.index].mesh;
  return textures_->albedo(mesh, mesh.material_ids[h.prim], h.prim, h.u, h.v);
}

SurfaceHit FinalGather::passed(const RayPacket& packet, unsigned l, Vec3 dir, Vec3& through) const {
  SurfaceHit h = surfaces_.hit(packet.rh, l);
  if (!passage_->passable(h)) return h;
  const Vec3 origin{packet.rh.ray.org_x[l], packet.rh.ray.org_y[l], packet.rh.ray.org_z[l]};
  h = passage_->continue_through(rtc_, h, dir, through);
  h.t = length(h.point - origin);  // from the texel's point, through the passages
  return h;
}

void update_open_shares(tbb::task_arena& arena, const FinalGather& gather, const TexelSpace& space,
                        const uint8_t* back_lit, OpenShares& open) {
  // Where some texels may be partly closed: meshes whose backs no photon
  // reached (a box standing on the floor) or faces in contact.
  const size_t meshes = space.views.size();
  if (std::equal(back_lit, back_lit + meshes, open.back_lit.begin(), open.back_lit.end())) return;
  open.back_lit.assign(back_lit, back_lit + meshes);
  open.share.clear();
  bool closable = false;
  for (size_t i = 0; i < meshes && !closable; ++i) closable = !back_lit[i] || space.views[i].contact;
  if (!closable) return;
  open.share.assign(space.texel_count, 1.0f);
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, space.covered.size(), 64), [&](const auto& r) {
      for (size_t k = r.begin(); k < r.end(); ++k) {
        const CoveredTexel& c = space.covered[k];
        open.share[space.views[c.mesh].texel_offset + c.texel] = gather.open_share(c.mesh, c.texel, back_lit);
      }
    });
  });
}

GatherResult run_final_gather(const BakeScene& ctx, const FinalGather& gather, const GatherLookup& lookup,
                              OpenShares& open, uint32_t samples, const std::function<bool()>& after_group,
                              CoveredSlice slice, Regather again) {
  tbb::task_arena& arena = ctx.arena;
  const TexelSpace& space = ctx.space;
  const std::vector<std::vector<float>>& images = lookup.images;
  const std::vector<std::vector<float>>& local = lookup.local;
  const std::vector<std::vector<float>>& wide = lookup.wide;
  const std::vector<std::vector<Vec3>>& albedo = lookup.albedo;
  const uint8_t* back_lit = lookup.back_lit;
  std::vector<float> radiosity(3 * space.texel_count, 0.0f), local_error(space.texel_count, 0.0f),
      wide_error(space.texel_count, 0.0f);
  for (size_t i = 0; i < images.size(); ++i) {
    const std::vector<float>& img = images[i];
    const size_t g0 = space.views[i].texel_offset;
    for (size_t t = 0; 4 * t < img.size(); ++t) {
      for (int c = 0; c < 3; ++c) radiosity[3 * (g0 + t) + c] = img[4 * t + c];
      local_error[g0 + t] = local[i][t];
      wide_error[g0 + t] = wide[i][t];
    }
  }
  update_open_shares(arena, gather, space, back_lit, open);
  // With light groups: the layers' shares of every texel's light, in the global order.
  const uint32_t layers = lookup.layer_shares ? uint32_t(ctx.layers.size()) : 0;
  std::vector<float> layer_share(3 * size_t(layers) * (layers ? space.texel_count : 0), 0.0f);
  for (size_t i = 0; layers && i < lookup.layer_shares->size(); ++i) {
    const std::vector<float>& s = (*lookup.layer_shares)[i];
    std::copy(s.begin(), s.end(), layer_share.begin() + 3 * layers * space.views[i].texel_offset);
  }
  const GatherSource source{radiosity.data(), local_error.data(), wide_error.data(), &albedo, back_lit,
                            open.share.empty() ? nullptr : open.share.data(),
                            layers ? layer_share.data() : nullptr, layers, ctx.split.directional};
  const uint32_t slots = layers + (ctx.split.directional ? 3u : 0u);
  slice = slice.clamped(space.covered.size());
  const CoveredTexel* const covered = space.covered.data() + slice.begin;
  // A gather after the first starts from the one before: the texels it does
  // not gather again, and those it has no time left for, keep their rays.
  GatherResult out = again.groups ? std::move(*again.before) : GatherResult{};
  const size_t step = gather_calibration_step(space.covered.size());
  out.sums.resize(slice.size());
  out.info.resize(slice.size());
  out.slots = slots;
  out.split_rgb.resize(3 * size_t(slots) * slice.size(), 0.0f);
  run_in_groups(
      arena, slice.size(), 64,
      [&](uint64_t first_texel, uint64_t n) {
        tbb::parallel_for(tbb::blocked_range<uint64_t>(first_texel, first_texel + n, 16), [&](const auto& r) {
          for (uint64_t k = r.begin(); k < r.end(); ++k) {
            GatherSums& a = out.sums[k];
            GatherInfo& info = out.info[k];
            if (again.groups) {
              const uint32_t g = space.group_of(slice.begin + k);
              if (g < again.groups->size() && !(*again.groups)[g]) continue;  // kept
              a = GatherSums{};
              info = GatherInfo{};
              std::fill_n(out.split_rgb.begin() + 3 * k * slots, 3 * slots, 0.0f);
            }
            gather.sample_texel(covered[k].mesh, covered[k].texel, 0, samples, source, a, info,
                                slots ? &out.split_rgb[3 * k * slots] : nullptr);
            if ((slice.begin + k) % step != 0 || info.unknown) continue;
            // A calibration texel: an independent replicate (it looks up the
            // same estimate, so the difference holds the rays' noise alone).
            GatherSums b;
            GatherInfo b_info;
            gather.sample_texel(covered[k].mesh, covered[k].texel, kCalibrationRound, samples, source, b, b_info);
            if (!a.paired || !b.paired || b_info.unknown) continue;
            const double d = a.mean() - b.mean();
            info.calibration_measured = float(d * d);
            info.calibration_estimated = float(a.pairs_of_mean(a.pair_sq) + b.pairs_of_mean(b.pair_sq));
          }
        });
      },
      [&](uint64_t) { return after_group(); });
  out.typical = typical_sample(out.sums);
  out.scale = gather_scale(out.info);
  return out;
}

size_t gather_calibration_step(size_t covered) { return std::max<size_t>(8, covered / 1024); }

double gather_scale(const std::vector<GatherInfo>& info) {
  double measured = 0.0, estimated = 0.0;
  size_t used = 0;
  for (const GatherInfo& g : info) {
    if (!(g.calibration_estimated > 0.0f)) continue;
    measured += g.calibration_measured;
    estimated += g.calibration_estimated;
    ++used;
  }
  return calibration_ratio(measured, estimated, used);
}

}  // namespace plm

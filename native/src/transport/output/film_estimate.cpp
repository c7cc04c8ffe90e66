#include "transport/output/film_estimate.h"

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "lightmap/reconstruct.h"
#include "util/math.h"

namespace plm {
namespace {

// Radius (texels) of the local linear fit that smooths the gather (reconstruct_linear).
constexpr uint32_t kGatherRadius = 2;
// Radius (texels) over which the variances that weigh photons against the gather are summed.
constexpr uint32_t kWeightRadius = 2;
// A texel's fit reaches at most kGatherReach x the harmonic mean distance of
// its gather rays' hits (docs/design/error-and-gather.md, "Final gather").
constexpr double kGatherReach = 1.0;
// Texels (of radius 2) a lightmap needs for an estimate of its gather fit's bias.
constexpr size_t kMinBiasTexels = 16;

// The gather fit's squared bias by radius (linear_fit_bias over the usable
// texels whose reach allows radius 2; none with fewer than kMinBiasTexels),
// from the fit of radius 2 in b.g_value and the one of radius 1 it makes
// (b.fit1, b.var1, b.rays1). With the gather's variance calibrated, this
// bias is what is left of its error where the bounce light curves (a box's
// foot, a wall under a lamp).
static_assert(kGatherRadius == 2, "the bias estimate compares the fits of radius 1 and 2");
FitBias gather_fit_bias(const TexelAreas& ta, uint32_t width, uint32_t height, EstimateBuffers& b) {
  reconstruct_linear(ta, width, height, b.g_mean.data(), b.g_var.data(), b.g_guide.data(), 1, b.fit1, b.var1,
                     b.radius.data(), 0.9f, b.lookup_rays.data(), &b.rays1);
  const FitBias out = linear_fit_bias(b.fit1, b.var1, b.g_value, b.g_fit_var, b.radius.size(),
                                      [&](size_t t) { return b.usable[t] && b.radius[t] >= 2; });
  return out.texels < kMinBiasTexels ? FitBias() : out;
}

double percentile(std::vector<double>& v, double q) {
  if (v.empty()) return 0.0;
  const size_t k = std::min(v.size() - 1, size_t(q * double(v.size())));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

// Calls fn(m) for every texel m within `radius` rows and columns of texel t, t included.
template <typename Fn>
void for_window(uint32_t width, uint32_t height, uint32_t t, uint32_t radius, Fn&& fn) {
  const int64_t x = t % width, y = t / width, r = radius;
  for (int64_t yy = std::max<int64_t>(y - r, 0); yy <= std::min<int64_t>(y + r, int64_t(height) - 1); ++yy)
    for (int64_t xx = std::max<int64_t>(x - r, 0); xx <= std::min<int64_t>(x + r, int64_t(width) - 1); ++xx)
      fn(uint32_t(yy * width + xx));
}

// Near a wall the photons' mean over the whole texel is biased against the
// value over the points the direct light and the gather sample (the central
// square, texel value CYCLES): where the two disagree by more than their
// noise, the excess squared difference (an unbiased estimate of the squared
// bias) joins the photons' variance, v_photons, and is kept in bias_sq.
// (Joined to both, it would set a floor under the error that no photon count
// lowers: the 21-monkey courtyard took 3.3 M photons to 5 % instead of 16 k.)
// The excess is the neighbours' along the wall, not the texel's own: a
// texel's own would lower the photons' weight exactly where their noise ran
// high, and photon counts are skewed (few texels far above their mean, many
// a little below), so the blend read low.
void photons_bias_sq(const TexelAreas& ta, uint32_t width, uint32_t height, const std::vector<uint8_t>& usable,
                     const std::vector<uint8_t>& radius, const std::vector<double>& value3, const double* g_value,
                     const std::vector<double>& v_gather, std::vector<double>& excess, std::vector<double>& v_photons,
                     std::vector<double>& bias_sq) {
  const size_t n = usable.size();
  auto near_wall = [&](size_t t) { return usable[t] && radius[t] < kGatherRadius; };
  excess.assign(n, std::numeric_limits<double>::quiet_NaN());
  for (size_t t = 0; t < n; ++t) {
    if (!near_wall(t)) continue;
    const double* pv = &value3[3 * t];
    const double* gv = &g_value[3 * t];
    const double diff = (pv[0] + pv[1] + pv[2] - gv[0] - gv[1] - gv[2]) / 3.0;
    excess[t] = diff * diff - v_photons[t] - v_gather[t];
  }
  const float reach = float(3.0 * texel_width(ta));
  for (size_t t = 0; t < n; ++t) {
    if (!near_wall(t)) continue;
    double sum = 0.0;
    uint32_t count = 0;
    for_window(width, height, uint32_t(t), 1, [&](uint32_t m) {
      if (m == t || std::isnan(excess[m]) || !same_surface(ta, uint32_t(t), m, reach, 0.9f)) return;
      sum += excess[m];
      ++count;
    });
    bias_sq[t] = std::max(0.0, count ? sum / double(count) : excess[t]);
    v_photons[t] += bias_sq[t];
  }
}

}  // namespace

double Estimator::csg_texel(size_t c, uint32_t sub, uint64_t photons, double value3[3]) const {
  const size_t g = space.csg_views[c].texel_offset + sub;
  const csg::CsgLightmap& lm = *space.csg_views[c].lightmap;
  const double k = 1.0 / (kPiD * double(std::max<uint64_t>(photons, 1)) * lm.area(sub));
  // The phantom hit scaled by the sub-texel's share of its texel, as a mesh
  // texel's (reconstruct.cpp): photons hit a sliver that much less often.
  const double cover = lm.cover(sub);
  const double phantom_sq = acc.phantom_sq() * cover;
  double variance = 0.0;
  for (int ch = 0; ch < 3; ++ch) value3[ch] = photons ? acc.sum[3 * g + ch] * k : 0.0;
  if (photons) variance = (acc.sum_sq[g] + phantom_sq) * k * k;
  if (photons && !acc.caustic.empty() && acc.caustic.hits[g]) {
    for (int ch = 0; ch < 3; ++ch) value3[ch] += acc.caustic.sum[3 * g + ch] * k;
    variance += (acc.caustic.sum_sq[g] + acc.caustic.phantom_sq() * cover) * k * k;
  }
  if (!direct.empty()) {
    const size_t k = space.covered_begin[space.views.size() + c] + sub;
    for (int ch = 0; ch < 3; ++ch) value3[ch] += direct.value3[3 * k + ch];
    variance += direct.variance[k];
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
// texels whose rays met dark backs (their G is their own). The fit's radius
// (0, 1 or 2) is the lightmap's of least estimated error, squared bias
// included, as the sky pool's (transport/direct/direct_pool.cpp): a linear fit reads the
// middle of a field that peaks inside a surface low and its edges high, and
// where the gather is precise that bias outweighs what a wider fit saves.
// Where the fit is narrowed, A (a mean over the whole texel, G over its
// central square) is tested against G for bias.
// var G: the fit's variance from the texels' own (their pair estimates,
// calibrated: gather_scale), the fit's squared bias (gather_fit_bias), and
// the error of what the rays looked up: its wide part whole; of its local
// part, the share rho of ray pairs that look up the same errors (measured
// within texels over the lightmap: pairs in one cell, GatherInfo) whole, the
// rest averaged down by the fit like independent errors. Rays from
// neighbouring texels are taken to meet the same cells as one texel's rays.
// An open scene's gather rays spread over many cells (rho 0.01-0.25); rays
// in a room meet more of the same.
// Adds the gather's part of the texels' variances, (1 - w)^2 var G, to
// gather_part->all, and of that the rays' own noise (the fit's variance) to
// gather_part->rays.
void Estimator::combine_gather(size_t i, EstimateBuffers& b, GatherPart* gather_part, LookupError* lookup) const {
  const Mesh& mesh = *space.views[i].mesh;
  std::vector<double>& value3 = b.value3;
  std::vector<double>& variance = b.variance;
  const size_t n = variance.size();
  std::vector<double>& g_mean = b.g_mean;
  std::vector<double>& g_var = b.g_var;
  std::vector<double>& guide = b.g_guide;
  std::vector<double>& lookup_rays = b.lookup_rays;
  std::vector<uint8_t>& usable = b.usable;
  std::vector<uint8_t>& radius = b.radius;
  g_mean.assign(3 * n, 0.0);
  g_var.assign(n, 0.0);
  guide.assign(n, -1.0);
  lookup_rays.assign(n, 0.0);
  usable.assign(n, 0);
  radius.assign(n, uint8_t(kGatherRadius));
  b.photon_weight.assign(n, 1.0);
  double shared = 0.0, pairs = 0.0;  // over the texels: ray pairs' products within one cell, and all
  const double width = texel_width(space.areas[i]);
  size_t k = space.covered_begin[i];
  for (size_t t = 0; t < n; ++t) {
    if (!(space.areas[i].area[t] > 0.0)) continue;
    const GatherInfo& info = gather->info[k];
    const GatherSums& g = gather->sums[k];
    const double direct_mean = direct.mean(k++);
    // The fit reaches no further than kGatherReach x the harmonic mean
    // distance of the texel's gather hits: near a wall the bounce light
    // changes faster than a plane follows. A texel whose rays met dark
    // backs (partly under a box) keeps its own gather and pools with none:
    // its neighbours' light is not its own.
    radius[t] = uint8_t(std::min(double(kGatherRadius), std::floor(kGatherReach * info.hit_distance / width)));
    if (info.dark) radius[t] = 0;
    if (info.unknown || g.count == 0) continue;
    usable[t] = 1;
    guide[t] = info.dark ? -1.0 : direct_mean;
    for (int c = 0; c < 3; ++c) g_mean[3 * t + c] = g.rgb[c] / g.count;
    // The calibration's scale is the open texels' (most of them): next to a
    // wall, where the hemisphere holds an edge, neighbouring strata differ by
    // noise more than by the smooth change the scale takes out, so there the
    // pairs are not scaled down (the open test scene's box-foot texels).
    const double scale = radius[t] < kGatherRadius ? std::max(1.0, gather->scale) : gather->scale;
    // Every ray met a dark back (the texel's points are under a box): no
    // light reaches them.
    g_var[t] = info.dark == g.count ? 0.0 : g.variance_of_mean(gather->typical, 0.0, scale);
    lookup_rays[t] = info.lookup_rays;
    shared += info.lookup_cells - info.lookup_rays;
    pairs += info.lookup_all - info.lookup_rays;
  }
  reconstruct_linear(space.areas[i], mesh.lightmap_width, mesh.lightmap_height, g_mean.data(), g_var.data(),
                     guide.data(), kGatherRadius, b.g_value, b.g_fit_var, radius.data(), 0.9f, lookup_rays.data(),
                     &b.rays_fit);
  const double rho = pairs > 0.0 ? std::clamp(shared / pairs, 0.0, 1.0) : 1.0;
  const FitBias fit_bias = gather_fit_bias(space.areas[i], mesh.lightmap_width, mesh.lightmap_height, b);
  // By radius: the fits' values, their variances and their lookup rays' variances.
  const double* fits[3] = {g_mean.data(), b.fit1.data(), b.g_value.data()};
  const double* fit_vars[3] = {g_var.data(), b.var1.data(), b.g_fit_var.data()};
  const double* fit_rays[3] = {lookup_rays.data(), b.rays1.data(), b.rays_fit.data()};
  auto fit_variance = [&](uint32_t r, size_t t) { return fit_vars[r][t] + (1.0 - rho) * fit_rays[r][t]; };
  auto is_usable = [&](size_t t) { return usable[t] != 0; };
  const uint32_t fit_r = fit_bias.texels == 0  // the bias unknown: the widest fit
                             ? kGatherRadius
                             : least_error_radius(n, radius.data(), fit_bias, is_usable, fit_variance);
  const double* g_value = fits[fit_r];
  const double* g_fit_var = fit_vars[fit_r];
  const TexelAreas& ta = space.areas[i];
  const uint32_t width_i = mesh.lightmap_width, height_i = mesh.lightmap_height;
  // Per usable texel: the gather's variance, the photons' (their squared
  // bias against the gather included) and that squared bias.
  std::vector<double>& v_gather = b.v_gather;
  std::vector<double>& v_photons = b.v_photons;
  std::vector<double>& bias_sq = b.bias_sq;
  v_gather.assign(n, 0.0);
  v_photons.assign(n, 0.0);
  bias_sq.assign(n, 0.0);
  for (size_t t = 0, k = space.covered_begin[i]; t < n; ++t) {
    if (!(ta.area[t] > 0.0)) continue;
    const GatherInfo& info = gather->info[k++];
    if (!usable[t]) continue;
    const double v_lookups = (1.0 - rho) * fit_rays[fit_r][t] + rho * info.lookup_all + info.lookup_wide;
    v_gather[t] = g_fit_var[t] + fit_bias.sq[std::min<uint32_t>(radius[t], fit_r)] + v_lookups;
    v_photons[t] = variance[t];
  }
  if (central_window) photons_bias_sq(ta, width_i, height_i, usable, radius, value3, g_value, v_gather, b.excess,
                                      v_photons, bias_sq);
  // The weights come from the variances of the texels around (kWeightRadius,
  // same surface), not the texel's own alone: estimated from the same hits
  // and rays as the values they weigh, its own are high where its values
  // are (more photon hits, a ray on a bright patch), and weights that fall
  // where a value is high read the light low (the walls of a room lit
  // through a window 1-4 % at 250 k photons: docs/bench_window_gather.py).
  // Texels whose gather pools with none (a negative guide: their rays met
  // dark backs, or something they cannot look up) keep their own.
  const float weight_reach = float(1.5 * (kWeightRadius + 1) * width);
  const double floor = guide_floor_of(ta, guide.data(), n);
  for (size_t t = 0; t < n; ++t) {
    if (!usable[t]) continue;
    double sum_photons = 0.0, sum_gather = 0.0;
    for_window(width_i, height_i, uint32_t(t), kWeightRadius, [&](uint32_t m) {
      if (!usable[m] || !(m == t || (same_surface(ta, uint32_t(t), m, weight_reach, 0.9f) &&
                                     similar_guide(guide.data(), m, uint32_t(t), floor))))
        return;
      sum_photons += v_photons[m], sum_gather += v_gather[m];
    });
    const double w = sum_photons + sum_gather > 0.0 ? sum_gather / (sum_photons + sum_gather) : 0.0;
    for (int c = 0; c < 3; ++c) value3[3 * t + c] = w * value3[3 * t + c] + (1.0 - w) * g_value[3 * t + c];
    b.photon_weight[t] = w;
    variance[t] = w * w * v_photons[t] + (1.0 - w) * (1.0 - w) * v_gather[t];
    // What a later gather's lookups see: the gather's own noise is local (its
    // fit's reach); its fit's bias and what its lookups carried in from far
    // texels are wide.
    if (lookup) {
      const double far = v_gather[t] - g_fit_var[t];  // the fit's bias and the lookups'
      lookup->local[t] = w * w * lookup->local[t] + (1.0 - w) * (1.0 - w) * g_fit_var[t];
      lookup->wide[t] = w * w * (lookup->wide[t] + bias_sq[t]) + (1.0 - w) * (1.0 - w) * far;
    }
    if (gather_part) {
      const double share = open_weight(i, t) * (1.0 - w) * (1.0 - w);
      gather_part->all += share * v_gather[t];
      gather_part->rays += share * g_fit_var[t];
    }
  }
}

double Estimator::open_weight(size_t i, size_t t) const {
  return open_share && !open_share->empty() ? double((*open_share)[space.views[i].texel_offset + t]) : 1.0;
}

double Estimator::level_variance(size_t i) const {
  if (i >= space.judged.size() || space.judged[i] >= acc.group_hits.size()) return 0.0;
  const double k = double(acc.group_hits[space.judged[i]]), k_sq = double(acc.group_hits_sq[space.judged[i]]);
  return k > 0.0 ? k_sq / (k * k) : 1.0;
}

const double* Estimator::guide(size_t i, std::vector<double>& buffer) const {
  if (direct.empty()) return nullptr;
  buffer.assign(space.areas[i].area.size(), 0.0);
  size_t k = space.covered_begin[i];
  for (size_t t = 0; t < buffer.size(); ++t)
    if (space.areas[i].area[t] > 0.0) buffer[t] = direct.mean(k++);
  return buffer.data();
}

void Estimator::texels(size_t i, uint64_t photons, EstimateBuffers& b, GatherPart* gather_part, bool lookups,
                       PhotonPart* part) const {
  std::vector<double>& value3 = b.value3;
  std::vector<double>& variance = b.variance;
  LookupError* lookup = lookups ? &b.lookup : nullptr;
  b.photon_weight.clear();
  const Mesh& mesh = *space.views[i].mesh;
  const size_t n = size_t(mesh.lightmap_width) * mesh.lightmap_height;
  // The photons' part: as the estimate before made it where `part` holds
  // these photons, else reconstructed (and kept in `part`).
  const bool kept = photons > 0 && part && part->photons == photons;
  if (photons > 0 && !kept) {
    ReconstructParams params;
    params.max_radius = filter_radius;
    params.photons = double(photons);
    params.phantom_sq = acc.phantom_sq();
    params.guide = guide(i, b.guide);  // the direct light guides the reconstruction
    const size_t g0 = space.views[i].texel_offset;
    reconstruct_indirect(space.areas[i], mesh.lightmap_width, mesh.lightmap_height,
                         {&acc.sum[3 * g0], &acc.sum_sq[g0], &acc.hits[g0]}, params, value3, variance, lookup);
  } else {
    value3.assign(3 * n, 0.0);
    variance.assign(n, 0.0);
    if (lookup) lookup->local.assign(n, 0.0), lookup->wide.assign(n, 0.0);
  }
  if (photons > 0 && part) {  // from the kept part, or into it
    for (size_t t = 0, k = space.covered_begin[i]; t < n; ++t) {
      if (!(space.areas[i].area[t] > 0.0)) continue;
      if (kept) {
        for (int c = 0; c < 3; ++c) value3[3 * t + c] = part->value3[3 * k + c];
        variance[t] = part->mse[k];
        if (lookup) lookup->local[t] = part->local[k], lookup->wide[t] = part->wide[k];
      } else {
        for (int c = 0; c < 3; ++c) part->value3[3 * k + c] = value3[3 * t + c];
        part->mse[k] = variance[t];
        if (lookup) part->local[k] = lookup->local[t], part->wide[k] = lookup->wide[t];
      }
      ++k;
    }
  }
  if (photons > 0 && gather && !gather->sums.empty()) combine_gather(i, b, gather_part, lookup);
  if (photons > 0 && !acc.caustic.empty()) add_caustics(i, photons, value3, variance, lookup);
  if (direct.empty()) return;
  size_t k = space.covered_begin[i];
  for (size_t t = 0; t < variance.size(); ++t) {
    if (!(space.areas[i].area[t] > 0.0)) continue;
    for (int c = 0; c < 3; ++c) value3[3 * t + c] += direct.value3[3 * k + c];
    variance[t] += direct.variance[k];
    if (lookup) lookup->local[t] += direct.variance[k];
    ++k;
  }
}

// Caustic photons (scenes with lobes: paths whose last event was specular)
// are reconstructed apart from the others, without the direct light's guide
// (a caustic's edges are not the direct light's) and with a pooling radius
// of their own, chosen by the estimated error as for the ordinary photons;
// their value and mean squared error add to the texel's.
void Estimator::add_caustics(size_t i, uint64_t photons, std::vector<double>& value3, std::vector<double>& variance,
                             LookupError* lookup) const {
  const Mesh& mesh = *space.views[i].mesh;
  const size_t g0 = space.views[i].texel_offset;
  ReconstructParams params;
  params.max_radius = filter_radius;
  params.photons = double(photons);
  params.phantom_sq = acc.caustic.phantom_sq();
  std::vector<double> c_value, c_mse;
  LookupError c_lookup;
  reconstruct_indirect(space.areas[i], mesh.lightmap_width, mesh.lightmap_height,
                       {&acc.caustic.sum[3 * g0], &acc.caustic.sum_sq[g0], &acc.caustic.hits[g0]}, params, c_value,
                       c_mse, lookup ? &c_lookup : nullptr);
  for (size_t t = 0; t < variance.size(); ++t) {
    for (int c = 0; c < 3; ++c) value3[3 * t + c] += c_value[3 * t + c];
    variance[t] += c_mse[t];
    if (lookup) lookup->local[t] += c_lookup.local[t], lookup->wide[t] += c_lookup.wide[t];
  }
}

void estimate(tbb::task_arena& arena, const Estimator& est, uint64_t photons, Estimate& out) {
  out.photons = photons;
  out.gather_size = est.gather ? est.gather->sums.size() : 0;
  const size_t meshes = est.space.views.size();
  out.values.resize(meshes);
  out.lookup_local.resize(est.lookups ? meshes : 0);
  out.lookup_wide.resize(out.lookup_local.size());
  ErrorEstimate& e = out.error;
  e = ErrorEstimate{};
  // Lightmaps in parallel (for_lightmaps; their reconstructions run in
  // parallel too), each with its own sums, added in order: the same for any
  // thread count.
  // Per mesh, then per CSG solid.
  struct Sums {
    double value = 0.0, var = 0.0, var_direct = 0.0, count = 0.0;
    GatherPart var_gather;
    size_t dark = 0;
    std::vector<double> per_texel;
    // None for sums without light or, for a judged group, with a mean at
    // most dark_mean (kDarkGroupShare).
    ErrorParts parts(double dark_mean = 0.0) const {
      if (!(count > 0.0 && value > 0.0 && value / count > dark_mean)) return {};
      const double mean = value / count;
      return {std::sqrt(var / count) / mean, std::sqrt(var_direct / count) / mean,
              std::sqrt(var_gather.all / count) / mean, std::sqrt(var_gather.rays / count) / mean, mean};
    }
  };
  std::vector<Sums> sums(meshes);
  tbb::enumerable_thread_specific<EstimateBuffers> buffers;
  // Before the first final gather, the photons' part is kept for the
  // estimates after the gathers (the same photons); later ones free it.
  PhotonPart& kept = out.photon_part;
  const bool reuse = est.lookups && photons > 0 && kept.photons == photons;
  const bool keep = !reuse && est.lookups && photons > 0 && est.gather && est.gather->sums.empty();
  if (!reuse) kept = PhotonPart();
  if (keep) {
    const size_t covered = est.space.covered.size();
    kept.value3.resize(3 * covered);
    kept.mse.resize(covered);
    kept.local.resize(covered);
    kept.wide.resize(covered);
  }
  PhotonPart* part = reuse || keep ? &kept : nullptr;
  arena.execute([&] {
    for_lightmaps(meshes, [&](size_t i) { return est.space.areas[i].area.size(); }, [&](size_t i) {
      if (!est.space.views[i].texel_area) return;
      EstimateBuffers& b = buffers.local();
      Sums& s = sums[i];
      est.texels(i, photons, b, &s.var_gather, est.lookups, part);
      const std::vector<double>& value3 = b.value3;
      const std::vector<double>& variance = b.variance;
      std::vector<float>& img = out.values[i];
      img.assign(4 * variance.size(), 0.0f);
      if (est.lookups) {
        out.lookup_local[i].assign(variance.size(), 0.0f);
        out.lookup_wide[i].assign(variance.size(), 0.0f);
      }
      const double level = est.level_variance(i);
      for (size_t t = 0, k = est.space.covered_begin[i]; t < variance.size(); ++t) {
        if (!(est.space.areas[i].area[t] > 0.0)) continue;
        store_texel(value3, variance, t, img.data());
        const double v = (value3[3 * t] + value3[3 * t + 1] + value3[3 * t + 2]) / 3.0;
        if (est.lookups) {
          const double indirect = std::max(0.0, v - (est.direct.empty() ? 0.0 : est.direct.mean(k)));
          out.lookup_local[i][t] = float(std::sqrt(b.lookup.local[t]));
          out.lookup_wide[i][t] = float(std::sqrt(b.lookup.wide[t] + indirect * indirect * level));
        }
        ++k;
        const double w = est.open_weight(i, t);
        if (!(w > 0.0)) continue;  // inside another object: never seen
        s.value += w * v;
        s.var += w * variance[t];
        s.count += w;
        if (v > 0.0) s.per_texel.push_back(std::sqrt(variance[t]) / v);
        else ++s.dark;
      }
    });
  });
  if (part) part->photons = photons;
  const TexelSpace& space = est.space;
  sums.resize(meshes + space.csg_views.size());
  for (size_t c = 0; c < space.csg_views.size(); ++c) {
    if (!space.csg_views[c].lightmap) continue;
    Sums& s = sums[meshes + c];
    for (uint32_t sub = 0; sub < space.csg_views[c].lightmap->sub_texel_count(); ++sub) {
      double v3[3];
      const double var = est.csg_texel(c, sub, photons, v3);
      const double v = (v3[0] + v3[1] + v3[2]) / 3.0;
      s.value += v;
      s.var += var;
      s.count += 1.0;
      if (v > 0.0) s.per_texel.push_back(std::sqrt(var) / v);
      else ++s.dark;
    }
  }
  // The whole, then each judged group: its units' sums and its texels' direct variance.
  Sums whole;
  std::vector<Sums> groups(space.judged_groups);
  std::vector<double> per_texel;
  for (size_t u = 0; u < sums.size(); ++u) {
    const Sums& s = sums[u];
    whole.value += s.value, whole.var += s.var, whole.var_gather += s.var_gather, whole.count += s.count;
    e.dark_texels += s.dark;
    per_texel.insert(per_texel.end(), s.per_texel.begin(), s.per_texel.end());
    if (u >= space.judged.size() || space.judged[u] == kNoGroup) continue;
    Sums& g = groups[space.judged[u]];
    g.value += s.value, g.var += s.var, g.var_gather += s.var_gather, g.count += s.count;
  }
  const bool direct_per_texel = space.judged_groups > 0 && est.direct.variance.size() == space.covered.size();
  for (size_t k = 0; k < est.direct.variance.size(); ++k) {
    const double v =
        (direct_per_texel ? est.open_weight(space.covered[k].mesh, space.covered[k].texel) : 1.0) * est.direct.variance[k];
    whole.var_direct += v;
    if (direct_per_texel) groups[space.group_of(k)].var_direct += v;
  }
  static_cast<ErrorParts&>(e) = whole.parts();
  const double dark_mean = whole.count > 0.0 ? kDarkGroupShare * whole.value / whole.count : 0.0;
  for (const Sums& g : groups) e.groups.push_back(g.parts(dark_mean));
  if (e.groups.empty()) e.groups.push_back(e);
  for (uint32_t g = 0; g < e.groups.size() && !groups.empty(); ++g)
    if (e.groups[g].relative > 0.0 && (e.worst == kNoGroup || e.groups[g].relative > e.groups[e.worst].relative))
      e.worst = g;
  e.median = percentile(per_texel, 0.5);
  e.p95 = percentile(per_texel, 0.95);
  e.per_texel.swap(per_texel);
}

double share_above(const ErrorEstimate& e, double threshold) {
  const size_t n = e.per_texel.size() + e.dark_texels;
  if (n == 0) return 0.0;
  return double(std::count_if(e.per_texel.begin(), e.per_texel.end(), [&](double r) { return r > threshold; })) /
         double(n);
}

}  // namespace plm

#include "transport/output/layers.h"

#include <algorithm>
#include <cmath>

#include "lightmap/reconstruct.h"
#include "transport/film/film.h"

namespace plm {
namespace {

// Per layer and channel, a share of a whole: part[l * stride + c] / the
// parts' sum, or `fallback` where the sum is 0.
struct Shares {
  std::vector<double> s;  // 3 per layer
  void of(const double* part, size_t stride, uint32_t layers, const std::vector<double>& fallback) {
    s.assign(3 * size_t(layers), 0.0);
    for (int c = 0; c < 3; ++c) {
      double whole = 0.0;
      for (uint32_t l = 0; l < layers; ++l) whole += part[l * stride + c];
      for (uint32_t l = 0; l < layers; ++l)
        s[3 * l + c] = whole > 0.0 ? part[l * stride + c] / whole : fallback[3 * l + c];
    }
  }
  // Layer l's share of a whole of value3, its channels weighed by their
  // value (none below 0: a texel's indirect part may be a rounding below 0).
  double mean(uint32_t l, const double value3[3]) const {
    double w = 0.0, sum = 0.0;
    for (int c = 0; c < 3; ++c) w += std::max(0.0, value3[c]), sum += s[3 * l + c] * std::max(0.0, value3[c]);
    return w > 0.0 ? sum / w : (s[3 * l] + s[3 * l + 1] + s[3 * l + 2]) / 3.0;
  }
};

// The shares of a whole lightmap (a texel with no part of its own takes
// these): per layer and channel, its sums over the texels over theirs; equal
// shares where nothing at all was recorded.
std::vector<double> mesh_shares(const std::vector<double>& totals, uint32_t layers) {
  std::vector<double> out(3 * size_t(layers), 1.0 / double(layers));
  for (int c = 0; c < 3; ++c) {
    double whole = 0.0;
    for (uint32_t l = 0; l < layers; ++l) whole += totals[3 * l + c];
    if (whole > 0.0)
      for (uint32_t l = 0; l < layers; ++l) out[3 * l + c] = totals[3 * l + c] / whole;
  }
  return out;
}

double mean3(const double* v) { return (v[0] + v[1] + v[2]) / 3.0; }

// What splits a lightmap's texels: each layer's photons pooled as the whole's
// reconstruction pools them, the whole's pool (for the shares' noise), the
// photons' weight in the blend with the final gather, and the lightmap's own
// shares for texels without parts.
struct Parts {
  std::vector<double> pooled;  // 3 per layer per texel
  std::vector<double> whole_value, whole_mse;
  std::vector<double> caustic_value;  // the caustic photons' pooled flux (3 per texel; empty without)
  std::vector<double> photon_weight;  // per texel; empty without a gather
  std::vector<double> photon_fallback, direct_fallback, gather_fallback;
};

// Of slots [first, first + layers) of the split (transport/context/split.h);
// with `caustics`, also the caustic photons pooled alike (Parts::caustic_value).
Parts mesh_parts(const Estimator& est, size_t i, uint64_t photons, uint32_t first, uint32_t layers,
                 bool caustics = false) {
  const uint32_t slots = est.acc.slots();
  const TexelAreas& ta = est.space.areas[i];
  const Mesh& mesh = *est.space.views[i].mesh;
  const size_t n = ta.area.size();
  Parts p;
  p.pooled.assign(3 * size_t(layers) * n, 0.0);
  if (photons > 0) {
    std::vector<double> guide, value3, mse;
    ReconstructParams params;
    params.max_radius = est.filter_radius;
    params.photons = double(photons);
    params.phantom_sq = est.acc.phantom_sq();
    params.guide = est.guide(i, guide);
    const uint64_t g0 = est.space.views[i].texel_offset;
    const PhotonSums whole{&est.acc.sum[3 * g0], &est.acc.sum_sq[g0], &est.acc.hits[g0]};
    params.fixed_radius = int32_t(reconstruct_indirect(ta, mesh.lightmap_width, mesh.lightmap_height, whole, params,
                                                       p.whole_value, p.whole_mse));
    if (caustics && !est.acc.caustic.empty()) {
      const Accumulators::CausticSums& cs = est.acc.caustic;
      const PhotonSums caustic{&cs.sum[3 * g0], &cs.sum_sq[g0], &cs.hits[g0]};
      reconstruct_indirect(ta, mesh.lightmap_width, mesh.lightmap_height, caustic, params, p.caustic_value, mse);
    }
    for (uint32_t l = 0; l < layers; ++l) {
      const PhotonSums part{est.acc.slot_flux(first + l, g0), &est.acc.sum_sq[g0], &est.acc.hits[g0]};
      reconstruct_indirect(ta, mesh.lightmap_width, mesh.lightmap_height, part, params, value3, mse);
      for (size_t t = 0; t < n; ++t)
        for (int c = 0; c < 3; ++c) p.pooled[3 * (t * layers + l) + c] = value3[3 * t + c];
    }
    if (est.gather && !est.gather->sums.empty()) {
      EstimateBuffers b;
      est.texels(i, photons, b);
      p.photon_weight.swap(b.photon_weight);
    }
  }
  const DirectResult* dr = est.direct_result;
  const GatherResult* gr = est.gather && est.gather->slots == slots ? est.gather : nullptr;
  std::vector<double> photon_totals(3 * size_t(layers), 0.0), direct_totals = photon_totals,
                      gather_totals = photon_totals;
  for (size_t t = 0, k = est.space.covered_begin[i]; t < n; ++t) {
    if (!(ta.area[t] > 0.0)) continue;
    for (size_t f = 0; f < 3 * size_t(layers); ++f) {
      photon_totals[f] += p.pooled[3 * t * layers + f];
      if (dr && !dr->split_rgb.empty()) direct_totals[f] += dr->split_rgb[3 * (k * slots + first) + f];
      if (gr && !gr->split_rgb.empty()) gather_totals[f] += gr->split_rgb[3 * (k * slots + first) + f];
    }
    ++k;
  }
  p.photon_fallback = mesh_shares(photon_totals, layers);
  p.direct_fallback = mesh_shares(direct_totals, layers);
  p.gather_fallback = mesh_shares(gather_totals, layers);
  return p;
}

// The direct and gather sums a lightmap's split reads: the direct pass's
// where the estimate has direct light and the sums a split, the gather's
// where the estimate blends photons with it (Parts::photon_weight); else null.
struct SplitSources {
  const DirectResult* direct = nullptr;
  const GatherResult* gather = nullptr;
};
SplitSources split_sources(const Estimator& est, const Parts& parts) {
  SplitSources s;
  const DirectResult* dr = est.direct_result;
  if (!est.direct.empty() && dr && !dr->split_rgb.empty()) s.direct = dr;
  const GatherResult* gr = est.gather;
  if (gr && gr->slots == est.acc.slots() && !gr->split_rgb.empty() && !parts.photon_weight.empty()) s.gather = gr;
  return s;
}

}  // namespace

void layer_texels(const Estimator& est, size_t i, uint64_t photons, const std::vector<float>& values,
                  std::vector<std::vector<float>>& layers_out) {
  const uint32_t layers = est.acc.split.layers, slots = est.acc.slots();
  const TexelAreas& ta = est.space.areas[i];
  const size_t n = ta.area.size();
  layers_out.assign(layers, std::vector<float>(4 * n, 0.0f));
  if (layers == 0) return;
  const Parts parts = mesh_parts(est, i, photons, 0, layers);
  const SplitSources src = split_sources(est, parts);
  const DirectResult* dr = src.direct;
  const bool direct = dr != nullptr;
  const GatherResult* gr = src.gather;
  Shares direct_share, photon_share, gather_share;
  std::vector<double> raw(3 * size_t(layers), 0.0), gathered(3 * size_t(layers), 0.0);
  for (size_t t = 0, k = est.space.covered_begin[i]; t < n; ++t) {
    if (!(ta.area[t] > 0.0)) continue;
    double d[3] = {0, 0, 0}, ind[3], var_d = 0.0;
    if (direct) {
      for (int c = 0; c < 3; ++c) d[c] = est.direct.value3[3 * k + c];
      var_d = est.direct.variance[k];
      for (size_t f = 0; f < raw.size(); ++f) raw[f] = dr->split_rgb[3 * k * slots + f];
    }
    for (int c = 0; c < 3; ++c) ind[c] = double(values[4 * t + c]) - d[c];
    const double error = values[4 * t + 3];
    const double var_ind = std::max(0.0, error * error - var_d);
    direct_share.of(raw.data(), 3, layers, parts.direct_fallback);
    photon_share.of(&parts.pooled[3 * t * layers], 3, layers, parts.photon_fallback);
    // The indirect light's shares: the photons' where they alone give it,
    // else the photons' and the final gather's (each layer's part of what
    // the texel's gather rays saw) as the estimate blends the two.
    double a[3] = {0, 0, 0}, g[3] = {0, 0, 0}, w = 1.0, gather_relative = 0.0;
    if (!parts.whole_value.empty())
      for (int c = 0; c < 3; ++c) a[c] = parts.whole_value[3 * t + c];
    if (gr && parts.photon_weight[t] < 1.0 && gr->sums[k].count > 0) {
      const GatherSums& gs = gr->sums[k];
      w = parts.photon_weight[t];
      for (int c = 0; c < 3; ++c) g[c] = gs.rgb[c] / gs.count;
      for (size_t f = 0; f < gathered.size(); ++f) gathered[f] = gr->split_rgb[3 * k * slots + f];
      gather_share.of(gathered.data(), 3, layers, parts.gather_fallback);
      const double gm = mean3(g);
      gather_relative = gm > 0.0 ? gs.variance_of_mean(gr->typical, 0.0, gr->scale) / (gm * gm) : 0.0;
    }
    // The shares' own noise: with one light chosen per sample, how the n
    // samples fell to the groups (binomial); the photons' share from the
    // texel's pool (its relative variance), the gather's from its rays'.
    const double d_mean = mean3(d), i_mean = std::max(0.0, mean3(ind));
    const double samples = direct ? std::max(1.0, double(dr->sums[k].count)) : 1.0;
    const double a_mean = mean3(a), a_w = w * a_mean, g_w = (1.0 - w) * mean3(g);
    const double photon_relative =
        a_mean > 0.0 && !parts.whole_mse.empty() ? parts.whole_mse[t] / (a_mean * a_mean) : 0.0;
    for (uint32_t l = 0; l < layers; ++l) {
      float* out = &layers_out[l][4 * t];
      for (int c = 0; c < 3; ++c) {
        double share = photon_share.s[3 * l + c];
        const double den = w * a[c] + (1.0 - w) * g[c];
        if (w < 1.0 && den > 0.0) share = (w * a[c] * share + (1.0 - w) * g[c] * gather_share.s[3 * l + c]) / den;
        out[c] = float(d[c] * direct_share.s[3 * l + c] + ind[c] * share);
      }
      const double sd = direct_share.mean(l, d), sp = photon_share.mean(l, ind);
      const double sg = w < 1.0 ? gather_share.mean(l, g) : sp;
      const double split = a_w + g_w > 0.0 ? 1.0 / (a_w + g_w) : 0.0;
      const double si = a_w + g_w > 0.0 ? (a_w * sp + g_w * sg) * split : sp;
      const double choice = direct && dr->chooses_lights ? d_mean * d_mean * sd * (1.0 - sd) / samples : 0.0;
      const double share_var = (a_w * split) * (a_w * split) * sp * (1.0 - sp) * photon_relative +
                               (g_w * split) * (g_w * split) * sg * (1.0 - sg) * gather_relative;
      // A layer is split from the texel's value, and the split is about as
      // noisy as the value: measured, a layer's absolute error comes within
      // 0.7-1.3x the texel's whatever its share (docs/design/light-groups.md,
      // "A layer's error"), which the terms above miss for a group with a
      // small share. The rest of the texel's variance bounds the layer's from below.
      const double s = sd * d_mean + si * i_mean, whole = d_mean + i_mean;
      const double floor = whole > 0.0 ? (1.0 - s / whole) * error * error : 0.0;
      const double var = std::max(floor, sd * var_d + choice + si * si * var_ind + i_mean * i_mean * share_var);
      out[3] = float(std::sqrt(std::max(0.0, var)));
    }
    ++k;
  }
}

void direction_texels(const Estimator& est, size_t i, uint64_t photons, const std::vector<float>& values,
                      std::vector<std::vector<float>>& axes) {
  const SplitLayout& split = est.acc.split;
  const uint32_t slots = est.acc.slots(), first = split.layers;
  const TexelAreas& ta = est.space.areas[i];
  const size_t n = ta.area.size();
  axes.assign(3, std::vector<float>(4 * n, 0.0f));
  if (!split.directional) return;
  const Parts parts = mesh_parts(est, i, photons, first, 3, true);  // the slots hold caustic hits too
  const SplitSources src = split_sources(est, parts);
  const DirectResult* dr = src.direct;
  const bool direct = dr != nullptr;
  const GatherResult* gr = src.gather;
  // A part's moment over its light, per axis and channel (0 where it has no light).
  auto ratio = [](double part, double whole) { return whole > 0.0 ? part / whole : 0.0; };
  for (size_t t = 0, k = est.space.covered_begin[i]; t < n; ++t) {
    if (!(ta.area[t] > 0.0)) continue;
    double d[3] = {0, 0, 0}, ind[3];
    if (direct)
      for (int c = 0; c < 3; ++c) d[c] = est.direct.value3[3 * k + c];
    for (int c = 0; c < 3; ++c) ind[c] = double(values[4 * t + c]) - d[c];
    // The indirect light's moments: the photons' where they alone give it,
    // else the photons' and the final gather's as the estimate blends them.
    double w = 1.0, g[3] = {0, 0, 0};
    const GatherSums* gs = nullptr;
    if (gr && parts.photon_weight[t] < 1.0 && gr->sums[k].count > 0) {
      gs = &gr->sums[k];
      w = parts.photon_weight[t];
      for (int c = 0; c < 3; ++c) g[c] = gs->rgb[c] / gs->count;
    }
    for (uint32_t a = 0; a < 3; ++a) {
      float* out = &axes[a][4 * t];
      for (int c = 0; c < 3; ++c) {
        const double sd = direct ? ratio(dr->split_rgb[3 * (k * slots + first + a) + c], dr->sums[k].rgb[c]) : 0.0;
        // The photons' flux pooled as the moments' are: ordinary and caustic hits alike.
        const double pa = (parts.whole_value.empty() ? 0.0 : parts.whole_value[3 * t + c]) +
                          (parts.caustic_value.empty() ? 0.0 : parts.caustic_value[3 * t + c]);
        double si = ratio(parts.pooled.empty() ? 0.0 : parts.pooled[3 * (3 * t + a) + c], pa);
        if (gs) {
          const double sg = ratio(gr->split_rgb[3 * (k * slots + first + a) + c], gs->rgb[c]);
          const double den = w * pa + (1.0 - w) * g[c];
          if (den > 0.0) si = (w * pa * si + (1.0 - w) * g[c] * sg) / den;
        }
        out[c] = float(d[c] * sd + ind[c] * si);
      }
    }
    ++k;
  }
}

std::vector<std::vector<float>> layer_shares(tbb::task_arena& arena, const Estimator& est, uint64_t photons,
                                             const std::vector<std::vector<float>>& values) {
  const uint32_t layers = est.acc.split.layers;
  const size_t meshes = est.space.views.size();
  std::vector<std::vector<float>> out(meshes);
  arena.execute([&] {
    for_lightmaps(meshes, [&](size_t i) { return est.space.areas[i].area.size(); }, [&](size_t i) {
      if (!est.space.views[i].texel_area || values[i].empty()) return;
      std::vector<std::vector<float>> parts;
      layer_texels(est, i, photons, values[i], parts);
      const size_t n = est.space.areas[i].area.size();
      std::vector<float>& share = out[i];
      share.assign(3 * size_t(layers) * n, 1.0f / float(layers));
      for (size_t t = 0; t < n; ++t) {
        for (int c = 0; c < 3; ++c) {
          double whole = 0.0;
          for (uint32_t l = 0; l < layers; ++l) whole += std::max(0.0f, parts[l][4 * t + c]);
          if (!(whole > 0.0)) continue;
          for (uint32_t l = 0; l < layers; ++l)
            share[3 * (t * layers + l) + c] = float(std::max(0.0f, parts[l][4 * t + c]) / whole);
        }
      }
    });
  });
  return out;
}

}  // namespace plm

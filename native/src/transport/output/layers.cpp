#include "transport/output/layers.h"

#include <algorithm>
#include <cmath>

#include "lightmap/reconstruct.h"

namespace plm {
namespace {

// Per layer and channel, a share of a whole: parts[l][c] / the parts' sum,
// or `fallback` where the sum is 0.
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

}  // namespace

void layer_texels(const Estimator& est, size_t i, uint64_t photons, const std::vector<float>& values,
                  std::vector<std::vector<float>>& layers_out) {
  const uint32_t layers = est.acc.layers;
  const TexelAreas& ta = est.space.areas[i];
  const Mesh& mesh = *est.space.views[i].mesh;
  const size_t n = ta.area.size();
  const size_t first = est.space.covered_begin[i];
  layers_out.assign(layers, std::vector<float>(4 * n, 0.0f));
  if (layers == 0) return;

  // Each layer's photon flux pooled at the radius the whole's reconstruction
  // chose (the same texels pool together), 3 per layer per texel.
  std::vector<double> pooled(3 * size_t(layers) * n, 0.0);
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
                                                       value3, mse));
    for (uint32_t l = 0; l < layers; ++l) {
      const PhotonSums part{est.acc.layer_flux(l, g0), &est.acc.sum_sq[g0], &est.acc.hits[g0]};
      reconstruct_indirect(ta, mesh.lightmap_width, mesh.lightmap_height, part, params, value3, mse);
      for (size_t t = 0; t < n; ++t)
        for (int c = 0; c < 3; ++c) pooled[3 * (t * layers + l) + c] = value3[3 * t + c];
    }
  }
  const bool direct = !est.direct.empty() && est.direct_layers && !est.direct_layers->empty();
  // The lightmap's own shares, for texels without a part of their own.
  std::vector<double> photon_totals(3 * size_t(layers), 0.0), direct_totals(3 * size_t(layers), 0.0);
  for (size_t t = 0, k = first; t < n; ++t) {
    if (!(ta.area[t] > 0.0)) continue;
    for (size_t f = 0; f < 3 * size_t(layers); ++f) {
      photon_totals[f] += pooled[3 * t * layers + f];
      if (direct) direct_totals[f] += (*est.direct_layers)[3 * k * layers + f];
    }
    ++k;
  }
  const std::vector<double> photon_fallback = mesh_shares(photon_totals, layers);
  const std::vector<double> direct_fallback = mesh_shares(direct_totals, layers);

  Shares direct_share, photon_share;
  std::vector<double> raw(3 * size_t(layers));
  for (size_t t = 0, k = first; t < n; ++t) {
    if (!(ta.area[t] > 0.0)) continue;
    double d[3] = {0, 0, 0}, ind[3], var_d = 0.0;
    if (direct) {
      for (int c = 0; c < 3; ++c) d[c] = est.direct.value3[3 * k + c];
      var_d = est.direct.variance[k];
      for (size_t f = 0; f < raw.size(); ++f) raw[f] = (*est.direct_layers)[3 * k * layers + f];
    } else {
      std::fill(raw.begin(), raw.end(), 0.0);
    }
    for (int c = 0; c < 3; ++c) ind[c] = double(values[4 * t + c]) - d[c];
    const double error = values[4 * t + 3];
    const double var_ind = std::max(0.0, error * error - var_d);
    direct_share.of(raw.data(), 3, layers, direct_fallback);
    photon_share.of(&pooled[3 * t * layers], 3, layers, photon_fallback);
    for (uint32_t l = 0; l < layers; ++l) {
      float* out = &layers_out[l][4 * t];
      for (int c = 0; c < 3; ++c)
        out[c] = float(d[c] * direct_share.s[3 * l + c] + ind[c] * photon_share.s[3 * l + c]);
      const double var = direct_share.mean(l, d) * var_d + photon_share.mean(l, ind) * var_ind;
      out[3] = float(std::sqrt(std::max(0.0, var)));
    }
    ++k;
  }
}

}  // namespace plm

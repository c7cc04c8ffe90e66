#include "transport/materials/bsdf.h"

#include <cmath>

namespace plm {
namespace bsdf {

LobeParams lobe_params(const Lobe& lobe) {
  LobeParams p;
  p.type = lobe.type;
  p.f0 = lobe.color;
  const bool layer = lobe.type == PLM_LOBE_FRESNEL || lobe.type == PLM_LOBE_SPECULAR;
  p.tint = layer ? Vec3{lobe.weight, lobe.weight, lobe.weight} : lobe.color * lobe.weight;
  p.alpha = lobe.roughness * lobe.roughness;
  p.ior = lobe.ior;
  p.smooth = p.alpha * p.alpha <= kSmoothAlpha2;
  return p;
}

namespace {

// eval_lobe's arithmetic in double: near total internal reflection and in
// GGX's tails the transmission's terms cancel, and tests compare it closely.
struct V {
  double x, y, z;
};
V operator+(V a, V b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
V operator*(V a, double s) { return {a.x * s, a.y * s, a.z * s}; }
double dotd(V a, V b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
V unit(V a) { return a * (1.0 / std::sqrt(dotd(a, a))); }

double d_ggx(double c, double a) {
  if (c <= 0.0) return 0.0;
  const double t = c * c * (a * a - 1.0) + 1.0;
  return a * a / (3.14159265358979323846 * t * t);
}
double g1_ggx(double c, double a) {
  const double c2 = c * c;
  return c2 > 0.0 ? 2.0 / (1.0 + std::sqrt(1.0 + a * a * (1.0 - c2) / c2)) : 0.0;
}
double lambda_ggx(double c, double a) { return 0.5 * (std::sqrt(1.0 + a * a * (1.0 - c * c) / (c * c)) - 1.0); }
double g2_over_g1(double ci, double co, double a) {
  const double li = lambda_ggx(ci, a), lo = lambda_ggx(co, a);
  return (1.0 + li) / (1.0 + li + lo);
}
double fresnel(double ci, double eta) {
  const double s2 = (1.0 - ci * ci) / (eta * eta);
  if (s2 >= 1.0) return 1.0;
  const double ct = std::sqrt(1.0 - s2);
  const double rs = (ci - eta * ct) / (ci + eta * ct), rp = (eta * ci - ct) / (eta * ci + ct);
  return 0.5 * (rs * rs + rp * rp);
}

}  // namespace

LobeEval eval_lobe(const LobeParams& p, Vec3 wi_f, Vec3 wo_f, bool front, float ior) {
  LobeEval e;
  if (p.smooth || p.type == PLM_LOBE_TRANSPARENT || !(wi_f.z > 0.0f)) return e;
  const V wi{wi_f.x, wi_f.y, wi_f.z}, wo{wo_f.x, wo_f.y, wo_f.z};
  const double a = p.alpha;
  const bool dielectric = p.type == PLM_LOBE_GLASS || p.type == PLM_LOBE_REFRACTION;
  const double eta = front ? double(ior) : 1.0 / double(ior);
  if (wo.z > 0.0) {  // reflection
    if (p.type == PLM_LOBE_REFRACTION) return e;
    const V h = unit(wi + wo);
    const double cos_ih = dotd(wi, h);
    if (!(cos_ih > 0.0)) return e;
    // pdf: the visible normal's density over the Jacobian 4 |wo.h|, times
    // the chance of reflecting (GLASS: F).
    const double common = d_ggx(h.z, a) * g1_ggx(wi.z, a) / (4.0 * wi.z);
    Vec3 f = p.tint;
    double choose = 1.0;
    if (p.type == PLM_LOBE_FRESNEL || p.type == PLM_LOBE_SPECULAR) f = f * fresnel_blend(float(cos_ih), p.ior, p.f0);
    if (p.type == PLM_LOBE_GLASS) choose = fresnel(cos_ih, eta);
    // SPECULAR: height-correlated G2 / G1(wi) in place of G1(wo).
    const double masking = p.type == PLM_LOBE_SPECULAR ? g2_over_g1(wi.z, wo.z, a) : g1_ggx(wo.z, a);
    e.f_cos = f * float(common * choose * masking);
    e.pdf = float(common * choose);
    return e;
  }
  if (!dielectric || !(wo.z < 0.0)) return e;
  // Transmission: the generalised half vector h ~ -(wi + eta wo), on wi's side.
  V h = unit(wi + wo * eta);
  if (h.z < 0.0) h = h * -1.0;
  const double cos_ih = dotd(wi, h), cos_oh = dotd(wo, h);
  if (!(cos_ih > 0.0) || !(cos_oh < 0.0)) return e;
  if ((1.0 - cos_ih * cos_ih) >= eta * eta) return e;  // total internal reflection at h
  const double F = fresnel(cos_ih, eta);
  const double denom = cos_ih + eta * cos_oh;
  const double jacobian = eta * eta * -cos_oh / (denom * denom);
  const double visible = g1_ggx(wi.z, a) * cos_ih * d_ggx(h.z, a) / wi.z;
  const double pdf = visible * jacobian * (p.type == PLM_LOBE_GLASS ? 1.0 - F : 1.0);
  e.pdf = float(pdf);
  e.f_cos = p.tint * float(pdf * g1_ggx(wo.z, a));
  return e;
}

LayerTable make_layer_table(const LobeParams& p) {
  LayerTable t;
  const double eta = p.ior;
  const double F0 = fresnel(1.0, eta);
  // The Fresnel curve's rise from F0 to 1 at a microfacet cosine c.
  auto rise = [&](double c) { return F0 < 1.0 ? (fresnel(std::fmin(c, 1.0), eta) - F0) / (1.0 - F0) : 1.0; };
  double s_node[kLayerNodes];
  // Visible normals on a stratified n x n grid (midpoints): deterministic; the
  // grid's coarseness shows in GGX's tail, the share of normals that reflect
  // below the horizon (E about 1e-2 high at roughness 0.3, less when rougher).
  constexpr int n = 96;
  for (int j = 0; j < kLayerNodes; ++j) {
    const double mu = std::fmax(double(j) / (kLayerNodes - 1), 1e-4);
    if (p.smooth) {
      t.E[j] = 1.0f;
      s_node[j] = rise(mu);
      continue;
    }
    const Vec3 wi{float(std::sqrt(1.0 - mu * mu)), 0.0f, float(mu)};
    double e_sum = 0.0, s_sum = 0.0;
    for (int a = 0; a < n; ++a)
      for (int b = 0; b < n; ++b) {
        const Vec3 m = ggx_sample_visible(wi, p.alpha, (a + 0.5f) / n, (b + 0.5f) / n);
        const Vec3 wo = reflect(wi, m);
        if (!(wo.z > 0.0f)) continue;  // below the surface: no light (counted, as a zero)
        e_sum += g2_over_g1(mu, wo.z, p.alpha);
        s_sum += rise(dot(wi, m));
      }
    t.E[j] = float(e_sum / (n * n));
    s_node[j] = s_sum / (n * n);
  }
  // E's cosine-weighted mean, 2 integral E(mu) mu dmu (trapezoids).
  double e_avg = 0.0;
  for (int j = 0; j + 1 < kLayerNodes; ++j) {
    const double m0 = double(j) / (kLayerNodes - 1), m1 = double(j + 1) / (kLayerNodes - 1);
    e_avg += (t.E[j] * m0 + t.E[j + 1] * m1) * (m1 - m0);
  }
  // The Fresnel's cosine-weighted mean 2 integral F mu dmu, by Kulla and
  // Conty's fit (as Cycles 4 takes it), as a rise from F0.
  const double f_avg = eta < 1.0 ? 0.997118 + eta * (0.1014 - eta * (0.965241 + eta * 0.130607))
                                 : (eta - 1.0) / (4.08567 + 1.00071 * eta);
  const double s_avg = F0 < 1.0 ? std::fmin(std::fmax((f_avg - F0) / (1.0 - F0), 0.0), 1.0) : 1.0;
  for (int c = 0; c < 3; ++c) {
    const double f0 = std::fmin(std::fmax(double(p.f0[c]), 0.0), 1.0);
    const double fss = f0 + (1.0 - f0) * s_avg;
    t.fms[c] = float(fss * e_avg / (1.0 - fss * (1.0 - e_avg)));
  }
  for (int j = 0; j < kLayerNodes; ++j) {
    double a = 0.0;
    for (int c = 0; c < 3; ++c) {
      const double f0 = std::fmin(std::fmax(double(p.f0[c]), 0.0), 1.0);
      const double dark = t.E[j] + t.fms[c] * (1.0 - t.E[j]);
      a = std::fmax(a, dark * (f0 + (1.0 - f0) * s_node[j]));
    }
    t.A[j] = float(std::fmin(a, 1.0));
  }
  return t;
}

void make_burley_albedo(float roughness, float out[kLayerNodes]) {
  constexpr int n = 64;
  for (int j = 0; j < kLayerNodes; ++j) {
    const double mu = double(j) / (kLayerNodes - 1);
    const double sv = std::sqrt(std::fmax(0.0, 1.0 - mu * mu));
    double sum = 0.0;
    for (int a = 0; a < n; ++a) {
      // Cosine-distributed L by the concentric-free polar map: cos^2 uniform, azimuth uniform.
      const double cl = std::sqrt((a + 0.5) / n), sl = std::sqrt(std::fmax(0.0, 1.0 - cl * cl));
      for (int b = 0; b < n; ++b) {
        const double phi = 2.0 * 3.14159265358979323846 * (b + 0.5) / n;
        const double ldv = sl * std::cos(phi) * sv + cl * mu;
        sum += burley_factor(float(cl), float(mu), float(ldv), roughness);
      }
    }
    out[j] = float(sum / (n * n));
  }
}

}  // namespace bsdf
}  // namespace plm

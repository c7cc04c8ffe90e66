#include "transport/bsdf.h"

#include <cmath>

namespace plm {
namespace bsdf {

LobeParams lobe_params(const Lobe& lobe) {
  LobeParams p;
  p.type = lobe.type;
  p.f0 = lobe.color;
  p.tint = lobe.type == PLM_LOBE_FRESNEL ? Vec3{lobe.weight, lobe.weight, lobe.weight} : lobe.color * lobe.weight;
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
    if (p.type == PLM_LOBE_FRESNEL) f = f * fresnel_blend(float(cos_ih), p.ior, p.f0);
    if (p.type == PLM_LOBE_GLASS) choose = fresnel(cos_ih, eta);
    e.f_cos = f * float(common * choose * g1_ggx(wo.z, a));
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

}  // namespace bsdf
}  // namespace plm

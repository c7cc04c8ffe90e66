// The specular lobes' scattering (docs/design/materials.md), following
// Cycles 3.4's closures: exact unpolarised Fresnel for dielectrics, the
// Principled BSDF's F0-to-1 Fresnel curve, GGX with separable Smith masking
// (G = G1(i) G1(o), as Cycles' single-scattering GGX) and visible-normal
// sampling [Heitz18], smooth and rough dielectric reflection and refraction
// [Walter07], glossy reflection and straight transparency.
//
// Directions live in a local frame whose +Z is the macro normal turned
// towards the side the light arrives from: wi (pointing away from the
// surface, towards where the light came from) has wi.z > 0; a reflected wo
// has wo.z > 0, a transmitted one wo.z < 0. eta = n(far side) / n(near side).
// A sample's weight is f |cos wo| / pdf for flux (photons): flux is
// conserved through a refraction, no eta^2 factor (that belongs to radiance).
#pragma once

#include <algorithm>
#include <cmath>

#include "scene/lobe.h"
#include "util/math.h"

namespace plm {
namespace bsdf {

// GGX alpha below which a lobe is a perfect mirror or pane: Cycles' test
// alpha_x alpha_y <= 1e-7 (Blender roughness below ~0.018).
constexpr float kSmoothAlpha2 = 1e-7f;

// Exact Fresnel reflectance of unpolarised light at a dielectric interface:
// cos_i > 0 the cosine on the incident side, eta = n_t / n_i. Sets cos_t (> 0)
// and returns the reflectance; 1 under total internal reflection (cos_t 0).
inline float fresnel_dielectric(float cos_i, float eta, float& cos_t) {
  const float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
  if (sin2_t >= 1.0f) {
    cos_t = 0.0f;
    return 1.0f;
  }
  cos_t = std::sqrt(1.0f - sin2_t);
  const float rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
  const float rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
  return 0.5f * (rs * rs + rp * rp);
}

inline float fresnel_dielectric(float cos_i, float eta) {
  float cos_t;
  return fresnel_dielectric(cos_i, eta, cos_t);
}

// The Principled BSDF's specular Fresnel (a FRESNEL lobe): f0 at normal
// incidence rising to 1 at grazing along a dielectric's curve of `ior`,
// FH = (F(cos) - F0) / (1 - F0), f0 (1 - FH) + FH.
inline Vec3 fresnel_blend(float cos_h, float ior, Vec3 f0) {
  const float F0 = fresnel_dielectric(1.0f, ior);
  const float F = fresnel_dielectric(std::fmin(std::fabs(cos_h), 1.0f), ior);
  const float fh = F0 < 1.0f ? (F - F0) / (1.0f - F0) : 1.0f;
  return f0 * (1.0f - fh) + Vec3{fh, fh, fh};
}

// GGX normal distribution D(m) (area-normalised: the integral of D(m) cos(m) is 1).
inline float ggx_d(float cos_m, float alpha) {
  if (cos_m <= 0.0f) return 0.0f;
  const float a2 = alpha * alpha, c2 = cos_m * cos_m;
  const float t = c2 * (a2 - 1.0f) + 1.0f;
  return a2 / (kPi * t * t);
}

// Smith masking of direction v (|cos_v| its cosine with the macro normal).
inline float ggx_g1(float cos_v, float alpha) {
  const float c2 = cos_v * cos_v;
  if (!(c2 > 0.0f)) return 0.0f;
  const float tan2 = (1.0f - c2) / c2;
  return 2.0f / (1.0f + std::sqrt(1.0f + alpha * alpha * tan2));
}

// Smith's Lambda for GGX (G1 = 1 / (1 + Lambda)).
inline float ggx_lambda(float cos_v, float alpha) {
  const float c2 = cos_v * cos_v;
  if (!(c2 > 0.0f)) return 1e30f;
  return 0.5f * (std::sqrt(1.0f + alpha * alpha * (1.0f - c2) / c2) - 1.0f);
}

// Height-correlated masking-shadowing over the masking of wi alone
// (G2 / G1(wi), a visible-normal sample's weight): Cycles 4's GGX.
inline float ggx_g2_over_g1(float cos_i, float cos_o, float alpha) {
  const float li = ggx_lambda(cos_i, alpha), lo = ggx_lambda(cos_o, alpha);
  return (1.0f + li) / (1.0f + li + lo);
}

// A microfacet normal drawn from the normals visible from wi (wi.z > 0),
// density G1(wi) max(0, wi.m) D(m) / wi.z [Heitz18].
inline Vec3 ggx_sample_visible(Vec3 wi, float alpha, float u1, float u2) {
  const Vec3 vh = normalize(Vec3{alpha * wi.x, alpha * wi.y, wi.z});
  const float len2 = vh.x * vh.x + vh.y * vh.y;
  const Vec3 t1 = len2 > 0.0f ? Vec3{-vh.y, vh.x, 0.0f} * (1.0f / std::sqrt(len2)) : Vec3{1.0f, 0.0f, 0.0f};
  const Vec3 t2 = cross(vh, t1);
  const float r = std::sqrt(u1);
  float s, c;
  sincos_2pi(u2, s, c);
  const float p1 = r * c;
  const float h = 0.5f * (1.0f + vh.z);
  const float p2 = (1.0f - h) * std::sqrt(std::fmax(0.0f, 1.0f - p1 * p1)) + h * r * s;
  const Vec3 nh = t1 * p1 + t2 * p2 + vh * std::sqrt(std::fmax(0.0f, 1.0f - p1 * p1 - p2 * p2));
  return normalize(Vec3{alpha * nh.x, alpha * nh.y, std::fmax(1e-7f, nh.z)});
}

// The density of ggx_sample_visible's m.
inline float ggx_visible_pdf(Vec3 wi, Vec3 m, float alpha) {
  return ggx_g1(wi.z, alpha) * std::fmax(0.0f, dot(wi, m)) * ggx_d(m.z, alpha) / wi.z;
}

inline Vec3 reflect(Vec3 wi, Vec3 m) { return m * (2.0f * dot(wi, m)) - wi; }

// wi refracted through a facet of normal m (wi.m > 0), given cos_t from
// fresnel_dielectric: on the far side of m.
inline Vec3 refract(Vec3 wi, Vec3 m, float eta, float cos_t) {
  const float c = dot(wi, m);
  return m * (c / eta - cos_t) - wi * (1.0f / eta);
}

// How light left a lobe.
enum class Event : uint8_t {
  Absorbed,     // no light goes on
  Reflected,    // specular or glossy reflection
  Refracted,    // through the surface, bent by eta
  Transparent,  // straight through (TRANSPARENT lobe)
};

struct LobeSample {
  Vec3 wo;
  Vec3 weight;  // f |cos wo| / pdf
  Event event = Event::Absorbed;
};

// A lobe as scattering needs it (transport/materials/material_table.h flattens Lobes into these).
struct LobeParams {
  plm_lobe_type type;
  Vec3 tint;     // weight x colour; FRESNEL, SPECULAR: weight alone (their colour is f0)
  Vec3 f0;       // FRESNEL, SPECULAR: colour
  float alpha;   // GGX alpha = roughness^2
  float ior;     // front side outside
  bool smooth;   // alpha^2 <= kSmoothAlpha2
};

LobeParams lobe_params(const Lobe& lobe);

// The lobe's reflectance seen from wi (an estimate for choosing it: exact for
// smooth lobes without total internal reflection), max over channels.
inline float lobe_albedo_estimate(const LobeParams& p, float cos_i) {
  if (p.type != PLM_LOBE_FRESNEL && p.type != PLM_LOBE_SPECULAR) return max_component(p.tint);
  return max_component(p.tint * fresnel_blend(cos_i, p.ior, p.f0));
}

// Samples lobe p for light arriving from wi (local, wi.z > 0) on the front
// (front: eta = ior) or back side (eta = 1 / ior) of the surface. ior: the
// lobe's index (the dispersed one for a photon of one wavelength). u1, u2
// pick the microfacet, u3 reflection against refraction (GLASS).
inline LobeSample sample_lobe(const LobeParams& p, Vec3 wi, bool front, float ior, float u1, float u2, float u3) {
  LobeSample s;
  if (p.type == PLM_LOBE_TRANSPARENT) {
    s.wo = -wi;
    s.weight = p.tint;
    s.event = Event::Transparent;
    return s;
  }
  const Vec3 m = p.smooth ? Vec3{0.0f, 0.0f, 1.0f} : ggx_sample_visible(wi, p.alpha, u1, u2);
  const float cos_im = dot(wi, m);
  if (!(cos_im > 0.0f)) return s;
  bool reflect_here = true;
  float cos_t = 0.0f;
  Vec3 weight = p.tint;
  if (p.type == PLM_LOBE_GLASS || p.type == PLM_LOBE_REFRACTION) {
    const float eta = front ? ior : 1.0f / ior;
    const float F = fresnel_dielectric(cos_im, eta, cos_t);
    if (p.type == PLM_LOBE_REFRACTION) {
      if (cos_t == 0.0f) return s;  // total internal reflection: Cycles' refraction BSDF gives nothing
      reflect_here = false;
    } else {
      reflect_here = u3 < F;
    }
    if (!reflect_here) {
      s.wo = refract(wi, m, eta, cos_t);
      if (!(s.wo.z < 0.0f)) return s;  // a facet's refraction back into the near side: lost (single scattering)
      s.event = Event::Refracted;
    }
  } else if (p.type == PLM_LOBE_FRESNEL || p.type == PLM_LOBE_SPECULAR) {
    weight = weight * fresnel_blend(cos_im, p.ior, p.f0);
  }
  if (reflect_here) {
    s.wo = reflect(wi, m);
    if (!(s.wo.z > 0.0f)) return s;
    s.event = Event::Reflected;
  }
  if (p.smooth) s.weight = weight;
  else if (p.type == PLM_LOBE_SPECULAR) s.weight = weight * ggx_g2_over_g1(wi.z, s.wo.z, p.alpha);
  else s.weight = weight * ggx_g1(s.wo.z, p.alpha);
  return s;
}

// A SPECULAR lobe's energy (Cycles 4's Multiscatter GGX under a dielectric
// Fresnel, docs/design/cycles-versions.md, "Principled BSDF v2"), tabulated
// over the cosine of the direction the light leaves at kLayerNodes evenly
// spaced nodes 0..1:
//   E      the single-scattering GGX albedo with Fresnel 1
//   A      the layer's directional albedo per unit weight, largest channel:
//          (E + Fms (1 - E)) (f0 + (1 - f0) s), s the mean over visible
//          normals of the Fresnel curve's rise (F - F0) / (1 - F0)
//   fms    Kulla and Conty's multiple-scattering Fresnel per channel
// The lobe's single-scattering weight times compensation(cos out) is the
// compensated lobe: 1 / E of the energy lost to single scattering returned,
// darkened by fms.
constexpr int kLayerNodes = 33;

inline float layer_lookup(const float* t, float c) {
  const float x = std::fmin(std::fmax(c, 0.0f), 1.0f) * float(kLayerNodes - 1);
  const int i = std::min(int(x), kLayerNodes - 2);
  const float f = x - float(i);
  return t[i] + (t[i + 1] - t[i]) * f;
}

struct LayerTable {
  float E[kLayerNodes];
  float A[kLayerNodes];
  Vec3 fms;
  float albedo(float cos_o) const { return layer_lookup(A, cos_o); }
  Vec3 compensation(float cos_o) const {
    const float e = layer_lookup(E, cos_o);
    return (Vec3{e, e, e} + fms * (1.0f - e)) * (1.0f / e);
  }
};

// The table of a SPECULAR lobe of GGX alpha, index ior and F0 f0 (tint
// excluded), by deterministic stratified integration over visible normals.
LayerTable make_layer_table(const LobeParams& p);

// Cycles 3.4's Principled BSDF diffuse (kernel/closure/bsdf_principled_diffuse.h,
// PRINCIPLED_DIFFUSE_FULL; Burley 2015): f = albedo / pi x burley_factor,
//   (1 - FL / 2)(1 - FV / 2) + R (FL + FV + FL FV (R - 1)),
// F = schlick_weight(cos) at the light's (L) and the viewer's (V) side and
// R = roughness (1 + L.V) (2 cos^2 of the half angle). Symmetric in L and V.
inline float schlick_weight(float c) {
  const float m = std::fmin(std::fmax(1.0f - c, 0.0f), 1.0f);
  const float m2 = m * m;
  return m2 * m2 * m;
}

inline float burley_factor(float cos_l, float cos_v, float l_dot_v, float roughness) {
  const float fl = schlick_weight(cos_l), fv = schlick_weight(cos_v);
  const float rr = roughness * (l_dot_v + 1.0f);
  return (1.0f - 0.5f * fl) * (1.0f - 0.5f * fv) + rr * (fl + fv + fl * fv * (rr - 1.0f));
}

// What Cycles 3.4 bakes (DIFFUSE, no COLOR) for a Burley surface weighs light
// arriving at cos_l by: the factor with the viewer along the normal.
inline float burley_receive(float cos_l, float roughness) {
  const float fl = schlick_weight(cos_l);
  return 1.0f - 0.5f * fl + roughness * (1.0f + cos_l) * fl;
}

// Burley's directional albedo over Lambert's, R(cos v) = the mean of
// burley_factor over cosine-distributed L (equal, by symmetry, to its albedo
// for light arriving at cos v), at kLayerNodes evenly spaced cosines 0..1, by
// a deterministic 64 x 64 midpoint quadrature. R(1) = 1 - 1/42 + 5/84 roughness.
void make_burley_albedo(float roughness, float out[kLayerNodes]);

// Evaluation for tests: the lobe's f(wi, wo) |cos wo| and the density of
// sample_lobe's wo (rough lobes only; smooth ones are Dirac deltas). Both
// zero where sample_lobe cannot go.
struct LobeEval {
  Vec3 f_cos;
  float pdf = 0.0f;
};
LobeEval eval_lobe(const LobeParams& p, Vec3 wi, Vec3 wo, bool front, float ior);

}  // namespace bsdf
}  // namespace plm

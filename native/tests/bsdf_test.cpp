// The lobes' scattering against truth: Fresnel against the textbook formula
// in angles (and its known values), the GGX model against its own
// normalisation and an independent quadrature, the sampler against the
// density it claims (histograms), reciprocity, and energy: a smooth
// dielectric's R + T = 1, a white GGX mirror loses only the known
// single-scattering energy.
#include "transport/materials/bsdf.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "util/rng.h"

namespace {

using namespace plm;
using namespace plm::bsdf;

constexpr double kPiT = 3.14159265358979323846;

// Fresnel from Snell's law in angles (Born & Wolf): the classical form.
double fresnel_angles(double theta_i, double eta) {
  if (theta_i == 0.0) {
    const double r = (1.0 - eta) / (1.0 + eta);
    return r * r;
  }
  const double s = std::sin(theta_i) / eta;
  if (s >= 1.0) return 1.0;
  const double theta_t = std::asin(s);
  const double rs = std::sin(theta_i - theta_t) / std::sin(theta_i + theta_t);
  const double rp = std::tan(theta_i - theta_t) / std::tan(theta_i + theta_t);
  return 0.5 * (rs * rs + rp * rp);
}

Vec3 dir(double theta, double phi) {
  return {float(std::sin(theta) * std::cos(phi)), float(std::sin(theta) * std::sin(phi)), float(std::cos(theta))};
}

LobeParams lobe(plm_lobe_type type, float roughness, float ior = 1.5f, Vec3 color = {1, 1, 1}) {
  Lobe l;
  l.type = type;
  l.roughness = roughness;
  l.ior = ior;
  l.color = color;
  return lobe_params(l);
}

TEST(Fresnel, KnownValuesAndTheAngleForm) {
  EXPECT_NEAR(fresnel_dielectric(1.0f, 1.5f), 0.04f, 1e-7f);  // ((1.5 - 1) / 2.5)^2
  EXPECT_NEAR(fresnel_dielectric(1.0f, 1.0f / 1.5f), 0.04f, 1e-7f);  // the same from inside
  EXPECT_NEAR(fresnel_dielectric(0.3f, 1.0f), 0.0f, 1e-12f);          // no interface
  for (double eta : {1.33, 1.45, 1.5, 2.4, 1.0 / 1.5})
    for (double deg = 0.0; deg < 89.9; deg += 2.5) {
      const double th = deg * kPiT / 180.0;
      EXPECT_NEAR(fresnel_dielectric(float(std::cos(th)), float(eta)), fresnel_angles(th, eta), 2e-6)
          << "eta " << eta << " at " << deg << " degrees";
    }
  // Brewster's angle: p-polarised light is not reflected, R = rs^2 / 2.
  const double brewster = std::atan(1.5);
  const double rs = std::sin(brewster - std::asin(std::sin(brewster) / 1.5)) /
                    std::sin(brewster + std::asin(std::sin(brewster) / 1.5));
  EXPECT_NEAR(fresnel_dielectric(float(std::cos(brewster)), 1.5f), 0.5 * rs * rs, 1e-6);
  // Total internal reflection beyond the critical angle, asin(1 / 1.5) = 41.8 degrees.
  float cos_t = 1.0f;
  EXPECT_EQ(fresnel_dielectric(float(std::cos(42.0 * kPiT / 180.0)), 1.0f / 1.5f, cos_t), 1.0f);
  EXPECT_EQ(cos_t, 0.0f);
  EXPECT_LT(fresnel_dielectric(float(std::cos(41.0 * kPiT / 180.0)), 1.0f / 1.5f), 1.0f);
  // Grazing: everything is reflected.
  EXPECT_NEAR(fresnel_dielectric(1e-6f, 1.5f), 1.0f, 1e-5f);
}

TEST(Fresnel, ThePrincipledCurveRunsFromF0ToOne) {
  const Vec3 gold{1.0f, 0.78f, 0.34f};
  const Vec3 at_normal = fresnel_blend(1.0f, 1.5f, gold);
  EXPECT_NEAR(at_normal.x, 1.0f, 1e-6f);
  EXPECT_NEAR(at_normal.y, 0.78f, 1e-6f);
  EXPECT_NEAR(at_normal.z, 0.34f, 1e-6f);
  const Vec3 grazing = fresnel_blend(1e-6f, 1.5f, gold);
  EXPECT_NEAR(grazing.z, 1.0f, 1e-4f);
  // With f0 the dielectric's own F0 the curve is the dielectric's Fresnel.
  for (float c = 0.05f; c <= 1.0f; c += 0.05f) {
    const float F0 = fresnel_dielectric(1.0f, 1.5f);
    EXPECT_NEAR(fresnel_blend(c, 1.5f, Vec3{F0, F0, F0}).y, fresnel_dielectric(c, 1.5f), 1e-6f) << c;
  }
  // Monotonic between the two.
  float last = 0.0f;
  for (float c = 1.0f; c > 0.0f; c -= 0.01f) {
    const float v = fresnel_blend(c, 1.5f, gold).z;
    EXPECT_GE(v, last - 1e-7f);
    last = v;
  }
}

// Integrates f over the sphere of directions, midpoint rule in (theta, phi)
// (fine steps near the poles, where narrow lobes peak), in double.
template <typename F>
double sphere_integral(F f, int n_theta = 2000, int n_phi = 400) {
  double sum = 0.0;
  for (int i = 0; i < n_theta; ++i) {
    const double th = (i + 0.5) * kPiT / n_theta, st = std::sin(th), z = std::cos(th);
    for (int j = 0; j < n_phi; ++j) {
      const double phi = (j + 0.5) * 2.0 * kPiT / n_phi;
      sum += st * f(Vec3{float(st * std::cos(phi)), float(st * std::sin(phi)), float(z)});
    }
  }
  return sum * (kPiT / n_theta) * (2.0 * kPiT / n_phi);
}

// GGX as the textbook writes it (Walter et al. 2007, eqs. 33-34), in double.
double d_ref(double cos_m, double a) {
  if (cos_m <= 0.0) return 0.0;
  const double c2 = cos_m * cos_m, t2 = (1.0 - c2) / c2;
  return a * a / (kPiT * c2 * c2 * (a * a + t2) * (a * a + t2));
}
double g1_ref(double cos_v, double a) {
  const double c2 = cos_v * cos_v;
  return 2.0 / (1.0 + std::sqrt(1.0 + a * a * (1.0 - c2) / c2));
}

TEST(Ggx, NormalDistributionIsNormalisedAndMatchesTheTextbook) {
  for (float a : {0.05f, 0.2f, 0.5f, 1.0f}) {
    for (double c = 0.05; c <= 1.0; c += 0.05) EXPECT_NEAR(ggx_d(float(c), a), d_ref(c, a), 2e-5 * d_ref(c, a) + 1e-7);
    // The projected area of the microfacets is the macro surface's: int D(m) cos(m) dm = 1.
    EXPECT_NEAR(sphere_integral([&](Vec3 m) { return m.z > 0 ? d_ref(m.z, a) * m.z : 0.0; }, 8000, 4), 1.0, 1e-4)
        << a;
  }
}

// Heitz's weak white furnace: the visible normals' density integrates to 1,
// int G1(wi) max(0, wi.m) D(m) / wi.z dm = 1, for any wi.
TEST(Ggx, VisibleNormalsIntegrateToOne) {
  for (float a : {0.1f, 0.4f, 1.0f})
    for (double th : {0.0, 0.6, 1.2, 1.5}) {
      const Vec3 wi = dir(th, 0.3);
      EXPECT_NEAR(sphere_integral([&](Vec3 m) { return double(ggx_visible_pdf(wi, m, a)); }), 1.0, 1e-3)
          << "alpha " << a << " theta " << th;
    }
}

// Histogram test: sampled directions against the density eval_lobe claims,
// on (cos theta, phi) cells of the sphere. Also the mean weight against
// the integral of f |cos| (energy) and weight = f cos / pdf per sample.
void check_sampler(const LobeParams& p, Vec3 wi, bool front, const char* what) {
  constexpr int kTheta = 20, kPhi = 20;
  constexpr int kN = 400000;
  std::vector<double> counts(kTheta * kPhi, 0.0);
  plm::Rng rng(7, 11);
  double weight_sum = 0.0;
  int misfit = 0;
  for (int k = 0; k < kN; ++k) {
    const float u1 = rng.next_float(), u2 = rng.next_float(), u3 = rng.next_float();
    const LobeSample s = sample_lobe(p, wi, front, p.ior, u1, u2, u3);
    if (s.event == Event::Absorbed) continue;
    ASSERT_TRUE(is_finite(s.wo) && is_finite(s.weight)) << what;
    weight_sum += s.weight.y;
    const LobeEval e = eval_lobe(p, wi, s.wo, front, p.ior);
    if (!(e.pdf > 0.0f) || std::fabs(e.f_cos.y / e.pdf - s.weight.y) > 1e-3f * s.weight.y + 1e-5f) ++misfit;
    const int i = std::min(kTheta - 1, int((s.wo.z + 1.0f) * 0.5f * kTheta));
    const float phi = std::atan2(s.wo.y, s.wo.x);
    const int j = std::min(kPhi - 1, int((phi + kPiT) / (2.0 * kPiT) * kPhi));
    counts[size_t(i * kPhi + j)] += 1.0;
  }
  EXPECT_LT(misfit, kN / 2000) << what << ": samples whose weight is not f cos / pdf";
  // Expected counts from the density, integrated over each cell.
  double chi2 = 0.0, total_pdf = 0.0, energy = 0.0;
  int cells = 0;
  for (int i = 0; i < kTheta; ++i)
    for (int j = 0; j < kPhi; ++j) {
      double integral = 0.0;
      constexpr int kSub = 24;
      for (int a = 0; a < kSub; ++a)
        for (int b = 0; b < kSub; ++b) {
          const double z = -1.0 + (i + (a + 0.5) / kSub) * 2.0 / kTheta;
          const double phi = -kPiT + (j + (b + 0.5) / kSub) * 2.0 * kPiT / kPhi;
          const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
          const Vec3 wo{float(r * std::cos(phi)), float(r * std::sin(phi)), float(z)};
          const LobeEval e = eval_lobe(p, wi, wo, front, p.ior);
          integral += e.pdf;
          energy += e.f_cos.y;
        }
      const double cell = (2.0 / kTheta) * (2.0 * kPiT / kPhi) / (kSub * kSub);
      integral *= cell;
      total_pdf += integral;
      const double expected = integral * kN, observed = counts[size_t(i * kPhi + j)];
      if (expected > 20.0) {
        chi2 += (observed - expected) * (observed - expected) / expected;
        ++cells;
      } else {
        EXPECT_LT(observed, 60.0 + 3.0 * expected) << what << " cell " << i << "," << j;
      }
    }
  energy *= (2.0 / kTheta) * (2.0 * kPiT / kPhi) / (24.0 * 24.0);
  // chi^2 with `cells` degrees of freedom: mean cells, sd sqrt(2 cells); 6 sd is far out.
  EXPECT_LT(chi2, cells + 6.0 * std::sqrt(2.0 * cells) + 10.0) << what << " (" << cells << " cells)";
  EXPECT_LE(total_pdf, 1.0 + 5e-3) << what;
  EXPECT_NEAR(weight_sum / kN, energy, 0.01 * energy + 2e-3) << what << ": energy";
}

TEST(Lobes, SamplersDrawTheDensityTheyClaim) {
  const Vec3 near_normal = dir(0.3, 0.4), oblique = dir(1.1, 2.0), grazing = dir(1.45, -1.0);
  for (const Vec3& wi : {near_normal, oblique, grazing}) {
    check_sampler(lobe(PLM_LOBE_GLOSSY, 0.3f), wi, true, "glossy 0.3");
    check_sampler(lobe(PLM_LOBE_GLOSSY, 0.8f), wi, true, "glossy 0.8");
    check_sampler(lobe(PLM_LOBE_FRESNEL, 0.5f, 1.5f, {0.9f, 0.6f, 0.2f}), wi, true, "fresnel 0.5");
    check_sampler(lobe(PLM_LOBE_GLASS, 0.4f, 1.5f), wi, true, "glass 0.4 from outside");
    check_sampler(lobe(PLM_LOBE_GLASS, 0.4f, 1.5f), wi, false, "glass 0.4 from inside");
    check_sampler(lobe(PLM_LOBE_REFRACTION, 0.6f, 1.33f), wi, true, "refraction 0.6");
    check_sampler(lobe(PLM_LOBE_REFRACTION, 0.6f, 1.33f), wi, false, "refraction 0.6 from inside");
  }
}

// Reflection is symmetric; transmission obeys f(wi, wo) = eta^2 f(wo, wi)
// for flux (eta = n(wo's side) / n(wi's side)): the same energy both ways.
TEST(Lobes, Reciprocity) {
  plm::Rng rng(3, 5);
  const LobeParams glossy = lobe(PLM_LOBE_FRESNEL, 0.5f, 1.5f, {0.5f, 0.5f, 0.5f});
  const LobeParams glass = lobe(PLM_LOBE_GLASS, 0.5f, 1.5f);
  int tested_r = 0, tested_t = 0, loose_t = 0;
  for (int k = 0; k < 2000; ++k) {
    const Vec3 a = dir(std::acos(rng.next_float()), 2.0 * kPiT * rng.next_float());
    Vec3 b = dir(std::acos(rng.next_float()), 2.0 * kPiT * rng.next_float());
    // Reflection: f cos / cos(wo) both ways.
    const LobeEval ab = eval_lobe(glossy, a, b, true, 1.5f), ba = eval_lobe(glossy, b, a, true, 1.5f);
    if (ab.f_cos.y > 1e-6f) {
      EXPECT_NEAR(ab.f_cos.y / b.z, ba.f_cos.y / a.z, 1e-4f * ab.f_cos.y / b.z) << k;
      ++tested_r;
    }
    // Transmission: a on the front (outside, n = 1), b inside (n = 1.5).
    b.z = -b.z;
    const LobeEval t_ab = eval_lobe(glass, a, b, true, 1.5f);
    const LobeEval t_ba = eval_lobe(glass, Vec3{b.x, b.y, -b.z}, Vec3{a.x, a.y, -a.z}, false, 1.5f);
    if (t_ab.f_cos.y > 1e-6f && t_ba.f_cos.y > 1e-6f) {
      const double f_ab = t_ab.f_cos.y / -b.z, f_ba = t_ba.f_cos.y / a.z;
      // Near grazing refraction (o.h -> 0) 1 - F is ill-conditioned in the
      // float inputs: a loose bound for all, a tight one for almost all.
      EXPECT_NEAR(f_ab, 1.5 * 1.5 * f_ba, 5e-3 * f_ab) << k;
      if (std::fabs(f_ab / (1.5 * 1.5 * f_ba) - 1.0) > 1e-4) ++loose_t;
      ++tested_t;
    }
  }
  EXPECT_GT(tested_r, 500);
  EXPECT_GT(tested_t, 300);
  EXPECT_LT(loose_t, tested_t / 20) << loose_t << " of " << tested_t;
}

// A smooth dielectric reflects F and transmits 1 - F of the light: samples
// choose reflection with probability F and carry weight 1 (the tint) either way.
TEST(Lobes, SmoothGlassConservesEnergy) {
  const LobeParams p = lobe(PLM_LOBE_GLASS, 0.0f, 1.5f);
  for (double deg : {0.0, 30.0, 45.0, 60.0, 80.0, 89.0})
    for (bool front : {true, false}) {
      const Vec3 wi = dir(deg * kPiT / 180.0, 0.7);
      const double eta = front ? 1.5 : 1.0 / 1.5;
      const double F = fresnel_angles(deg * kPiT / 180.0, eta);
      constexpr int kN = 200000;
      plm::Rng rng(1, 2);
      int reflected = 0, refracted = 0;
      double energy = 0.0;
      for (int k = 0; k < kN; ++k) {
        const LobeSample s = sample_lobe(p, wi, front, 1.5f, rng.next_float(), rng.next_float(), rng.next_float());
        ASSERT_NE(s.event, Event::Absorbed);
        EXPECT_EQ(s.weight.x, 1.0f);
        energy += s.weight.x;
        if (s.event == Event::Reflected) {
          ++reflected;
          EXPECT_NEAR(s.wo.z, wi.z, 1e-6f);  // mirror direction
        } else {
          ++refracted;
          // Snell: n_i sin_i = n_t sin_t, in the plane of incidence.
          const double sin_t = std::sqrt(double(s.wo.x) * s.wo.x + double(s.wo.y) * s.wo.y);
          EXPECT_NEAR(sin_t * eta, std::sin(deg * kPiT / 180.0), 1e-5);
          EXPECT_LT(s.wo.z, 0.0f);
        }
      }
      EXPECT_NEAR(energy / kN, 1.0, 1e-12);  // R + T = 1
      const double sd = std::sqrt(F * (1.0 - F) / kN);
      EXPECT_NEAR(double(reflected) / kN, F, 5.0 * sd + 1e-9) << deg << (front ? " front" : " back");
    }
}

// A white GGX mirror (F = 1) reflects all light but the single-scattering
// loss of the separable Smith model, the integral of D G1(i) G1(o) / (4 cos i)
// over the upper hemisphere (computed here from the textbook formulas);
// smooth it loses nothing.
TEST(Lobes, WhiteGgxMirrorLosesOnlyTheSingleScatteringEnergy) {
  for (float r : {0.0f, 0.2f, 0.5f, 0.8f, 1.0f}) {
    const LobeParams p = lobe(PLM_LOBE_GLOSSY, r);
    const double a = double(r) * r;
    for (double th : {0.0, 0.8, 1.3}) {
      const Vec3 wi = dir(th, 0.0);
      double truth = 1.0;
      if (!p.smooth)
        truth = sphere_integral(
            [&](Vec3 wo) {
              if (wo.z <= 0.0f) return 0.0;
              const Vec3 h = normalize(wi + wo);
              return d_ref(h.z, a) * g1_ref(wi.z, a) * g1_ref(wo.z, a) / (4.0 * wi.z);
            });
      plm::Rng rng(9, 4);
      constexpr int kN = 200000;
      double sum = 0.0;
      for (int k = 0; k < kN; ++k) {
        const LobeSample s = sample_lobe(p, wi, true, 1.5f, rng.next_float(), rng.next_float(), rng.next_float());
        if (s.event != Event::Absorbed) sum += s.weight.x;
      }
      EXPECT_NEAR(sum / kN, truth, 4e-3) << "roughness " << r << " theta " << th;
      EXPECT_LE(truth, 1.0 + 1e-3);
      if (r == 0.0f) {
        EXPECT_EQ(sum / kN, 1.0);
      }
    }
  }
}

TEST(Lobes, TransparentPassesStraightWithItsTint) {
  const LobeParams p = lobe(PLM_LOBE_TRANSPARENT, 0.7f, 1.5f, {0.2f, 0.5f, 0.9f});
  const Vec3 wi = dir(0.9, 1.3);
  const LobeSample s = sample_lobe(p, wi, true, 1.5f, 0.3f, 0.6f, 0.2f);
  EXPECT_EQ(s.event, Event::Transparent);
  EXPECT_EQ(s.wo.x, -wi.x);
  EXPECT_EQ(s.wo.z, -wi.z);
  EXPECT_EQ(s.weight.y, 0.5f);
}

TEST(Lobes, RefractionGivesNothingUnderTotalInternalReflection) {
  const LobeParams p = lobe(PLM_LOBE_REFRACTION, 0.0f, 1.5f);
  const LobeSample s = sample_lobe(p, dir(1.0, 0.0), false, 1.5f, 0.5f, 0.5f, 0.5f);  // 57 degrees inside
  EXPECT_EQ(s.event, Event::Absorbed);
  const LobeSample t = sample_lobe(p, dir(0.5, 0.0), false, 1.5f, 0.5f, 0.5f, 0.5f);
  EXPECT_EQ(t.event, Event::Refracted);
  EXPECT_EQ(t.weight.x, 1.0f);  // no Fresnel term
}

TEST(Lobes, GrazingAndDegenerateInputGiveNoNaN) {
  for (plm_lobe_type type : {PLM_LOBE_GLOSSY, PLM_LOBE_FRESNEL, PLM_LOBE_GLASS, PLM_LOBE_REFRACTION})
    for (float r : {0.0f, 0.01f, 0.02f, 0.5f, 1.0f})
      for (float z : {1.0f, 1e-3f, 1e-7f}) {
        const Vec3 wi = normalize(Vec3{std::sqrt(1.0f - z * z), 0.0f, z});
        for (float u : {0.0f, 0.5f, 0.9999999f}) {
          const LobeSample s = sample_lobe(lobe(type, r), wi, true, 1.5f, u, u, u);
          EXPECT_TRUE(is_finite(s.weight)) << type << " " << r << " " << z;
          if (s.event != Event::Absorbed) {
            EXPECT_TRUE(is_finite(s.wo));
            EXPECT_NEAR(length(s.wo), 1.0f, 1e-4f);
            EXPECT_LE(max_component(s.weight), 1.0f + 1e-5f);
          }
        }
      }
}

}  // namespace

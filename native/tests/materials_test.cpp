// Glass, mirrors and metal in the bake, against truth: the sun through a
// clear pane (Fresnel transmission with its internal reflections, at normal
// incidence and at 45 degrees, in the direct pass and by photons alone), a
// pane of IOR 1, a transparent lobe, a mirror's sun patch on a wall, lossless
// spheres in a furnace (the furnace's analytic value), rough glass and metal
// (energy, no NaN) and a dispersing prism (an ordered spectrum where a ray
// trace of Snell's law puts it, energy conserved).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "demo_scenes.h"
#include "test_support.h"
#include "transport/materials/bsdf.h"
#include "transport/materials/material_table.h"
#include "transport/materials/spectrum.h"

namespace {

using plm_demo::SceneBuilder;
using plm_demo::V3;
using plm_test::BakeResult;
using plm_test::Map;

constexpr double kPiT = 3.14159265358979323846;

// A sun of strength e travelling along unit direction d, no angular size.
plm_light sun(V3 d, float e) {
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_SUN);
  l.power = e;
  l.angle = 0.0f;
  // The sun shines along its frame's -Z: Z = -d, X and Y any frame around it.
  const float z[3] = {-d.x, -d.y, -d.z};
  float x[3] = {1, 0, 0};
  if (std::fabs(z[0]) > 0.9f) x[0] = 0, x[1] = 1;
  const float xz = x[0] * z[0] + x[1] * z[1] + x[2] * z[2];
  for (int c = 0; c < 3; ++c) x[c] -= xz * z[c];
  const float xl = std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
  for (float& c : x) c /= xl;
  const float y[3] = {z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]};
  for (int r = 0; r < 3; ++r) {
    l.matrix[4 * r + 0] = x[r];
    l.matrix[4 * r + 1] = y[r];
    l.matrix[4 * r + 2] = z[r];
    l.matrix[4 * r + 3] = 0.0f;
  }
  return l;
}

void add_lobe(SceneBuilder& b, uint32_t material, plm_lobe_type type, V3 color, float roughness = 0.0f,
              float ior = 1.5f, float abbe = 0.0f) {
  plm_lobe l;
  plm_lobe_default(&l, type);
  l.color[0] = color.x, l.color[1] = color.y, l.color[2] = color.z;
  l.roughness = roughness;
  l.ior = ior;
  l.abbe = abbe;
  ASSERT_EQ(plm_scene_add_material_lobe(b.scene, material, &l), PLM_OK) << plm_last_error();
}

// A slab of glass: two parallel quads, the top at z = z_top facing up, the
// bottom `thickness` below facing down, over [x0, x1] x [y0, y1].
void slab(SceneBuilder& b, uint32_t material, float x0, float x1, float y0, float y1, float z_top, float thickness) {
  b.quad("pane top", {x0, y0, z_top}, {x1 - x0, 0, 0}, {0, y1 - y0, 0}, material, 0);
  b.quad("pane bottom", {x0, y0, z_top - thickness}, {0, y1 - y0, 0}, {x1 - x0, 0, 0}, material, 0);
}

// A UV sphere (smooth normals), outward faces, no lightmap.
void sphere(SceneBuilder& b, const char* name, V3 c, float r, uint32_t material, int rings = 32, int segments = 64) {
  std::vector<float> pos;
  std::vector<uint32_t> idx;
  for (int i = 0; i <= rings; ++i)
    for (int j = 0; j <= segments; ++j) {
      const double th = kPiT * i / rings, ph = 2.0 * kPiT * j / segments;
      pos.insert(pos.end(), {c.x + r * float(std::sin(th) * std::cos(ph)), c.y + r * float(std::sin(th) * std::sin(ph)),
                             c.z + r * float(std::cos(th))});
    }
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const uint32_t a = uint32_t(i * (segments + 1) + j), bb = a + 1, cc = a + uint32_t(segments + 1), d = cc + 1;
      if (i > 0) idx.insert(idx.end(), {a, cc, bb});
      if (i < rings - 1) idx.insert(idx.end(), {bb, cc, d});
    }
  std::vector<uint32_t> mats(idx.size() / 3, material);
  uint32_t id = 0;
  ASSERT_EQ(plm_scene_add_mesh(b.scene, name, pos.data(), uint32_t(pos.size() / 3), idx.data(),
                               uint32_t(idx.size() / 3), nullptr, mats.data(), 0, 0, &id),
            PLM_OK)
      << plm_last_error();
  ASSERT_EQ(plm_scene_set_mesh_smooth(b.scene, id, 1), PLM_OK);
}

// Mean texel value (mean RGB) over texels [i0, i1) x [j0, j1) of a map, per channel too.
struct Mean {
  double v = 0, r = 0, g = 0, b = 0;
};
Mean mean_over(const Map& m, uint32_t i0, uint32_t i1, uint32_t j0, uint32_t j1) {
  Mean s;
  double n = 0;
  for (uint32_t j = j0; j < j1; ++j)
    for (uint32_t i = i0; i < i1; ++i) {
      const size_t t = size_t(j) * m.w + i;
      s.r += m.rgb[3 * t], s.g += m.rgb[3 * t + 1], s.b += m.rgb[3 * t + 2];
      n += 1.0;
    }
  s.r /= n, s.g /= n, s.b /= n;
  s.v = (s.r + s.g + s.b) / 3.0;
  return s;
}

double fresnel(double cos_i, double eta) { return plm::bsdf::fresnel_dielectric(float(cos_i), float(eta)); }

// The sun through a clear slab of glass onto a black floor. Returns the
// floor's mean value over its inner texels.
double pane_floor(float theta, float ior, uint64_t photons, uint32_t direct_samples, uint32_t max_bounces = 1024) {
  SceneBuilder b;
  const uint32_t floor = b.material("floor", {0, 0, 0});
  const uint32_t glass = b.material("glass", {0, 0, 0});
  add_lobe(b, glass, PLM_LOBE_GLASS, {1, 1, 1}, 0.0f, ior);
  b.quad("floor", {-0.5f, -0.5f, 0}, {1, 0, 0}, {0, 1, 0}, floor, 8);
  const float shift = std::tan(theta);  // the pane above the floor as the sun sees it
  slab(b, glass, -1.0f - shift, 1.0f, -1.0f, 1.0f, 1.0f, 0.02f);
  b.light(sun({std::sin(theta), 0, -std::cos(theta)}, 1.0f), "sun");
  plm_bake_settings s = plm_test::settings_with(photons, direct_samples, max_bounces);
  s.seed = 5;
  BakeResult r;
  plm_test::bake(b, s, r);
  if (!r.r) return -1.0;
  const Map m = r.map(0);
  for (float v : m.rgb) EXPECT_TRUE(std::isfinite(v));
  return mean_over(m, 1, 7, 1, 7).v;
}

// Unpolarised transmission of a slab with all its internal reflections: (1 - R) / (1 + R).
double slab_transmission(double cos_i, double ior) {
  const double R = fresnel(cos_i, ior);
  return (1.0 - R) / (1.0 + R);
}

TEST(Materials, SunThroughAClearPaneAtNormalIncidence) {
  const double E = 1.0, direct = (1.0 - 0.04) * (1.0 - 0.04);  // 0.9216
  // The direct pass alone (no photons): the straight ray's two Fresnel transmissions.
  EXPECT_NEAR(pane_floor(0.0f, 1.5f, 1000, 16, 0), E * direct / kPiT, 1e-6);
  // With photons: the internal reflections' caustic on top, (1 - R) / (1 + R) = 0.92308.
  const double T = slab_transmission(1.0, 1.5);
  EXPECT_NEAR(T, 0.923077, 1e-6);
  const double both = pane_floor(0.0f, 1.5f, 2000000, 16);
  EXPECT_NEAR(both, E * T / kPiT, 2e-4 * E * T / kPiT);
  EXPECT_GT(both, E * (direct + 0.5 * (T - direct)) / kPiT);  // the caustic is there
  // Photons alone carry all of it.
  EXPECT_NEAR(pane_floor(0.0f, 1.5f, 4000000, 0), E * T / kPiT, 0.01 * E * T / kPiT);
}

TEST(Materials, SunThroughAClearPaneAt45Degrees) {
  const float theta = float(kPiT / 4.0);
  const double c = std::cos(double(theta)), R = fresnel(c, 1.5);
  const double direct = (1.0 - R) * (1.0 - R), T = slab_transmission(c, 1.5);
  EXPECT_NEAR(pane_floor(theta, 1.5f, 1000, 16, 0), c * direct / kPiT, 1e-6);
  EXPECT_NEAR(pane_floor(theta, 1.5f, 2000000, 16), c * T / kPiT, 3e-4 * c * T / kPiT);
}

TEST(Materials, APaneOfIorOneChangesNothing) {
  EXPECT_NEAR(pane_floor(0.3f, 1.0f, 200000, 16), std::cos(0.3) / kPiT, 1e-6);
}

TEST(Materials, ATransparentLobePassesItsColour) {
  for (uint32_t direct_samples : {16u, 0u}) {
    SceneBuilder b;
    const uint32_t floor = b.material("floor", {0, 0, 0});
    const uint32_t veil = b.material("veil", {0, 0, 0});
    add_lobe(b, veil, PLM_LOBE_TRANSPARENT, {0.3f, 0.6f, 0.9f});
    b.quad("floor", {-0.5f, -0.5f, 0}, {1, 0, 0}, {0, 1, 0}, floor, 8);
    b.quad("veil", {-1, -1, 1}, {2, 0, 0}, {0, 2, 0}, veil, 0);
    b.light(sun({0, 0, -1}, 2.0f), "sun");
    BakeResult r;
    plm_test::bake(b, plm_test::settings_with(direct_samples ? 1000 : 2000000, direct_samples, direct_samples ? 0 : 1024), r);
    const Mean m = mean_over(r.map(0), 1, 7, 1, 7);
    const double tol = direct_samples ? 1e-6 : 0.01;
    EXPECT_NEAR(m.r, 2.0 * 0.3 / kPiT, tol * 2.0 * 0.3 / kPiT) << direct_samples;
    EXPECT_NEAR(m.g, 2.0 * 0.6 / kPiT, tol * 2.0 * 0.6 / kPiT) << direct_samples;
    EXPECT_NEAR(m.b, 2.0 * 0.9 / kPiT, tol * 2.0 * 0.9 / kPiT) << direct_samples;
  }
}

// A horizontal mirror (FRESNEL lobe, colour = F0) under a sun at 45 degrees
// throws a patch of sun onto a wall facing it: there the wall gets E x the
// Fresnel curve's reflectance x cos 45 more than beside the patch, which
// the sun lights directly.
TEST(Materials, AMirrorThrowsTheSunOntoAWall) {
  SceneBuilder b;
  const uint32_t black = b.material("black", {0, 0, 0});
  const uint32_t metal = b.material("metal", {0, 0, 0});
  const V3 f0{0.9f, 0.6f, 0.3f};
  add_lobe(b, metal, PLM_LOBE_FRESNEL, f0, 0.0f, 1.5f);
  // Wall at x = 2 facing -x, y in [-1.5, 1.5], z in [0.5, 3.5]: 12 x 12 texels of 0.25 m.
  b.quad("wall", {2, 1.5f, 0.5f}, {0, -3, 0}, {0, 0, 3}, black, 12);
  b.quad("mirror", {-0.5f, -0.5f, 0}, {1, 0, 0}, {0, 1, 0}, metal, 0);
  const double E = 1.0;
  b.light(sun({std::sqrt(0.5f), 0, -std::sqrt(0.5f)}, float(E)), "sun");
  BakeResult r;
  plm_test::bake(b, plm_test::settings_with(3000000, 16), r);
  const Map m = r.map(0);
  // The patch: mirror points (x, y, 0) reach the wall at z = 2 - x, y: z in
  // [1.5, 2.5] (texel rows 4..7), y in [-0.5, 0.5] (u = (1.5 - y) / 3: columns 4..7).
  const Mean patch = mean_over(m, 5, 7, 5, 7);
  const Mean beside = mean_over(m, 5, 7, 9, 11);
  const Mean below = mean_over(m, 0, 3, 0, 3);
  const double c = std::sqrt(0.5);
  const double F0 = fresnel(1.0, 1.5), fh = (fresnel(c, 1.5) - F0) / (1.0 - F0);
  const double expect[3] = {E * c * (f0.x * (1 - fh) + fh) / kPiT, E * c * (f0.y * (1 - fh) + fh) / kPiT,
                            E * c * (f0.z * (1 - fh) + fh) / kPiT};
  EXPECT_NEAR(beside.v, E * c / kPiT, 1e-5);  // direct sun only
  EXPECT_NEAR(below.v, E * c / kPiT, 1e-5);
  EXPECT_NEAR(patch.r - beside.r, expect[0], 0.01 * expect[0]);
  EXPECT_NEAR(patch.g - beside.g, expect[1], 0.01 * expect[1]);
  EXPECT_NEAR(patch.b - beside.b, expect[2], 0.015 * expect[2]);
  // Its edge lies on the texel edges: the texel rows just outside get nothing of it.
  const Mean above_patch = mean_over(m, 5, 7, 8, 9), side_patch = mean_over(m, 2, 3, 5, 7);
  EXPECT_NEAR(above_patch.v, E * c / kPiT, 2e-3);
  EXPECT_NEAR(side_patch.v, E * c / kPiT, 2e-3);
}

// A closed furnace (every wall emits 1 and reflects rho = 0.5: every texel
// reads 2) with a lossless object inside keeps its value: a smooth glass
// sphere, a perfect mirror sphere. Rough glass and rough metal lose GGX's
// single-scattering energy: lower, never higher, and no NaN.
double furnace_with_sphere(plm_lobe_type type, float roughness, double* worst = nullptr) {
  SceneBuilder b;
  plm_demo::build_furnace(b, 0.5f, 1.0f, 16);
  const uint32_t m = b.material("ball", {0, 0, 0});
  add_lobe(b, m, type, {1, 1, 1}, roughness, 1.5f);
  sphere(b, "ball", {0.2f, -0.1f, 0.1f}, 0.6f, m);
  BakeResult r;
  plm_test::bake(b, plm_test::settings_with(2000000, 16), r);
  double sum = 0.0, n = 0.0, far = 0.0;
  {
    const Map map = r.map(0);  // the box: its six faces in one map
    for (size_t t = 0; t < map.coverage.size(); ++t) {
      if (map.coverage[t] <= 0.0f) continue;
      const double v = map.value(t);
      EXPECT_TRUE(std::isfinite(v));
      sum += v, n += 1.0;
      far = std::max(far, std::fabs(v - 2.0) / std::max(double(map.error[t]), 1e-9));
    }
  }
  if (worst) *worst = far;
  return sum / n;
}

TEST(Materials, LosslessSpheresKeepTheFurnacesValue) {
  double worst = 0.0;
  EXPECT_NEAR(furnace_with_sphere(PLM_LOBE_GLASS, 0.0f, &worst), 2.0, 0.005);
  EXPECT_LT(worst, 6.0) << "a texel beyond 6 of its reported errors";
  EXPECT_NEAR(furnace_with_sphere(PLM_LOBE_GLOSSY, 0.0f, &worst), 2.0, 0.005);
  EXPECT_LT(worst, 6.0);
}

// GGX's single-scattering albedo averaged over cosine-weighted incidence,
// 2 int E(mu) mu dmu with E(mu) = int D G1(i) G1(o) / (4 mu) do (Walter et
// al. 2007, eqs. 33-34), by quadrature.
double ggx_mean_albedo(double a) {
  auto d = [&](double c) {
    const double c2 = c * c, t2 = (1.0 - c2) / c2;
    return a * a / (kPiT * c2 * c2 * (a * a + t2) * (a * a + t2));
  };
  auto g1 = [&](double c) { return 2.0 / (1.0 + std::sqrt(1.0 + a * a * (1.0 - c * c) / (c * c))); };
  constexpr int kMu = 48, kTheta = 600, kPhi = 120;
  double mean = 0.0;
  for (int m = 0; m < kMu; ++m) {
    const double mu = (m + 0.5) / kMu, s = std::sqrt(1.0 - mu * mu);
    double e = 0.0;
    for (int i = 0; i < kTheta; ++i) {
      const double th = (i + 0.5) * 0.5 * kPiT / kTheta, z = std::cos(th), st = std::sin(th);
      for (int j = 0; j < kPhi; ++j) {
        const double ph = (j + 0.5) * 2.0 * kPiT / kPhi;
        double h[3] = {s + st * std::cos(ph), st * std::sin(ph), mu + z};
        const double hl = std::sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
        e += st * d(h[2] / hl) * g1(mu) * g1(z) / (4.0 * mu);
      }
    }
    e *= (0.5 * kPiT / kTheta) * (2.0 * kPiT / kPhi);
    mean += 2.0 * e * mu / kMu;
  }
  return mean;
}

// A rough metal sphere absorbs 1 - its mean albedo a of the light reaching
// it (a convex sphere is met once): the furnace's balance, emission into the
// box = what the walls and the sphere absorb, gives L = e A_w / ((1 - rho)
// A_w + (1 - a) A_s) for the walls' mean. Rough glass (light bounces inside
// it) loses less than nothing: below the lossless value, no NaN.
TEST(Materials, RoughGlassAndMetalLoseOnlyTheirSingleScatteringEnergy) {
  const double a = ggx_mean_albedo(0.7 * 0.7);
  const double walls = 24.0, ball = 4.0 * kPiT * 0.6 * 0.6;
  const double metal = furnace_with_sphere(PLM_LOBE_GLOSSY, 0.7f);
  EXPECT_NEAR(metal, walls / (0.5 * walls + (1.0 - a) * ball), 0.01) << "mean albedo " << a;
  const double glass = furnace_with_sphere(PLM_LOBE_GLASS, 0.5f);
  EXPECT_LT(glass, 2.0 + 0.005);
  EXPECT_GT(glass, metal);
}


TEST(Materials, DispersionWeightsAverageToWhite) {
  // The mean of each channel's weight over 380-780 nm is 1 (white stays white).
  double sum[3] = {0, 0, 0};
  constexpr int kN = 40000;
  for (int i = 0; i < kN; ++i) {
    const plm::Vec3 w = plm::rgb_weight(380.0f + 400.0f * (float(i) + 0.5f) / kN);
    sum[0] += w.x, sum[1] += w.y, sum[2] += w.z;
  }
  for (double v : sum) EXPECT_NEAR(v / kN, 1.0, 1e-4);
  // Blue before green before red: the weights' centroids in wavelength.
  double c[3] = {0, 0, 0};
  for (int i = 0; i < kN; ++i) {
    const float l = 380.0f + 400.0f * (float(i) + 0.5f) / kN;
    const plm::Vec3 w = plm::rgb_weight(l);
    c[0] += w.x * l, c[1] += w.y * l, c[2] += w.z * l;
  }
  EXPECT_GT(c[0], c[1]);
  EXPECT_GT(c[1], c[2]);
  // The Cauchy fit goes through n_d and has the asked-for Abbe number.
  const plm::Cauchy k = plm::cauchy_fit(1.5168f, 64.17f);  // Schott N-BK7
  EXPECT_NEAR(k.at(0.5876f), 1.5168f, 1e-6f);
  EXPECT_NEAR((k.at(0.5876f) - 1.0f) / (k.at(0.4861f) - k.at(0.6563f)), 64.17f, 0.01f);
}

// A 2D ray in the prism's cross-section (x, z).
struct Ray2 {
  double x, z, dx, dz;
};

// Refracts unit direction (dx, dz) at a face of unit normal (nx, nz) facing
// the incoming side, from index 1 to eta = n2 / n1; false under total internal reflection.
bool refract2(Ray2& r, double nx, double nz, double eta) {
  const double c = -(r.dx * nx + r.dz * nz);
  const double k = 1.0 - (1.0 - c * c) / (eta * eta);
  if (k < 0.0) return false;
  const double a = c / eta - std::sqrt(k);
  r.dx = r.dx / eta + a * nx;
  r.dz = r.dz / eta + a * nz;
  return true;
}

// Distance along r to the segment p-q (infinite if missed).
double to_segment(const Ray2& r, double px, double pz, double qx, double qz) {
  const double ex = qx - px, ez = qz - pz, det = r.dx * -ez - r.dz * -ex;
  if (std::fabs(det) < 1e-12) return INFINITY;
  const double wx = px - r.x, wz = pz - r.z;
  const double t = (wx * -ez - wz * -ex) / det, s = (r.dx * wz - r.dz * wx) / det;
  return t > 1e-9 && s >= 0.0 && s <= 1.0 ? t : INFINITY;
}

// A prism of IOR 1.5 and Abbe number 30 (apex down, 60 degrees) under a sun
// at its minimum deviation: the light leaving it reaches a ceiling (facing
// down) as a spectrum, blue nearer the prism than red. Each channel's
// centroid on the ceiling lies where a 2D trace of Snell's law (each
// wavelength's Cauchy index, weighted by the channel's weight) puts it, and
// each channel brings the flux the prism's entry face catches.
TEST(Materials, APrismSplitsWhiteIntoAnOrderedSpectrum) {
  const double ax = -0.5, az = 0.866025, bx = 0.5, bz = 0.866025, cx = 0.0, cz = 0.0;  // the cross-section
  const double ceiling_z = 1.5;
  const float ior = 1.5f, abbe = 30.0f;
  const double phi = -(std::asin(0.75) - kPiT / 6.0);  // the sun's elevation for minimum deviation at n = 1.5
  const V3 d{float(std::cos(phi)), 0.0f, float(std::sin(phi))};
  SceneBuilder b;
  const uint32_t black = b.material("black", {0, 0, 0});
  const uint32_t glass = b.material("flint", {0, 0, 0});
  add_lobe(b, glass, PLM_LOBE_REFRACTION, {1, 1, 1}, 0.0f, ior, abbe);
  b.quad("entry", {float(ax), -2, float(az)}, {0, 4, 0}, {float(cx - ax), 0, float(cz - az)}, glass, 0);
  b.quad("exit", {float(cx), -2, float(cz)}, {0, 4, 0}, {float(bx - cx), 0, float(bz - cz)}, glass, 0);
  b.quad("base", {float(ax), -2, float(az)}, {1, 0, 0}, {0, 4, 0}, black, 0);
  b.light(sun(d, 1.0f), "sun");
  ASSERT_TRUE(b.ok()) << b.error;
  // The ceiling, 6 x 2 m facing down, with 60 x 20 texels of 0.1 m (quad() makes square maps).
  const float pos[12] = {0, 1, float(ceiling_z), 6, 1, float(ceiling_z), 0, -1, float(ceiling_z),
                         6, -1, float(ceiling_z)};
  const uint32_t idx[6] = {0, 1, 3, 0, 3, 2};  // facing down
  const float uv[12] = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
  const uint32_t mats[2] = {black, black};
  uint32_t screen = 0;
  ASSERT_EQ(plm_scene_add_mesh(b.scene, "screen", pos, 4, idx, 2, uv, mats, 60, 20, &screen), PLM_OK)
      << plm_last_error();
  BakeResult r;
  plm_test::bake(b, plm_test::settings_with(4000000, 16), r);
  const Map m = r.map(screen);
  double flux[3] = {0, 0, 0}, cx_sum[3] = {0, 0, 0};
  for (uint32_t j = 0; j < m.h; ++j)
    for (uint32_t i = 0; i < m.w; ++i) {
      const size_t t = size_t(j) * m.w + i;
      const double x = (i + 0.5) * 0.1;
      for (int c = 0; c < 3; ++c) {
        ASSERT_TRUE(std::isfinite(m.rgb[3 * t + c]));
        flux[c] += m.rgb[3 * t + c] * kPiT * 0.01;  // irradiance x area
        cx_sum[c] += m.rgb[3 * t + c] * x;
      }
    }
  // The trace: rays entering the entry face at heights z, each wavelength.
  double want_flux[3] = {0, 0, 0}, want_x[3] = {0, 0, 0}, weight[3] = {0, 0, 0};
  const plm::Cauchy k = plm::cauchy_fit(ior, abbe);
  const double n_entry[2] = {-0.866025, -0.5}, n_exit[2] = {0.866025, -0.5};
  constexpr int kZ = 200, kL = 400;
  for (int zi = 0; zi < kZ; ++zi)
    for (int li = 0; li < kL; ++li) {
      const double f = (zi + 0.5) / kZ, lambda = 380.0 + 400.0 * (li + 0.5) / kL;
      const plm::Vec3 w = plm::rgb_weight(float(lambda));
      const double n = k.at(float(lambda * 1e-3));
      Ray2 ray{ax + f * (cx - ax), az + f * (cz - az), d.x, d.z};
      double hit_x = NAN;
      if (refract2(ray, n_entry[0], n_entry[1], n)) {
        const double t_exit = to_segment(ray, cx, cz, bx, bz), t_base = to_segment(ray, ax, az, bx, bz);
        if (t_exit < t_base) {
          ray.x += t_exit * ray.dx, ray.z += t_exit * ray.dz;
          if (refract2(ray, -n_exit[0], -n_exit[1], 1.0 / n) && ray.dz > 0.0)
            hit_x = ray.x + (ceiling_z - ray.z) / ray.dz * ray.dx;
        }
      }
      const double wc[3] = {w.x, w.y, w.z};
      for (int c = 0; c < 3; ++c) {
        weight[c] += wc[c];
        if (std::isnan(hit_x) || hit_x < 0.0 || hit_x > 6.0) continue;
        want_flux[c] += wc[c];
        want_x[c] += wc[c] * hit_x;
      }
    }
  const double caught = std::fabs(d.x * n_entry[0] + d.z * n_entry[1]) * 1.0 * 2.0;  // |d.n| x face width x 2 m
  for (int c = 0; c < 3; ++c) {
    want_x[c] /= want_flux[c];
    want_flux[c] *= caught / weight[c];
    EXPECT_NEAR(flux[c], want_flux[c], 0.02 * want_flux[c]) << "channel " << c;
    EXPECT_NEAR(cx_sum[c] * kPiT * 0.01 / flux[c], want_x[c], 0.02) << "channel " << c;
  }
  EXPECT_GT(want_x[0] - want_x[2], 0.15);  // the trace's spectrum: red ~0.3 m beyond blue
  EXPECT_GT(cx_sum[0] * kPiT * 0.01 / flux[0], cx_sum[1] * kPiT * 0.01 / flux[1]);
  EXPECT_GT(cx_sum[1] * kPiT * 0.01 / flux[1], cx_sum[2] * kPiT * 0.01 / flux[2]);
}

}  // namespace

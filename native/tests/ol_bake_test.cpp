// Orientation-lightmap groups baked through the C API, checked against
// analytic answers: a furnace, the energy balance around a point light, a
// sphere under the sun (and the same sphere with an ordinary lightmap).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "demo_scenes.h"
#include "ol/octahedral.h"
#include "test_support.h"

namespace {

using plm_demo::SceneBuilder;
using plm_demo::V3;
using plm_test::bake;
using Baked = plm_test::BakeResult;

plm_bake_settings settings(uint64_t photons, uint32_t direct_samples) {
  return plm_test::settings_with(photons, direct_samples);
}

bool contains(const char* text, const std::string& needle) { return std::string(text).find(needle) != std::string::npos; }

// One baked OL, copied out of the result.
struct Ol {
  uint32_t n = 0;
  std::vector<float> rgb, error, area, hits;
  plm_ol_stats stats = plm_test::sized<plm_ol_stats>();
  double value(size_t b) const { return (double(rgb[3 * b]) + rgb[3 * b + 1] + rgb[3 * b + 2]) / 3.0; }
};

Ol read_ol(const Baked& r, uint32_t group) {
  Ol o;
  const float *rgb = nullptr, *err = nullptr, *area = nullptr, *hits = nullptr;
  EXPECT_EQ(plm_result_ol(r.r, group, &rgb, &err, &o.n), PLM_OK) << plm_last_error();
  EXPECT_EQ(plm_result_ol_bins(r.r, group, &area, &hits), PLM_OK) << plm_last_error();
  EXPECT_EQ(plm_result_ol_stats(r.r, group, &o.stats), PLM_OK) << plm_last_error();
  const size_t bins = size_t(o.n) * o.n;
  o.rgb.assign(rgb, rgb + 3 * bins);
  o.error.assign(err, err + bins);
  o.area.assign(area, area + bins);
  o.hits.assign(hits, hits + bins);
  return o;
}

// A UV sphere of nphi x ntheta cells (triangle fans at the poles), faces
// outward (or inward), lightmap UVs putting each triangle alone in a texel of
// a res x res map (res = ceil(sqrt(T))).
struct SphereMesh {
  std::vector<float> pos;
  std::vector<uint32_t> idx;
  std::vector<float> uv;
  uint32_t res = 0;
  uint32_t triangles() const { return uint32_t(idx.size() / 3); }
  V3 vertex(uint32_t t, int k) const {
    const uint32_t v = idx[3 * t + k];
    return {pos[3 * v], pos[3 * v + 1], pos[3 * v + 2]};
  }
};

SphereMesh uv_sphere(V3 c, float radius, uint32_t nphi, uint32_t ntheta, bool inward) {
  SphereMesh m;
  auto add = [&](double th, double ph) {
    m.pos.insert(m.pos.end(), {c.x + float(radius * std::sin(th) * std::cos(ph)),
                               c.y + float(radius * std::sin(th) * std::sin(ph)), c.z + float(radius * std::cos(th))});
  };
  add(0.0, 0.0);  // north pole: vertex 0
  for (uint32_t j = 1; j < ntheta; ++j)
    for (uint32_t i = 0; i < nphi; ++i) add(M_PI * j / ntheta, 2.0 * M_PI * i / nphi);
  add(M_PI, 0.0);  // south pole
  const uint32_t south = uint32_t(m.pos.size() / 3 - 1);
  auto ring = [&](uint32_t j, uint32_t i) { return j == 0 ? 0u : j == ntheta ? south : 1 + (j - 1) * nphi + i % nphi; };
  auto tri = [&](uint32_t a, uint32_t b, uint32_t d) {
    if (inward) m.idx.insert(m.idx.end(), {a, d, b});
    else m.idx.insert(m.idx.end(), {a, b, d});
  };
  for (uint32_t j = 0; j < ntheta; ++j)
    for (uint32_t i = 0; i < nphi; ++i) {
      const uint32_t a = ring(j, i), b = ring(j, i + 1), cc = ring(j + 1, i), d = ring(j + 1, i + 1);
      if (j + 1 < ntheta) tri(a, cc, d);  // (a, c, d) and (a, d, b): cross(c - a, d - a) points out
      if (j > 0) tri(a, d, b);  // the south fan: (a, south, b)
    }
  m.res = uint32_t(std::ceil(std::sqrt(double(m.triangles()))));
  for (uint32_t t = 0; t < m.triangles(); ++t) {
    const float x = float(t % m.res), y = float(t / m.res), s = 1.0f / float(m.res);
    m.uv.insert(m.uv.end(), {(x + 0.1f) * s, (y + 0.1f) * s, (x + 0.9f) * s, (y + 0.1f) * s, (x + 0.1f) * s, (y + 0.9f) * s});
  }
  return m;
}

V3 sub(V3 a, V3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
V3 cross(V3 a, V3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
double dot(V3 a, V3 b) { return double(a.x) * b.x + double(a.y) * b.y + double(a.z) * b.z; }

// Adds the sphere as a mesh of material mat, with a lightmap or in a new OL group.
uint32_t add_sphere(SceneBuilder& b, const SphereMesh& s, uint32_t mat, bool lightmap, uint32_t ol_resolution,
                    uint32_t* group) {
  std::vector<uint32_t> mats(s.triangles(), mat);
  uint32_t mesh = 0;
  EXPECT_EQ(plm_scene_add_mesh(b.scene, "sphere", s.pos.data(), uint32_t(s.pos.size() / 3), s.idx.data(),
                               s.triangles(), lightmap ? s.uv.data() : nullptr, mats.data(), lightmap ? s.res : 0,
                               lightmap ? s.res : 0, &mesh),
            PLM_OK)
      << plm_last_error();
  if (!lightmap) {
    EXPECT_EQ(plm_scene_add_ol_group(b.scene, "sphere group", ol_resolution, group), PLM_OK) << plm_last_error();
    EXPECT_EQ(plm_scene_set_mesh_ol_group(b.scene, mesh, *group), PLM_OK) << plm_last_error();
  }
  return mesh;
}

// Every bin with area reads E / (1 - rho) within its reported error.
void expect_furnace_bins(const Ol& o, double exact, double rel_tol, const char* what) {
  double z2 = 0.0;
  int covered = 0;
  for (size_t b = 0; b < o.area.size(); ++b) {
    if (!(o.area[b] > 0.0f)) {
      EXPECT_EQ(o.value(b), 0.0) << what << " bin " << b;
      continue;
    }
    ++covered;
    const double z = (o.value(b) - exact) / o.error[b];
    z2 += z * z;
    EXPECT_NEAR(o.value(b), exact, std::max(4.5 * o.error[b], rel_tol * exact)) << what << " bin " << b;
  }
  ASSERT_GT(covered, 0);
  std::printf("[ %s ] %d bins with area, mean z^2 %.3f, flux %.6g, orphan %.3g\n", what, covered, z2 / covered,
              o.stats.flux, o.stats.orphan_flux);
  if (covered >= 50) {  // enough bins for the spread to say something
    EXPECT_GT(z2 / covered, 0.5) << what;
    EXPECT_LT(z2 / covered, 2.0) << what;
  }
  EXPECT_EQ(o.stats.orphan_flux, 0.0) << what;
}

TEST(OlBake, FurnaceBoxReadsEmissionOverOneMinusAlbedo) {
  for (uint32_t direct : {0u, 16u}) {  // OL meshes record depth 0 too when the direct pass is on
    SceneBuilder b;
    const float rho = 0.5f;
    const uint32_t m = b.material("furnace", {rho, rho, rho}, {1, 1, 1});
    const uint32_t mesh = b.box("furnace", {0, 0, 0}, {2, 2, 2}, 0.0f, m, 0, true);
    uint32_t g = 0;
    ASSERT_EQ(plm_scene_add_ol_group(b.scene, "walls", 0, &g), PLM_OK) << plm_last_error();
    ASSERT_EQ(plm_scene_set_mesh_ol_group(b.scene, mesh, g), PLM_OK) << plm_last_error();
    Baked r;
    bake(b, settings(1000000, direct), r);
    const Ol o = read_ol(r, g);
    EXPECT_EQ(o.n, 16u);  // automatic resolution
    EXPECT_EQ(o.stats.mesh_count, 1u);
    EXPECT_NEAR(o.stats.area, 24.0, 1e-9);
    // Each 4 m^2 face's area goes to the bins the lookup reads at its normal
    // by their weights: 2 bins for +-x and +-y (on the square's edge, where
    // the fold pairs the taps), 4 for +z (the centre) and -z (the corners).
    const plm::ol::OctGrid grid(o.n);
    std::vector<double> area(grid.bins(), 0.0);
    for (int axis = 0; axis < 3; ++axis)
      for (double side : {-1.0, 1.0}) {
        plm::Vec3d n{0, 0, 0};
        n[axis] = side;
        const plm::ol::Taps taps = grid.taps(n);
        for (int k = 0; k < 4; ++k) area[taps.bin[k]] += 4.0 * taps.weight[k];
      }
    int covered = 0;
    for (size_t k = 0; k < o.area.size(); ++k) {
      covered += area[k] > 0.0;
      EXPECT_NEAR(o.area[k], area[k], 1e-6) << "bin " << k;
    }
    EXPECT_EQ(covered, 16);
    expect_furnace_bins(o, 1.0 / (1.0 - rho), 0.01, direct ? "box, direct pass on" : "box, photons only");
  }
}

// A mesh with a lightmap in an OL group gets its lightmap resolved from the
// OL: every covered texel of a furnace box reads E / (1 - rho), the value and
// error of its face's bin, and the texels take no direct-pass samples.
TEST(OlBake, LightmapResolvedFromTheOl) {
  SceneBuilder b;
  const float rho = 0.5f;
  const uint32_t m = b.material("furnace", {rho, rho, rho}, {1, 1, 1});
  const uint32_t mesh = b.box("furnace", {0, 0, 0}, {2, 2, 2}, 0.0f, m, 8, true);
  uint32_t g = 0;
  ASSERT_EQ(plm_scene_add_ol_group(b.scene, "walls", 0, &g), PLM_OK) << plm_last_error();
  ASSERT_EQ(plm_scene_set_mesh_ol_group(b.scene, mesh, g), PLM_OK) << plm_last_error();
  Baked r;
  bake(b, settings(1000000, 16), r);
  EXPECT_EQ(r.stats().direct_samples, 0u);
  const Ol o = read_ol(r, g);
  const plm_test::Map lm = r.map(mesh);
  const double exact = 1.0 / (1.0 - rho);
  int covered = 0;
  for (size_t t = 0; t < lm.coverage.size(); ++t) {
    if (!(lm.coverage[t] > 0.0f)) continue;
    ++covered;
    EXPECT_GT(lm.hits[t], 0.0f) << "texel " << t;
    EXPECT_GT(lm.error[t], 0.0f) << "texel " << t;
    EXPECT_NEAR(lm.value(t), exact, std::max(4.5 * lm.error[t], 0.01 * exact)) << "texel " << t;
  }
  EXPECT_GT(covered, 6 * 30);
  EXPECT_EQ(o.stats.mesh_count, 1u);
}

// An inward sphere: a furnace with hundreds of covered bins, enough for the
// z-scores of the reported errors to be checked.
TEST(OlBake, FurnaceSphereErrorsAreHonest) {
  SceneBuilder b;
  const float rho = 0.7f;
  const uint32_t m = b.material("furnace", {rho, rho, rho}, {1, 1, 1});
  const SphereMesh s = uv_sphere({0.5f, -1.0f, 2.0f}, 1.5f, 40, 20, true);
  uint32_t g = 0;
  add_sphere(b, s, m, false, 8, &g);
  Baked r;
  // 2 M photons are 489 batches of 4096 (the last one short): the OL's 16
  // replicates hold 30 or 31 of them, unequal groups whose sizes the error
  // takes into account (taken as equal, their sizes alone spread them apart
  // more than their noise here).
  bake(b, settings(2000000, 16), r);
  expect_furnace_bins(read_ol(r, g), 1.0 / (1.0 - rho), 0.02, "inward sphere furnace");
}

// A black closed box around a point light: every photon ends on the box at
// its first hit, so the OL holds exactly the light's power.
TEST(OlBake, BlackBoxAroundPointLightHoldsItsPower) {
  SceneBuilder b;
  const uint32_t black = b.material("black", {0, 0, 0});
  const uint32_t mesh = b.box("box", {0, 0, 0}, {2, 3, 4}, 0.3f, black, 0, true);
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_POINT);
  l.power = 100.0f;
  l.radius = 0.0f;
  l.matrix[3] = 0.2f;
  l.matrix[7] = -0.4f;
  b.light(l, "lamp");
  uint32_t g = 0;
  ASSERT_EQ(plm_scene_add_ol_group(b.scene, "box", 4, &g), PLM_OK);
  ASSERT_EQ(plm_scene_set_mesh_ol_group(b.scene, mesh, g), PLM_OK);
  Baked r;
  bake(b, settings(300000, 16), r);
  const Ol o = read_ol(r, g);
  double sum = 0.0, hits = 0.0;
  for (size_t k = 0; k < o.area.size(); ++k) {
    sum += o.value(k) * M_PI * o.area[k];
    hits += o.hits[k];
  }
  std::printf("[ black box ] recorded %.7f W of 100 W (stats %.7f), %.0f hits\n", sum, o.stats.flux, hits);
  EXPECT_NEAR(sum, 100.0, 1e-4 * 100.0);
  EXPECT_NEAR(o.stats.flux, 100.0, 1e-6 * 100.0);
  EXPECT_EQ(o.stats.hits, r.stats().photons_emitted);
  EXPECT_EQ(hits, double(r.stats().photons_emitted));
}

// A sphere under the sun (strength S from +z): every bin reads the exact
// S max(0, cos theta) / pi of its triangles, averaged with their areas
// splatted by the lookup's taps (OctGrid::taps), 0 behind; and the same
// average of an ordinary lightmap on the same sphere.
TEST(OlBake, SphereUnderSunMatchesCosineAndTheLightmapLimit) {
  const float S = 3.0f;
  const SphereMesh s = uv_sphere({0, 0, 0}, 1.0f, 40, 20, false);
  for (uint32_t t = 0; t < s.triangles(); ++t) {  // the mesh really faces outward
    const V3 n = cross(sub(s.vertex(t, 1), s.vertex(t, 0)), sub(s.vertex(t, 2), s.vertex(t, 0)));
    ASSERT_GT(dot(n, s.vertex(t, 0)), 0.0) << "triangle " << t;
  }
  plm_light sun;
  plm_light_default(&sun, PLM_LIGHT_SUN);
  sun.power = S;
  sun.angle = 0.0f;
  auto scene = [&](SceneBuilder& b, bool lightmap, uint32_t* group) {
    const uint32_t black = b.material("black", {0, 0, 0});
    b.light(sun, "sun");
    return add_sphere(b, s, black, lightmap, 0, group);
  };
  SceneBuilder bo, bl;
  uint32_t g = 0;
  scene(bo, false, &g);
  const uint32_t lm_mesh = scene(bl, true, nullptr);
  Baked ro, rl;
  bake(bo, settings(4000000, 16), ro);
  plm_bake_settings ls = settings(200000, 64);
  ls.filter_radius = 0;
  ls.texel_value = PLM_TEXEL_AREA;  // a texel = its one triangle
  bake(bl, ls, rl);
  const Ol o = read_ol(ro, g);
  const plm_test::Map lm = rl.map(lm_mesh);

  // Per bin: triangle area, exact irradiance / pi and lightmap value, weighted
  // by the splatted area.
  const plm::ol::OctGrid grid(o.n);
  const size_t bins = grid.bins();
  std::vector<double> area(bins, 0.0), exact(bins, 0.0), lmv(bins, 0.0), lm_var(bins, 0.0);
  for (uint32_t t = 0; t < s.triangles(); ++t) {
    const V3 c = cross(sub(s.vertex(t, 1), s.vertex(t, 0)), sub(s.vertex(t, 2), s.vertex(t, 0)));
    const double len = std::sqrt(dot(c, c));
    const plm::Vec3d n{c.x / len, c.y / len, c.z / len};
    const plm::ol::Taps taps = grid.taps(n);
    for (int k = 0; k < 4; ++k) {
      const uint32_t b = taps.bin[k];
      const double a = 0.5 * len * taps.weight[k];
      area[b] += a;
      exact[b] += a * S * std::max(0.0, n.z) / M_PI;
      lmv[b] += a * lm.value(t);
      lm_var[b] += a * a * double(lm.error[t]) * lm.error[t];
    }
  }
  double z2 = 0.0, zl2 = 0.0, worst = 0.0;
  int lit = 0, dark = 0;
  for (size_t b = 0; b < bins; ++b) {
    EXPECT_NEAR(o.area[b], area[b], 1e-5 * (area[b] + 1e-3)) << "bin " << b;
    if (!(area[b] > 0.0)) continue;
    const double e = exact[b] / area[b], l = lmv[b] / area[b], le = std::sqrt(lm_var[b]) / area[b];
    if (e == 0.0) {
      EXPECT_EQ(o.value(b), 0.0) << "bin " << b << " faces away from the sun";
      ++dark;
      continue;
    }
    ++lit;
    const double z = (o.value(b) - e) / o.error[b];
    const double zl = (o.value(b) - l) / std::sqrt(double(o.error[b]) * o.error[b] + le * le);
    z2 += z * z;
    zl2 += zl * zl;
    worst = std::max(worst, std::fabs(o.value(b) - e) / e);
    EXPECT_NEAR(o.value(b), e, 4.5 * o.error[b] + 1e-3 * e) << "bin " << b << " exact " << e;
    EXPECT_NEAR(o.value(b), l, 4.5 * std::sqrt(double(o.error[b]) * o.error[b] + le * le) + 2e-3 * e)
        << "bin " << b << " lightmap " << l;
  }
  std::printf("[ sun sphere ] %d lit bins, %d dark; vs exact mean z^2 %.3f (worst relative %.4f); "
              "vs lightmap mean z^2 %.3f\n", lit, dark, z2 / lit, worst, zl2 / lit);
  EXPECT_GT(lit, 60);
  EXPECT_GT(dark, 60);
  EXPECT_GT(z2 / lit, 0.5);
  EXPECT_LT(z2 / lit, 2.0);
  EXPECT_LT(zl2 / lit, 2.0);
  EXPECT_EQ(o.stats.orphan_flux, 0.0);
  // Energy: the sphere intercepts S pi r^2 (of its faceted cross-section).
  double cross_section = 0.0;
  for (size_t b = 0; b < bins; ++b) cross_section += exact[b] * M_PI / S;
  EXPECT_NEAR(o.stats.flux, S * cross_section, 5e-3 * S * cross_section);
}

// A coarse sphere (32 x 16 segments) in a 16 x 16 OL, its lightmap resolved
// from the OL, under a tilted sun: its bins' areas differ by up to 1.6x, yet
// the resolved lightmap (texel t = the OL at triangle t's normal) holds the
// light the sphere intercepts: its area-weighted mean is the exact
// sum_t A_t S max(0, n_t.s) / pi / sum_t A_t, and that of the same sphere
// baked with its own lightmap.
TEST(OlBake, CoarseSphereResolvedLightmapHoldsTheInterceptedLight) {
  const float S = 3.0f, tilt = 0.3f;
  const SphereMesh s = uv_sphere({0, 0, 0}, 1.0f, 32, 16, false);
  const plm_light sun = plm_test::tilted_sun(S, tilt);  // light travels along (0, sin a, -cos a)
  const double sx = 0.0, sy = -std::sin(double(tilt)), sz = std::cos(double(tilt));
  double area = 0.0, exact = 0.0;
  std::vector<double> tri_area(s.triangles());
  for (uint32_t t = 0; t < s.triangles(); ++t) {
    const V3 c = cross(sub(s.vertex(t, 1), s.vertex(t, 0)), sub(s.vertex(t, 2), s.vertex(t, 0)));
    const double len = std::sqrt(dot(c, c));
    tri_area[t] = 0.5 * len;
    area += tri_area[t];
    exact += tri_area[t] * S * std::max(0.0, (c.x * sx + c.y * sy + c.z * sz) / len) / M_PI;
  }
  exact /= area;
  auto mean = [&](bool ol, uint64_t photons, uint32_t direct) {
    SceneBuilder b;
    const uint32_t black = b.material("black", {0, 0, 0});
    b.light(sun, "sun");
    const uint32_t mesh = add_sphere(b, s, black, true, 0, nullptr);
    if (ol) {
      uint32_t g = 0;
      EXPECT_EQ(plm_scene_add_ol_group(b.scene, "sphere group", 16, &g), PLM_OK) << plm_last_error();
      EXPECT_EQ(plm_scene_set_mesh_ol_group(b.scene, mesh, g), PLM_OK) << plm_last_error();
    }
    plm_bake_settings st = settings(photons, direct);
    st.filter_radius = 0;
    st.texel_value = PLM_TEXEL_AREA;  // a texel = its one triangle
    Baked r;
    bake(b, st, r);
    const plm_test::Map lm = r.map(mesh);
    double sum = 0.0;
    for (uint32_t t = 0; t < s.triangles(); ++t) sum += tri_area[t] * lm.value(t);
    return sum / area;
  };
  const double ol = mean(true, 1000000, 0), lightmap = mean(false, 200000, 64);
  std::printf("[ coarse sphere ] OL-resolved mean / exact %.4f, / own lightmap %.4f (lightmap / exact %.4f)\n",
              ol / exact, ol / lightmap, lightmap / exact);
  EXPECT_NEAR(lightmap, exact, 0.005 * exact);
  EXPECT_NEAR(ol, exact, 0.01 * exact);
  EXPECT_NEAR(ol, lightmap, 0.01 * lightmap);
}

TEST(OlBake, SameSeedSameOlWhateverTheThreads) {
  std::vector<float> first;
  for (uint32_t threads : {1u, 3u, 8u}) {
    SceneBuilder b;
    const uint32_t m = b.material("grey", {0.6f, 0.6f, 0.6f}, {1, 1, 1});
    const uint32_t mesh = b.box("box", {0, 0, 0}, {2, 1, 3}, 0.2f, m, 0, true);
    uint32_t g = 0;
    ASSERT_EQ(plm_scene_add_ol_group(b.scene, nullptr, 8, &g), PLM_OK);
    ASSERT_EQ(plm_scene_set_mesh_ol_group(b.scene, mesh, g), PLM_OK);
    plm_bake_settings s = settings(100000, 0);
    s.thread_count = threads;
    Baked r;
    bake(b, s, r);
    const Ol o = read_ol(r, g);
    if (first.empty()) first = o.rgb;
    else EXPECT_EQ(o.rgb, first) << threads << " threads";
  }
}

TEST(OlApi, BadInputNamesGroupAndMesh) {
  SceneBuilder b;
  const uint32_t m = b.material("grey", {0.5f, 0.5f, 0.5f});
  const uint32_t geo = b.quad("floor", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, m, 0);
  const uint32_t mapped = b.quad("wall", {0, 0, 0}, {0, 1, 0}, {0, 0, 1}, m, 8);
  uint32_t g = 99;
  EXPECT_EQ(plm_scene_add_ol_group(b.scene, "huge", 2000, &g), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(contains(plm_last_error(), "'huge'")) << plm_last_error();
  EXPECT_TRUE(contains(plm_last_error(), "2000")) << plm_last_error();
  EXPECT_TRUE(contains(plm_last_error(), "1024")) << plm_last_error();
  EXPECT_EQ(g, 99u);
  ASSERT_EQ(plm_scene_add_ol_group(b.scene, "objects", 1024, &g), PLM_OK);
  EXPECT_EQ(g, 0u);
  EXPECT_EQ(plm_scene_set_mesh_ol_group(b.scene, 7, g), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(contains(plm_last_error(), "mesh 7 does not exist")) << plm_last_error();
  EXPECT_EQ(plm_scene_set_mesh_ol_group(b.scene, geo, 3), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(contains(plm_last_error(), "'floor'")) << plm_last_error();
  EXPECT_TRUE(contains(plm_last_error(), "OL group 3 does not exist")) << plm_last_error();
  (void)mapped;
  EXPECT_EQ(plm_scene_set_mesh_ol_group(nullptr, geo, g), PLM_ERROR_INVALID_ARGUMENT);

  // A group without meshes is a warning; a bad group index on the result an error.
  uint32_t empty = 0;
  ASSERT_EQ(plm_scene_add_ol_group(b.scene, "nobody", 0, &empty), PLM_OK);
  ASSERT_EQ(plm_scene_set_mesh_ol_group(b.scene, geo, g), PLM_OK);
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_SUN);
  b.light(l, "sun");
  Baked r;
  bake(b, settings(20000, 4), r);
  EXPECT_NE(r.warning("'nobody' (1) has no meshes"), "") << r.all_warnings();
  const Ol o = read_ol(r, empty);
  for (float v : o.rgb) EXPECT_EQ(v, 0.0f);
  const float* rgb = nullptr;
  uint32_t n = 0;
  EXPECT_EQ(plm_result_ol(r.r, 2, &rgb, nullptr, &n), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(contains(plm_last_error(), "OL group 2 is out of range")) << plm_last_error();
  EXPECT_EQ(plm_result_write_ol_exr(r.r, 5, "/tmp/x.exr"), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(contains(plm_last_error(), "OL group 5")) << plm_last_error();
}

TEST(OlApi, OlOnlySceneBakesAndTargetErrorNeedsACap) {
  SceneBuilder b;
  const uint32_t m = b.material("grey", {0.5f, 0.5f, 0.5f}, {1, 1, 1});
  const uint32_t mesh = b.box("box", {0, 0, 0}, {1, 1, 1}, 0.0f, m, 0, true);
  plm_bake_settings s = settings(10000, 4);
  plm_result* r = nullptr;
  EXPECT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r), PLM_ERROR_INVALID_SCENE);  // nothing to bake
  EXPECT_TRUE(contains(plm_last_error(), "OL group")) << plm_last_error();
  uint32_t g = 0;
  ASSERT_EQ(plm_scene_add_ol_group(b.scene, "g", 0, &g), PLM_OK);
  ASSERT_EQ(plm_scene_set_mesh_ol_group(b.scene, mesh, g), PLM_OK);
  // A target cannot steer OLs: with a photon cap it is ignored with a warning, without one refused.
  s.target_error = 0.05;
  {
    Baked baked;
    bake(b, s, baked);
    EXPECT_EQ(baked.stats().photons_emitted, 10000u);
    EXPECT_TRUE(contains(baked.all_warnings().c_str(), "target_error ignored")) << baked.all_warnings();
  }
  s.photon_count = 0;
  EXPECT_EQ(plm_bake(b.scene, &s, nullptr, nullptr, &r), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(contains(plm_last_error(), "target_error")) << plm_last_error();
  EXPECT_EQ(r, nullptr);
}

TEST(OlApi, OlExrReadsBack) {
  SceneBuilder b;
  const uint32_t m = b.material("grey", {0.5f, 0.5f, 0.5f}, {1, 1, 1});
  const uint32_t mesh = b.box("box", {0, 0, 0}, {1, 1, 1}, 0.0f, m, 0, true);
  uint32_t g = 0;
  ASSERT_EQ(plm_scene_add_ol_group(b.scene, "g", 6, &g), PLM_OK);
  ASSERT_EQ(plm_scene_set_mesh_ol_group(b.scene, mesh, g), PLM_OK);
  Baked r;
  bake(b, settings(20000, 0), r);
  const Ol o = read_ol(r, g);
  char tmpl[] = "/tmp/photonlm_olexr_XXXXXX";
  const std::string dir = mkdtemp(tmpl);
  const std::string path = dir + "/ol.exr";
  ASSERT_EQ(plm_result_write_ol_exr(r.r, g, path.c_str()), PLM_OK) << plm_last_error();
  const plm_test::ExrChannels exr = plm_test::read_exr_channels(path);
  ASSERT_EQ(exr.width, 6);
  ASSERT_EQ(exr.height, 6);
  ASSERT_EQ(exr.channels.size(), 6u);
  for (uint32_t y = 0; y < 6; ++y)  // file row 0 = top = bin row 5
    for (uint32_t x = 0; x < 6; ++x) {
      const size_t f = size_t(5 - y) * 6 + x, k = size_t(y) * 6 + x;
      EXPECT_EQ(exr.channels.at("R")[f], o.rgb[3 * k]);
      EXPECT_EQ(exr.channels.at("area")[f], o.area[k]);
      EXPECT_EQ(exr.channels.at("error")[f], o.error[k]);
      EXPECT_EQ(exr.channels.at("hits")[f], o.hits[k]);
    }
  std::remove(path.c_str());
  rmdir(dir.c_str());
}

}  // namespace

namespace {

// Relative RMSE of all covered texels of the given meshes against reference maps.
double rmse_against(const Baked& r, const std::vector<uint32_t>& meshes, const std::vector<plm_test::Map>& ref) {
  double sq = 0.0, sum = 0.0, n = 0.0;
  for (size_t i = 0; i < meshes.size(); ++i) {
    const plm_test::Map m = r.map(meshes[i]);
    for (size_t t = 0; t < m.coverage.size(); ++t) {
      if (m.coverage[t] < 0.999f) continue;
      const double d = m.value(t) - ref[i].value(t);
      sq += d * d;
      sum += ref[i].value(t);
      n += 1.0;
    }
  }
  return std::sqrt(sq / n) / (sum / n);
}

}  // namespace

// A backup OL over a furnace box (uniform: the OL is exact there) cuts the
// texels' photon noise (against plain texels without the final gather, which
// OL meshes do not have), and the reported errors stay honest.
TEST(OlBake, BackupOlLowersFurnaceNoise) {
  const float rho = 0.5f;
  const double exact = 1.0 / (1.0 - rho);
  double err[2] = {0, 0}, z2[2] = {0, 0};
  for (int backup = 0; backup < 2; ++backup) {
    SceneBuilder b;
    const uint32_t m = b.material("furnace", {rho, rho, rho}, {1, 1, 1});
    const uint32_t mesh = b.box("furnace", {0, 0, 0}, {2, 2, 2}, 0.0f, m, 16, true);
    uint32_t g = 0;
    ASSERT_EQ(plm_scene_add_ol_group(b.scene, "walls", 8, &g), PLM_OK);
    ASSERT_EQ(plm_scene_set_mesh_ol_group(b.scene, mesh, g), PLM_OK);
    ASSERT_EQ(plm_scene_set_ol_group_backup(b.scene, g, backup), PLM_OK);
    plm_bake_settings s = settings(200000, 16);
    s.filter_radius = 0;
    Baked r;
    bake(b, s, r);
    if (!backup) {  // without backup the OL resolves the lightmap; compare against plain texels
      SceneBuilder b2;
      const uint32_t m2 = b2.material("furnace", {rho, rho, rho}, {1, 1, 1});
      const uint32_t mesh2 = b2.box("furnace", {0, 0, 0}, {2, 2, 2}, 0.0f, m2, 16, true);
      Baked r2;
      plm_bake_settings photons_only = s;
      photons_only.max_bounces = 63;  // no final gather (OL meshes have none): the photons' noise alone
      bake(b2, photons_only, r2);
      const plm_test::Map lm = r2.map(mesh2);
      double sq = 0.0, zz = 0.0, n = 0.0;
      for (size_t t = 0; t < lm.coverage.size(); ++t) {
        if (lm.coverage[t] < 0.999f) continue;
        sq += (lm.value(t) - exact) * (lm.value(t) - exact);
        zz += (lm.value(t) - exact) * (lm.value(t) - exact) / (double(lm.error[t]) * lm.error[t]);
        n += 1.0;
      }
      err[0] = std::sqrt(sq / n) / exact;
      z2[0] = zz / n;
      continue;
    }
    EXPECT_GT(r.stats().direct_samples, 0u) << "a backed-up mesh keeps its direct pass";
    const plm_test::Map lm = r.map(mesh);
    double sq = 0.0, zz = 0.0, n = 0.0;
    for (size_t t = 0; t < lm.coverage.size(); ++t) {
      if (lm.coverage[t] < 0.999f) continue;
      sq += (lm.value(t) - exact) * (lm.value(t) - exact);
      zz += (lm.value(t) - exact) * (lm.value(t) - exact) / (double(lm.error[t]) * lm.error[t]);
      n += 1.0;
    }
    err[1] = std::sqrt(sq / n) / exact;
    z2[1] = zz / n;
  }
  std::printf("[ measured ] furnace texels: plain %.2f %% (z^2 %.2f), with a backup OL %.2f %% (z^2 %.2f)\n",
              100 * err[0], z2[0], 100 * err[1], z2[1]);
  EXPECT_LT(err[1], 0.7 * err[0]);
  EXPECT_GT(z2[1], 0.3);
  EXPECT_LT(z2[1], 2.0);
}

// Over a Cornell box, where one normal sees very different light (walls of
// two colours, floor and box tops), the bias estimate keeps the backup from
// blurring: against a converged reference the backed-up bake is no worse than
// the plain one at the same photons.
TEST(OlBake, BackupOlDoesNotWashOutTheCornellBox) {
  auto run = [](bool backup, uint64_t photons, uint32_t seed, std::vector<plm_test::Map>* maps, Baked& r) {
    SceneBuilder b;
    plm_demo::build_cornell(b, 16);
    uint32_t g = 0;
    ASSERT_EQ(plm_scene_add_ol_group(b.scene, "room", 16, &g), PLM_OK);
    std::vector<uint32_t> meshes;
    for (uint32_t i = 0; i < 7; ++i) meshes.push_back(i);
    if (backup) {
      for (uint32_t i : meshes) ASSERT_EQ(plm_scene_set_mesh_ol_group(b.scene, i, g), PLM_OK) << plm_last_error();
      ASSERT_EQ(plm_scene_set_ol_group_backup(b.scene, g, 1), PLM_OK);
    }
    plm_bake_settings s = settings(photons, 32);
    s.seed = seed;
    bake(b, s, r);
    if (maps)
      for (uint32_t i : meshes) maps->push_back(r.map(i));
  };
  std::vector<plm_test::Map> ref;
  Baked rr;
  run(false, 8000000, 11, &ref, rr);
  const std::vector<uint32_t> meshes = {0, 1, 2, 3, 4, 5, 6};
  Baked plain, backed;
  run(false, 300000, 3, nullptr, plain);  // the same photons: the difference is the blend alone
  run(true, 300000, 3, nullptr, backed);
  const double e_plain = rmse_against(plain, meshes, ref), e_backup = rmse_against(backed, meshes, ref);
  std::printf("[ measured ] Cornell box at 300k photons: plain %.2f %%, with a backup OL %.2f %%\n", 100 * e_plain,
              100 * e_backup);
  EXPECT_LT(e_backup, 1.05 * e_plain);
}

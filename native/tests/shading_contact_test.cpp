// Smooth shading (shading normals) and faces in contact, checked against
// analytic answers and Cycles' conventions (docs/design/texels.md, "Shading
// normals", "Faces in contact"): a smooth-shaded face is lit with its
// interpolated normal, light from below the triangle's own plane does not
// count, and a face pressed flat against another gets no light.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "demo_scenes.h"
#include "test_support.h"

namespace {

using plm_demo::SceneBuilder;
using plm_demo::V3;
using plm_test::bake;
using Map = plm_test::Map;
using Baked = plm_test::BakeResult;

plm_bake_settings settings(uint64_t photons, uint32_t max_bounces, uint32_t direct_samples) {
  return plm_test::settings_with(photons, direct_samples, max_bounces);
}

// A sun of strength `power` whose light travels along (0, sin a, -cos a).
plm_light sun(float power, float a) {
  plm_light l = plm_test::tilted_sun(power, a);
  l.angle = 0.0f;
  return l;
}

// Sets the corner normals of the unit quad (0..1)^2 at z = 0 built by
// SceneBuilder::quad with n = 1 (triangles {00, 10, 11} and {00, 11, 01}) to
// normal(x, y) at each corner.
template <typename F>
void set_quad_normals(SceneBuilder& b, uint32_t mesh, F&& normal) {
  const float corners[6][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 0}, {1, 1}, {0, 1}};
  std::vector<float> n;
  for (const auto& c : corners) {
    const V3 v = normal(c[0], c[1]);
    n.insert(n.end(), {v.x, v.y, v.z});
  }
  ASSERT_EQ(plm_scene_set_mesh_normals(b.scene, mesh, n.data()), PLM_OK) << plm_last_error();
}

// A face whose shading normal is tilted by alpha from its geometric normal,
// under a uniform sky of radiance 1: it receives light only from the half
// space above its own plane, weighted by the cosine about the shading normal:
// E / pi = (1 + cos alpha) / 2 (a plane tilted by alpha under a sky that
// ends at the horizon). Without shading normals: 1.
void tilted_normal_under_sky(double degrees, uint64_t photons, uint32_t direct_samples, double tolerance) {
  const double alpha = degrees * M_PI / 180.0;
  SceneBuilder b;
  b.material("grey", {0.5f, 0.5f, 0.5f});
  const uint32_t q = b.quad("tilted", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 0, 8);
  set_quad_normals(b, q, [&](float, float) { return V3{0.0f, float(std::sin(alpha)), float(std::cos(alpha))}; });
  const float world[3] = {1, 1, 1};
  ASSERT_EQ(plm_scene_set_world(b.scene, world), PLM_OK);
  Baked r;
  bake(b, settings(photons, 0, direct_samples), r);
  const Map m = r.map(q);
  const double exact = 0.5 * (1.0 + std::cos(alpha));
  double sum = 0.0;
  int n = 0;
  for (size_t t = 0; t < m.coverage.size(); ++t) {
    if (m.coverage[t] <= 0.0f) continue;
    EXPECT_NEAR(m.value(t), exact, 4.0 * tolerance * exact) << "texel " << t;
    sum += m.value(t), ++n;
  }
  EXPECT_NEAR(sum / n, exact, tolerance * exact);
}

TEST(Shading, TiltedNormalUnderSkyDirectPass) { tilted_normal_under_sky(60.0, 1000, 256, 0.01); }
// Photons weigh cos(shading) / cos(geometric) up to kMaxShadingRatio (16):
// 0.45 % of the light lost at 30 degrees.
TEST(Shading, TiltedNormalUnderSkyPhotons) { tilted_normal_under_sky(30.0, 4000000, 0, 0.015); }

// Normals that turn across the quad, from -beta (x = 0) to +beta (x = 1)
// about the y axis, under a sun 40 degrees from the zenith towards +x: each
// texel holds S max(0, n(x) . L) / pi with n(x) the normalised linear
// interpolation of the corner normals. With the sun below the quad's plane,
// although half the quad's shading normals face it: 0 (Cycles' test on the
// geometric normal).
void turning_normals_under_sun(uint64_t photons, uint32_t direct_samples, double tolerance) {
  const double beta = 0.5;
  auto normal = [&](float x, float) {
    const double a = -beta + 2.0 * beta * x;
    return V3{float(std::sin(a)), 0.0f, float(std::cos(a))};
  };
  for (const double zenith : {40.0, 100.0}) {
    SceneBuilder b;
    b.material("grey", {0.5f, 0.5f, 0.5f});
    const uint32_t q = b.quad("turning", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 0, 8);
    set_quad_normals(b, q, normal);
    // The sun's light travels along (sin z, 0, -cos z) rotated into the x-z plane: a sun frame turned about y.
    plm_light l;
    plm_light_default(&l, PLM_LIGHT_SUN);
    l.power = 2.0f;
    l.angle = 0.0f;
    const double z = zenith * M_PI / 180.0;
    l.matrix[0] = float(std::cos(z)), l.matrix[2] = float(-std::sin(z));
    l.matrix[8] = float(std::sin(z)), l.matrix[10] = float(std::cos(z));
    b.light(l, "sun");
    // The texel's whole area (Cycles' central square folds points across the quad's diagonal).
    plm_bake_settings s = settings(photons, 0, direct_samples);
    s.texel_value = PLM_TEXEL_AREA;
    Baked r;
    bake(b, s, r);
    const Map m = r.map(q);
    const double Lx = -std::sin(z), Lz = std::cos(z);  // towards the sun
    for (uint32_t j = 0; j < m.h; ++j) {
      for (uint32_t i = 0; i < m.w; ++i) {
        const size_t t = size_t(j) * m.w + i;
        const double x = (i + 0.5) / m.w;
        // Normalised linear interpolation of the corner normals at x.
        const double nx = (1 - x) * std::sin(-beta) + x * std::sin(beta), nz = std::cos(beta);
        const double cos_s = (nx * Lx + nz * Lz) / std::sqrt(nx * nx + nz * nz);
        const double exact = Lz > 0.0 ? 2.0 * std::max(0.0, cos_s) / M_PI : 0.0;
        EXPECT_NEAR(m.value(t), exact, tolerance * 2.0 / M_PI) << "zenith " << zenith << " texel " << i << ", " << j;
      }
    }
  }
}

TEST(Shading, TurningNormalsUnderSunDirectPass) { turning_normals_under_sun(1000, 16, 0.01); }
TEST(Shading, TurningNormalsUnderSunPhotons) { turning_normals_under_sun(2000000, 0, 0.04); }

// Normals equal to the geometric ones leave the mesh flat: the same lightmap
// bit for bit as without normals; a zero normal shades with the geometric one.
TEST(Shading, GeometricNormalsChangeNothing) {
  std::vector<float> values[3];
  for (int mode = 0; mode < 3; ++mode) {
    SceneBuilder b;
    b.material("grey", {0.5f, 0.5f, 0.5f});
    const uint32_t q = b.quad("flat", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 0, 8);
    if (mode == 1) set_quad_normals(b, q, [](float, float) { return V3{0, 0, 3}; });
    if (mode == 2) set_quad_normals(b, q, [](float, float) { return V3{0, 0, 0}; });
    b.light(sun(2.0f, 0.4f), "sun");
    Baked r;
    bake(b, settings(20000, 0, 16), r);
    values[mode] = r.map(q).rgb;
  }
  EXPECT_EQ(values[0], values[1]);
  EXPECT_EQ(values[0], values[2]);
}

// A UV sphere (radius 1, 32 segments, 16 rings; latitude-longitude lightmap
// UVs) under a sun: shaded smooth (normals from plm_scene_set_mesh_smooth),
// each texel is near S max(0, n . L) / pi with n the true sphere normal at
// the texel's centre (away from the terminator); flat, its facets are far from it.
double sphere_under_sun_error(bool smooth) {
  constexpr uint32_t kSeg = 32, kRings = 16, kRes = 64;
  std::vector<float> pos, uv;
  std::vector<uint32_t> idx;
  auto vertex = [&](uint32_t i, uint32_t j) { return j * (kSeg + 1) + i; };
  for (uint32_t j = 0; j <= kRings; ++j)
    for (uint32_t i = 0; i <= kSeg; ++i) {
      const double th = M_PI * j / kRings, ph = 2.0 * M_PI * i / kSeg;
      pos.insert(pos.end(), {float(std::sin(th) * std::cos(ph)), float(std::sin(th) * std::sin(ph)),
                             float(std::cos(th))});
    }
  // Texel-aligned UV cells (2 x 4 texels): u = i / kSeg, v = j / kRings.
  auto corner_uv = [&](uint32_t i, uint32_t j, float di, float dj) {
    uv.insert(uv.end(), {(float(i) + di) / kSeg, (float(j) + dj) / kRings});
  };
  for (uint32_t j = 0; j < kRings; ++j)
    for (uint32_t i = 0; i < kSeg; ++i) {
      const uint32_t a = vertex(i, j), b = vertex(i + 1, j), c = vertex(i + 1, j + 1), d = vertex(i, j + 1);
      idx.insert(idx.end(), {a, d, c, a, c, b});  // outward
      corner_uv(i, j, 0, 0), corner_uv(i, j, 0, 1), corner_uv(i, j, 1, 1);
      corner_uv(i, j, 0, 0), corner_uv(i, j, 1, 1), corner_uv(i, j, 1, 0);
    }
  SceneBuilder b;
  b.material("grey", {0.0f, 0.0f, 0.0f});  // no bounce light: the sun alone
  uint32_t id = 0;
  EXPECT_EQ(plm_scene_add_mesh(b.scene, "sphere", pos.data(), uint32_t(pos.size() / 3), idx.data(),
                               uint32_t(idx.size() / 3), uv.data(), nullptr, kRes, kRes, &id),
            PLM_OK);
  if (smooth) {
    EXPECT_EQ(plm_scene_set_mesh_smooth(b.scene, id, 1), PLM_OK);
  }
  const float a = 0.7f;  // the sun travels along (0, sin a, -cos a)
  b.light(sun(3.0f, a), "sun");
  plm_bake_settings s = settings(1000, 0, 64);
  s.texel_value = PLM_TEXEL_AREA;
  Baked r;
  bake(b, s, r);
  const Map m = r.map(id);
  double sq = 0.0, sum = 0.0;
  int n = 0;
  for (uint32_t tv = 0; tv < m.h; ++tv)
    for (uint32_t tu = 0; tu < m.w; ++tu) {
      const size_t t = size_t(tv) * m.w + tu;
      if (m.coverage[t] < 1.0f) continue;  // whole texels inside a cell
      const double th = M_PI * (tv + 0.5) / kRes, ph = 2.0 * M_PI * (tu + 0.5) / kRes;
      const double ny = std::sin(th) * std::sin(ph), nz = std::cos(th);
      const double cos_l = -(ny * std::sin(a) - nz * std::cos(a));
      // Within about a facet of the terminator Cycles' test on the geometric
      // normal darkens what the true normal would light: left out.
      if (std::fabs(cos_l) < 0.2) continue;
      const double exact = 3.0 * std::max(0.0, cos_l) / M_PI;
      sq += (m.value(t) - exact) * (m.value(t) - exact), sum += exact, ++n;
    }
  return std::sqrt(sq / n) / (sum / n);
}

TEST(Shading, SmoothSphereFollowsTheTrueNormal) {
  const double smooth = sphere_under_sun_error(true), flat = sphere_under_sun_error(false);
  std::printf("[ measured ] sphere under the sun, relative RMS error against the true normal: smooth %.4f, flat %.4f\n",
              smooth, flat);
  EXPECT_LT(smooth, 0.02);
  EXPECT_GT(flat, 3.0 * smooth);
}

TEST(Shading, BadNormalsAreRejected) {
  SceneBuilder b;
  b.material("grey", {0.5f, 0.5f, 0.5f});
  const uint32_t q = b.quad("quad", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 0, 8);
  std::vector<float> n(18, 0.0f);
  n[13] = std::nanf("");
  EXPECT_EQ(plm_scene_set_mesh_normals(b.scene, q, n.data()), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("mesh 'quad' (0): triangle 1 corner 1"), std::string::npos)
      << plm_last_error();
  EXPECT_EQ(plm_scene_set_mesh_normals(b.scene, 7, n.data()), PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(plm_scene_set_mesh_normals(nullptr, q, n.data()), PLM_ERROR_INVALID_ARGUMENT);
}

// ---- faces in contact ------------------------------------------------------

// A 4 x 4 m floor (lightmap 16 x 16) and a 1 m box on it at height `lift`
// (0: standing on it), lit by a sun and a sky of radiance 1 that is also below
// the horizon (Cycles' world). Returns the box's bottom face texels and the
// floor texels that lie wholly under the box.
struct Contact {
  std::vector<double> bottom, floor_under;
};

Contact box_on_floor(float lift, bool photons_only = false) {
  SceneBuilder b;
  const uint32_t white = b.material("white", {0.8f, 0.8f, 0.8f});
  const uint32_t floor = b.quad("floor", {-2, -2, 0}, {4, 0, 0}, {0, 4, 0}, white, 16);
  const uint32_t box = b.box("box", {0, 0, 0.5f + lift}, {1, 1, 1}, 0.0f, white, 8);
  b.light(sun(3.0f, 0.5f), "sun");
  const float world[3] = {1, 1, 1};
  EXPECT_EQ(plm_scene_set_world(b.scene, world), PLM_OK);
  Baked r;
  plm_bake_settings s = photons_only ? settings(400000, 1024, 0) : settings(200000, 1024, 16);
  if (photons_only) s.filter_radius = 0;  // each texel its own photons
  bake(b, s, r);
  Contact c;
  if (!r.r) return c;
  const Map f = r.map(floor), m = r.map(box);
  // The box's bottom face (-z) is atlas cell (1, 0) of its 3 x 2 atlas.
  for (uint32_t j = 0; j < m.h / 2; ++j)
    for (uint32_t i = m.w / 3; i < 2 * m.w / 3; ++i)
      if (m.coverage[size_t(j) * m.w + i] > 0.0f) c.bottom.push_back(m.value(size_t(j) * m.w + i));
  // Floor texels (0.25 m) wholly inside [-0.5, 0.5]^2: i, j in 6..9.
  for (uint32_t j = 6; j < 10; ++j)
    for (uint32_t i = 6; i < 10; ++i) c.floor_under.push_back(f.value(size_t(j) * f.w + i));
  return c;
}

TEST(Contact, BoxStandingOnFloorTouchesItBlack) {
  const Contact c = box_on_floor(0.0f);
  ASSERT_FALSE(c.bottom.empty());
  for (double v : c.bottom) EXPECT_EQ(v, 0.0) << "the bottom of a box standing on the floor";
  for (double v : c.floor_under) EXPECT_EQ(v, 0.0) << "the floor under a box";
}

// Photons alone: no photon reaches a face pressed against another (the
// photon pass needs no contact test of its own).
TEST(Contact, PhotonsDoNotReachFacesInContact) {
  const Contact c = box_on_floor(0.0f, true);
  ASSERT_FALSE(c.bottom.empty());
  for (double v : c.bottom) EXPECT_EQ(v, 0.0);
  for (double v : c.floor_under) EXPECT_EQ(v, 0.0);
}

// 1 mm above the floor the box's bottom is not in contact: it sees the sky
// under the box's rim and the lit floor around it through the gap (about
// 0.008; a face in contact gets exactly 0). Photons alone: the light through
// a 1 mm gap is a few grazing paths, which the two-pass estimate at 200 k
// photons reports with an error of several times the value.
TEST(Contact, BoxJustAboveTheFloorIsNotInContact) {
  const Contact c = box_on_floor(1e-3f, true);
  ASSERT_FALSE(c.bottom.empty());
  double mean = 0.0;
  for (double v : c.bottom) mean += v / double(c.bottom.size());
  std::printf("[ measured ] bottom of a box 1 mm above the floor: mean %.5f\n", mean);
  EXPECT_GT(mean, 0.003);
}

// A column whose top touches a ceiling that faces down gets no light, as in
// Cycles; 1 cm lower it gets the light the ceiling reflects.
TEST(Contact, ColumnTopTouchingTheCeilingIsBlack) {
  for (const float gap : {0.0f, 0.01f}) {
    SceneBuilder b;
    const uint32_t white = b.material("white", {0.8f, 0.8f, 0.8f});
    b.quad("floor", {-2, -2, 0}, {4, 0, 0}, {0, 4, 0}, white, 8);
    b.quad("ceiling", {-2, -2, 2}, {0, 4, 0}, {4, 0, 0}, white, 8);
    const uint32_t column = b.box("column", {0, 0, 1.0f - 0.5f * gap}, {0.5f, 0.5f, 2.0f - gap}, 0.0f, white, 8);
    b.light(sun(3.0f, 1.2f), "sun");
    const float world[3] = {1, 1, 1};
    ASSERT_EQ(plm_scene_set_world(b.scene, world), PLM_OK);
    Baked r;
    bake(b, settings(200000, 1024, 16), r);
    const Map m = r.map(column);
    double mean = 0.0;
    int n = 0;
    // The top face (+z) is atlas cell (0, 0).
    for (uint32_t j = 0; j < m.h / 2; ++j)
      for (uint32_t i = 0; i < m.w / 3; ++i)
        if (m.coverage[size_t(j) * m.w + i] > 0.0f) mean += m.value(size_t(j) * m.w + i), ++n;
    ASSERT_GT(n, 0);
    mean /= n;
    if (gap == 0.0f) {
      EXPECT_EQ(mean, 0.0);
    } else {
      EXPECT_GT(mean, 0.001);
    }
  }
}

// Two faces in one plane facing the same way (an object duplicated in
// place): neither is in contact, both are lit like one face alone.
TEST(Contact, DuplicatedFacesAreBothLit) {
  SceneBuilder b;
  const uint32_t black = b.material("black", {0, 0, 0});
  const uint32_t q0 = b.quad("quad", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, black, 4);
  const uint32_t q1 = b.quad("quad copy", {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, black, 4);
  b.light(sun(3.0f, 0.5f), "sun");
  Baked r;
  bake(b, settings(1000, 0, 16), r);
  const double exact = 3.0 * std::cos(0.5) / M_PI;
  for (const uint32_t q : {q0, q1}) {
    const Map m = r.map(q);
    for (size_t t = 0; t < m.coverage.size(); ++t) {
      EXPECT_NEAR(m.value(t), exact, 1e-4) << "mesh " << q << " texel " << t;
    }
  }
}

// A sheet lying 0.1 mm above the floor, facing up like it, is not in contact:
// it is lit like the open floor (sun at 0.5 rad: 3 cos(0.5) / pi, plus the
// sky's upper half, 1).
TEST(Contact, SheetLyingOnTheFloorIsLit) {
  SceneBuilder b;
  const uint32_t black = b.material("black", {0, 0, 0});
  b.quad("floor", {-2, -2, 0}, {4, 0, 0}, {0, 4, 0}, black, 8);
  const uint32_t sheet = b.quad("sheet", {-0.5f, -0.5f, 1e-4f}, {1, 0, 0}, {0, 1, 0}, black, 8);
  b.light(sun(3.0f, 0.5f), "sun");
  const float world[3] = {1, 1, 1};
  ASSERT_EQ(plm_scene_set_world(b.scene, world), PLM_OK);
  Baked r;
  bake(b, settings(1000, 0, 64), r);
  const Map m = r.map(sheet);
  const double exact = 3.0 * std::cos(0.5) / M_PI + 1.0;
  for (size_t t = 0; t < m.coverage.size(); ++t) {
    if (m.coverage[t] > 0.0f) {
      EXPECT_NEAR(m.value(t), exact, 0.03 * exact) << "texel " << t;
    }
  }
}

// A ball resting on the floor touches it at one point: the triangles at its
// pole, tilted away from the floor, are not pressed flat against it, so the
// floor under it is not marked as in contact and the ball's lower half keeps
// its final gather (whose rays look up the floor right under it). Its
// reported error is then that of the same ball lifted 2 cm (no contact at
// all), not the photons' alone.
double ball_lower_half_error(float lift) {
  constexpr uint32_t kSeg = 48, kRings = 24, kRes = 32;
  const float radius = 0.5f;
  std::vector<float> pos, uv;
  std::vector<uint32_t> idx;
  auto vertex = [&](uint32_t i, uint32_t j) { return j * (kSeg + 1) + i; };
  for (uint32_t j = 0; j <= kRings; ++j)
    for (uint32_t i = 0; i <= kSeg; ++i) {
      const double th = M_PI * j / kRings, ph = 2.0 * M_PI * i / kSeg;
      pos.insert(pos.end(), {float(radius * std::sin(th) * std::cos(ph)), float(radius * std::sin(th) * std::sin(ph)),
                             float(radius + lift + radius * std::cos(th))});
    }
  auto corner_uv = [&](uint32_t i, uint32_t j, float di, float dj) {
    uv.insert(uv.end(), {(float(i) + di) / kSeg, (float(j) + dj) / kRings});
  };
  for (uint32_t j = 0; j < kRings; ++j)
    for (uint32_t i = 0; i < kSeg; ++i) {
      const uint32_t a = vertex(i, j), b = vertex(i + 1, j), c = vertex(i + 1, j + 1), d = vertex(i, j + 1);
      idx.insert(idx.end(), {a, d, c, a, c, b});  // outward
      corner_uv(i, j, 0, 0), corner_uv(i, j, 0, 1), corner_uv(i, j, 1, 1);
      corner_uv(i, j, 0, 0), corner_uv(i, j, 1, 1), corner_uv(i, j, 1, 0);
    }
  SceneBuilder b;
  const uint32_t white = b.material("white", {0.8f, 0.8f, 0.8f});
  b.quad("floor", {-2, -2, 0}, {4, 0, 0}, {0, 4, 0}, white, 8);
  uint32_t ball = 0;
  EXPECT_EQ(plm_scene_add_mesh(b.scene, "ball", pos.data(), uint32_t(pos.size() / 3), idx.data(),
                               uint32_t(idx.size() / 3), uv.data(), nullptr, kRes, kRes, &ball),
            PLM_OK);
  b.light(sun(3.0f, 0.5f), "sun");
  const float world[3] = {0.3f, 0.4f, 0.6f};
  EXPECT_EQ(plm_scene_set_world(b.scene, world), PLM_OK);
  Baked r;
  bake(b, settings(100000, 1024, 16), r);
  if (!r.r) return 0.0;
  const Map m = r.map(ball);
  double sq = 0.0, sum = 0.0;
  for (uint32_t tv = kRes / 2 + 1; tv < kRes - 1; ++tv)  // v = j / kRings: the lower half, without the pole row
    for (uint32_t tu = 0; tu < kRes; ++tu) {
      const size_t t = size_t(tv) * m.w + tu;
      if (m.coverage[t] < 1.0f) continue;
      sq += double(m.error[t]) * m.error[t];
      sum += m.value(t);
    }
  return sum > 0.0 ? std::sqrt(sq) / sum : 0.0;
}

TEST(Contact, BallRestingOnTheFloorKeepsItsGather) {
  const double resting = ball_lower_half_error(0.0f), lifted = ball_lower_half_error(0.02f);
  std::printf("[ measured ] ball's lower half, reported error (relative, summed): resting %.5f, lifted 2 cm %.5f\n",
              resting, lifted);
  ASSERT_GT(lifted, 0.0);
  EXPECT_LT(resting, 1.5 * lifted);
}

}  // namespace

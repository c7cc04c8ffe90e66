// OpenSubdiv refinement of polygon cages (native/src/subdiv) against values
// known in closed form, and the C API's validation of cages.
#include "subdiv/subdiv.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "io/scene_file.h"
#include "photonlm/photonlm.h"
#include "test_support.h"
#include "util/error.h"

namespace plm::subdiv {
namespace {

// The cube [-1, 1]^3 as Blender's default cube: 8 vertices, 6 quads.
struct CubeCage {
  std::vector<float> p = {1, 1, 1, 1, 1, -1, 1, -1, 1, 1, -1, -1, -1, 1, 1, -1, 1, -1, -1, -1, 1, -1, -1, -1};
  std::vector<uint32_t> sizes = {4, 4, 4, 4, 4, 4};
  // +z, -y, -x, -z, +x, +y (outward winding)
  std::vector<uint32_t> idx = {0, 4, 6, 2, 3, 2, 6, 7, 7, 6, 4, 5, 5, 1, 3, 7, 1, 0, 2, 3, 5, 4, 0, 1};
  Cage cage(uint32_t level) const {
    Cage c;
    c.positions = p.data();
    c.vertex_count = 8;
    c.face_sizes = sizes.data();
    c.face_count = 6;
    c.face_indices = idx.data();
    c.level = level;
    return c;
  }
};

// The Catmull-Clark limit of the cube: corners go to (+-1/2)^3 (limit mask
// (n^2 v + 4 sum e + sum f) / (n (n + 5)) with n = 3) and face centres to
// 68/81 (the same mask with n = 4 on the level-1 mesh).
TEST(Subdiv, CubeLimitPointsMatchClosedForm) {
  const CubeCage cube;
  for (uint32_t level = 1; level <= 3; ++level) {
    const RefinedMesh m = refine("cube", cube.cage(level));
    const uint32_t n = 1u << level;
    EXPECT_EQ(m.triangle_count(), 2u * 24u * (1u << (2 * (level - 1))));
    EXPECT_EQ(m.vertex_count(), 6u * (n - 1) * (n - 1) + 12u * (n - 1) + 8u);
    int corners = 0, centres = 0;
    for (uint32_t v = 0; v < m.vertex_count(); ++v) {
      const float x = m.positions[3 * v], y = m.positions[3 * v + 1], z = m.positions[3 * v + 2];
      if (std::fabs(std::fabs(x) - 0.5f) < 1e-6f && std::fabs(std::fabs(y) - 0.5f) < 1e-6f &&
          std::fabs(std::fabs(z) - 0.5f) < 1e-6f)
        ++corners;
      const float a[3] = {std::fabs(x), std::fabs(y), std::fabs(z)};
      std::vector<float> s(a, a + 3);
      std::sort(s.begin(), s.end());
      if (s[0] < 1e-7f && s[1] < 1e-7f && std::fabs(s[2] - 68.0f / 81.0f) < 1e-6f) ++centres;
      // The limit surface of the cube lies inside the cage and outside the corner limit points' sphere.
      EXPECT_LE(std::max({a[0], a[1], a[2]}), 1.0f);
      EXPECT_GE(std::sqrt(x * x + y * y + z * z), 0.8f);
    }
    EXPECT_EQ(corners, 8) << "level " << level;
    EXPECT_EQ(centres, 6) << "level " << level;
  }
}

// An infinitely sharp crease loop (Blender crease 1 = sharpness 10) around the
// top face keeps that face exactly flat at z = 1 (every rule that touches it
// averages points of the plane), while the smooth cube never reaches z = 1.
TEST(Subdiv, SharpCreaseLoopKeepsTopFaceFlat) {
  const CubeCage cube;
  const std::vector<uint32_t> edges = {0, 4, 4, 6, 6, 2, 2, 0};
  const std::vector<float> weights = {1, 1, 1, 1};
  for (uint32_t level = 1; level <= 3; ++level) {
    Cage c = cube.cage(level);
    const RefinedMesh smooth = refine("cube", c);
    float smooth_max = -1;
    for (uint32_t v = 0; v < smooth.vertex_count(); ++v) smooth_max = std::max(smooth_max, smooth.positions[3 * v + 2]);
    EXPECT_NEAR(smooth_max, 68.0f / 81.0f, 1e-6f);

    c.crease_edges = edges.data();
    c.crease_weights = weights.data();
    c.crease_count = 4;
    const RefinedMesh m = refine("cube", c);
    const uint32_t n = (1u << level) + 1;
    uint32_t on_top = 0;
    float zmax = -1;
    for (uint32_t v = 0; v < m.vertex_count(); ++v) {
      zmax = std::max(zmax, m.positions[3 * v + 2]);
      if (std::fabs(m.positions[3 * v + 2] - 1.0f) < 1e-6f) ++on_top;
    }
    EXPECT_NEAR(zmax, 1.0f, 1e-6f);
    EXPECT_EQ(on_top, n * n) << "level " << level;
    // Vertex 0 (the corner (1, 1, 1), kept first by Far) goes to the crease
    // limit (e_prev + 4 v + e_next) / 6 = (2/3, 2/3, 1); smooth, to (1/2)^3.
    EXPECT_NEAR(m.positions[0], 2.0f / 3.0f, 1e-6f);
    EXPECT_NEAR(m.positions[1], 2.0f / 3.0f, 1e-6f);
    EXPECT_NEAR(m.positions[2], 1.0f, 1e-6f);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(smooth.positions[k], 0.5f, 1e-6f);
    // A half crease (sharpness 10 * 0.5^2 = 2.5) pulls the corner up, less than a full one.
    const std::vector<float> half = {0.5f, 0.5f, 0.5f, 0.5f};
    c.crease_weights = half.data();
    const RefinedMesh h = refine("cube", c);
    EXPECT_GT(h.positions[2], 0.55f);
    EXPECT_LE(h.positions[2], 1.0f + 1e-6f);
  }
}

// A flat 4 x 4 grid with UV = (x, y) / 4: Catmull-Clark reproduces linear
// data in the interior and PRESERVE_BOUNDARIES keeps the UV boundary linear,
// so the refined UVs are exactly the uniform lattice k / (4 2^L), while the
// positions' boundary corners are rounded (boundary smooth ALL).
TEST(Subdiv, LinearUvOnGridIsReproducedExactly) {
  const uint32_t g = 4;
  std::vector<float> p;
  for (uint32_t j = 0; j <= g; ++j)
    for (uint32_t i = 0; i <= g; ++i) p.insert(p.end(), {float(i), float(j), 0.0f});
  std::vector<uint32_t> sizes(g * g, 4), idx;
  std::vector<float> uv;
  for (uint32_t j = 0; j < g; ++j)
    for (uint32_t i = 0; i < g; ++i) {
      const uint32_t q[4] = {j * (g + 1) + i, j * (g + 1) + i + 1, (j + 1) * (g + 1) + i + 1, (j + 1) * (g + 1) + i};
      for (uint32_t k : q) {
        idx.push_back(k);
        uv.push_back(p[3 * k] / g);
        uv.push_back(p[3 * k + 1] / g);
      }
    }
  for (uint32_t level = 1; level <= 3; ++level) {
    Cage c;
    c.positions = p.data();
    c.vertex_count = uint32_t(p.size() / 3);
    c.face_sizes = sizes.data();
    c.face_count = g * g;
    c.face_indices = idx.data();
    c.uv = uv.data();
    c.level = level;
    const RefinedMesh m = refine("grid", c);
    const double steps = double(g << level);
    std::set<std::pair<int, int>> lattice;
    ASSERT_EQ(m.uv.size(), size_t(m.triangle_count()) * 6);
    for (size_t k = 0; k < m.uv.size(); k += 2) {
      const double a = m.uv[k] * steps, b = m.uv[k + 1] * steps;
      ASSERT_NEAR(a, std::round(a), 1e-4) << "level " << level;
      ASSERT_NEAR(b, std::round(b), 1e-4) << "level " << level;
      lattice.insert({int(std::lround(a)), int(std::lround(b))});
    }
    EXPECT_EQ(lattice.size(), size_t((steps + 1) * (steps + 1)));
    float xmin = 1e9f;
    for (uint32_t v = 0; v < m.vertex_count(); ++v) {
      EXPECT_EQ(m.positions[3 * v + 2], 0.0f);
      xmin = std::min(xmin, m.positions[3 * v]);
    }
    EXPECT_NEAR(xmin, 0.0f, 1e-6f);  // the straight boundary stays put
    // The corner vertex (0, 0) is smoothed by the boundary B-spline to (1/6, 1/6)... but not beyond.
    bool corner_moved = true;
    for (uint32_t v = 0; v < m.vertex_count(); ++v)
      if (std::fabs(m.positions[3 * v]) < 1e-6f && std::fabs(m.positions[3 * v + 1]) < 1e-6f) corner_moved = false;
    EXPECT_TRUE(corner_moved) << "boundary smooth ALL rounds the corners";
  }
}

TEST(Subdiv, UvSeamsStayApart) {
  // Two quads sharing an edge, each its own UV island: the shared edge is a
  // seam, so no refined UV of one island lands in the other's.
  const std::vector<float> p = {0, 0, 0, 1, 0, 0, 2, 0, 0, 0, 1, 0, 1, 1, 0, 2, 1, 0};
  const std::vector<uint32_t> sizes = {4, 4}, idx = {0, 1, 4, 3, 1, 2, 5, 4};
  const std::vector<float> uv = {0.0f, 0.0f, 0.4f, 0.0f, 0.4f, 0.4f, 0.0f, 0.4f,
                                 0.6f, 0.6f, 1.0f, 0.6f, 1.0f, 1.0f, 0.6f, 1.0f};
  Cage c;
  c.positions = p.data();
  c.vertex_count = 6;
  c.face_sizes = sizes.data();
  c.face_count = 2;
  c.face_indices = idx.data();
  c.uv = uv.data();
  c.level = 2;
  const RefinedMesh m = refine("seam", c);
  for (size_t k = 0; k < m.uv.size(); k += 2) {
    const bool first = m.uv[k] <= 0.4f + 1e-6f && m.uv[k + 1] <= 0.4f + 1e-6f && m.uv[k] >= -1e-6f;
    const bool second = m.uv[k] >= 0.6f - 1e-6f && m.uv[k + 1] >= 0.6f - 1e-6f && m.uv[k] <= 1.0f + 1e-6f;
    EXPECT_TRUE(first || second) << m.uv[k] << ", " << m.uv[k + 1];
  }
}

TEST(Subdiv, MaterialIdsFollowTheirCageFace) {
  const CubeCage cube;
  const std::vector<uint32_t> ids = {0, 1, 2, 3, 4, 5};
  const int axis[6] = {2, 1, 0, 2, 0, 1};
  const float sign[6] = {1, -1, -1, -1, 1, 1};
  Cage c = cube.cage(2);
  c.material_ids = ids.data();
  const RefinedMesh m = refine("cube", c);
  ASSERT_EQ(m.material_ids.size(), m.triangle_count());
  for (uint32_t t = 0; t < m.triangle_count(); ++t) {
    const uint32_t f = m.material_ids[t];
    ASSERT_LT(f, 6u);
    float centroid = 0;
    for (int j = 0; j < 3; ++j) centroid += m.positions[3 * m.indices[3 * t + j] + axis[f]] / 3;
    EXPECT_GT(centroid * sign[f], 0.3f) << "triangle " << t << " material " << f;
  }
}

TEST(Subdiv, NonManifoldCagesDoNotCrash) {
  // Three quads on one edge (0-1) plus a triangle touching at a single vertex.
  const std::vector<float> p = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 1, 0, 1, 0, 0, 1,
                                1, -1, 0, 0, -1, 0, 2, 1, 1, 2, 2, 1};
  const std::vector<uint32_t> sizes = {4, 4, 4, 3};
  const std::vector<uint32_t> idx = {0, 1, 2, 3, 1, 0, 5, 4, 1, 0, 7, 6, 2, 8, 9};
  Cage c;
  c.positions = p.data();
  c.vertex_count = 10;
  c.face_sizes = sizes.data();
  c.face_count = 4;
  c.face_indices = idx.data();
  c.level = 2;
  try {
    const RefinedMesh m = refine("nonmanifold", c);
    EXPECT_GT(m.triangle_count(), 0u);
    for (float x : m.positions) EXPECT_TRUE(std::isfinite(x));
    for (uint32_t i : m.indices) EXPECT_LT(i, m.vertex_count());
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("nonmanifold"), std::string::npos) << e.what();
  }
}

// Random polygon soups over few vertices (non-manifold edges, bow-ties, flipped neighbours,
// isolated vertices, creases on random edges): refinement either succeeds with sane output
// or throws plm::Error; it never crashes (run under ASan in build-asan).
TEST(Subdiv, RandomCagesNeverCrash) {
  std::mt19937 gen(11);
  for (int trial = 0; trial < 300; ++trial) {
    const uint32_t nv = 4 + gen() % 8, nf = 1 + gen() % 8;
    std::vector<float> p(nv * 3);
    for (float& x : p) x = float(gen() % 1000) / 100.0f;
    std::vector<uint32_t> sizes, idx;
    for (uint32_t f = 0; f < nf; ++f) {
      const uint32_t n = 3 + gen() % 3;
      std::vector<uint32_t> all(nv);
      for (uint32_t i = 0; i < nv; ++i) all[i] = i;
      std::shuffle(all.begin(), all.end(), gen);
      if (n > nv) continue;
      sizes.push_back(n);
      idx.insert(idx.end(), all.begin(), all.begin() + n);
    }
    if (sizes.empty()) continue;
    std::vector<float> uv(idx.size() * 2);
    for (float& x : uv) x = float(gen() % 100) / 100.0f;
    std::vector<uint32_t> crease = {idx[0], idx[1]};
    std::vector<float> weight = {float(gen() % 11) / 10.0f};
    Cage c;
    c.positions = p.data();
    c.vertex_count = nv;
    c.face_sizes = sizes.data();
    c.face_count = uint32_t(sizes.size());
    c.face_indices = idx.data();
    c.uv = uv.data();
    c.crease_edges = crease.data();
    c.crease_weights = weight.data();
    c.crease_count = 1;
    c.level = 1 + gen() % 3;
    try {
      const RefinedMesh m = refine("soup", c);
      for (float x : m.positions) ASSERT_TRUE(std::isfinite(x)) << "trial " << trial;
      for (float x : m.uv) ASSERT_TRUE(std::isfinite(x)) << "trial " << trial;
      for (uint32_t i : m.indices) ASSERT_LT(i, m.vertex_count()) << "trial " << trial;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("soup"), std::string::npos) << e.what();
    }
  }
}

std::string refine_error(const Cage& c) {
  try {
    refine("mesh 'bad'", c);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Subdiv, BadCagesGiveErrorsNamingTheIndex) {
  CubeCage cube;
  Cage c = cube.cage(1);
  EXPECT_EQ(refine_error(c), "");

  c.level = 0;
  EXPECT_NE(refine_error(c).find("level 0"), std::string::npos);
  c.level = 11;
  EXPECT_NE(refine_error(c).find("level 11"), std::string::npos);
  // 25 quads at level 10: 2 * 100 * 4^9 = 52 M triangles, over the cap (checked before refining).
  std::vector<float> gp;
  std::vector<uint32_t> gs(25, 4), gi;
  for (uint32_t j = 0; j <= 5; ++j)
    for (uint32_t i = 0; i <= 5; ++i) gp.insert(gp.end(), {float(i), float(j), 0.0f});
  for (uint32_t j = 0; j < 5; ++j)
    for (uint32_t i = 0; i < 5; ++i) gi.insert(gi.end(), {j * 6 + i, j * 6 + i + 1, j * 6 + i + 7, j * 6 + i + 6});
  Cage big;
  big.positions = gp.data();
  big.vertex_count = 36;
  big.face_sizes = gs.data();
  big.face_count = 25;
  big.face_indices = gi.data();
  big.level = 10;
  EXPECT_NE(refine_error(big).find("level 10 would make 52428800 triangles"), std::string::npos)
      << refine_error(big);

  c = cube.cage(1);
  cube.idx[9] = 8;
  EXPECT_NE(refine_error(c).find("face 2 corner 1 uses vertex 8"), std::string::npos) << refine_error(c);
  cube.idx[9] = 5;
  EXPECT_NE(refine_error(c).find("face 2 uses vertex 5 twice"), std::string::npos) << refine_error(c);
  cube.idx[9] = 6;
  cube.sizes[3] = 2;
  EXPECT_NE(refine_error(c).find("face 3 has 2 vertices"), std::string::npos) << refine_error(c);
  cube.sizes[3] = 4;
  cube.p[7] = std::nanf("");
  EXPECT_NE(refine_error(c).find("vertex 2 has a non-finite"), std::string::npos) << refine_error(c);
  cube.p[7] = -1;

  const std::vector<uint32_t> not_edge = {0, 4, 0, 7};
  const std::vector<float> w = {1.0f, 1.0f}, too_big = {0.5f, 1.5f};
  c.crease_edges = not_edge.data();
  c.crease_weights = w.data();
  c.crease_count = 2;
  EXPECT_NE(refine_error(c).find("crease 1 names the edge 0-7"), std::string::npos) << refine_error(c);
  const std::vector<uint32_t> edges = {0, 4, 4, 6};
  c.crease_edges = edges.data();
  c.crease_weights = too_big.data();
  EXPECT_NE(refine_error(c).find("crease 1 has weight 1.5"), std::string::npos) << refine_error(c);
  c.crease_weights = nullptr;
  EXPECT_NE(refine_error(c).find("NULL"), std::string::npos);

  c = cube.cage(1);
  std::vector<float> uv(48, 0.5f);
  uv[13] = INFINITY;
  c.uv = uv.data();
  EXPECT_NE(refine_error(c).find("face 1 corner 2 has the lightmap UV"), std::string::npos) << refine_error(c);
}

TEST(Subdiv, CApiAddsAnOrdinaryMesh) {
  const CubeCage cube;
  plm_scene* scene = nullptr;
  ASSERT_EQ(plm_scene_create(&scene), PLM_OK);
  const float albedo[3] = {0.5f, 0.5f, 0.5f}, black[3] = {0, 0, 0};
  ASSERT_EQ(plm_scene_add_material(scene, "grey", albedo, black, nullptr), PLM_OK);
  std::vector<float> uv(48, 0.25f);
  const std::vector<uint32_t> ids = {0, 0, 0, 0, 0, 1};
  uint32_t id = 99;
  EXPECT_EQ(plm_scene_add_subdiv_mesh(scene, "cube", cube.p.data(), 8, cube.sizes.data(), 6, cube.idx.data(),
                                      uv.data(), ids.data(), nullptr, nullptr, 0, 2, 8, 8, &id),
            PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("mesh 'cube': cage face 5 uses material 1"), std::string::npos)
      << plm_last_error();
  EXPECT_EQ(plm_scene_add_subdiv_mesh(scene, "cube", cube.p.data(), 8, cube.sizes.data(), 6, cube.idx.data(),
                                      nullptr, nullptr, nullptr, nullptr, 0, 2, 8, 8, &id),
            PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("no lightmap UVs"), std::string::npos) << plm_last_error();
  EXPECT_EQ(plm_scene_add_subdiv_mesh(scene, nullptr, cube.p.data(), 8, cube.sizes.data(), 6, cube.idx.data(),
                                      nullptr, nullptr, nullptr, nullptr, 0, 0, 0, 0, &id),
            PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("mesh '#0': subdivision level 0"), std::string::npos)
      << plm_last_error();
  EXPECT_EQ(plm_scene_add_subdiv_mesh(scene, "cube", cube.p.data(), 8, cube.sizes.data(), 6, cube.idx.data(),
                                      uv.data(), nullptr, nullptr, nullptr, 0, 2, 8, 8, &id),
            PLM_OK)
      << plm_last_error();
  EXPECT_EQ(id, 0u);
  plm_scene_release(scene);
}

// ---- scene files: "subdivision" on a mesh entry ----

std::string parse_text(const std::string& text, SceneFile& out) {
  SceneFileOptions options;
  options.allow_file_access = false;
  std::string error;
  if (!parse_scene_file_text(text, options, out, error)) return error.empty() ? "(empty error)" : error;
  return "";
}

// The cube cage of CubeCage, each face its own UV island in a 3 x 2 layout.
std::string cube_entry(const std::string& extra_subdivision, const std::string& extra_mesh = "") {
  const CubeCage cube;
  std::string pos, idx, uv;
  for (size_t k = 0; k < cube.p.size(); ++k) pos += (k ? "," : "") + std::to_string(int(cube.p[k]));
  for (size_t k = 0; k < cube.idx.size(); ++k) idx += (k ? "," : "") + std::to_string(cube.idx[k]);
  for (int f = 0; f < 6; ++f) {
    const double u0 = (f % 3) / 3.0 + 0.02, v0 = (f / 3) / 2.0 + 0.02, su = 1 / 3.0 - 0.04, sv = 0.5 - 0.04;
    const double c[8] = {u0, v0, u0 + su, v0, u0 + su, v0 + sv, u0, v0 + sv};
    for (double x : c) uv += (uv.empty() ? "" : ",") + std::to_string(x);
  }
  return R"({"name": "blob", "positions": [)" + pos + R"(], "indices": [)" + idx + R"(], "lightmap_uv": [)" + uv +
         R"(], "lightmap_resolution": 32, "subdivision": {"level": 3)" + extra_subdivision + "}" + extra_mesh + "}";
}

TEST(SubdivSceneFile, ConvexCubeCageUnderTheSkyBakesToTheSky) {
  SceneFile f;
  const std::string text = R"({"world": {"radiance": 1}, "settings": {"photon_count": 300000, "seed": 3},
      "materials": [{"name": "grey", "albedo": 0.6}], "meshes": [)" +
                           cube_entry(R"(, "face_sizes": [4,4,4,4,4,4], "creases": [[0, 4, 0.2]])",
                                      R"(, "material": "grey")") + "]}";
  ASSERT_EQ(parse_text(text, f), "");
  ASSERT_EQ(f.meshes.size(), 1u);
  plm_test::BakeResult r;
  ASSERT_EQ(plm_bake(f.scene, &f.settings, nullptr, nullptr, &r.r), PLM_OK) << plm_last_error();
  const plm_test::Map lm = r.map(f.meshes[0].id);
  double sum = 0;
  int n = 0;
  for (size_t t = 0; t < lm.coverage.size(); ++t) {
    if (lm.coverage[t] < 0.999f) continue;
    sum += lm.value(t);
    ++n;
  }
  ASSERT_GT(n, 400);
  EXPECT_NEAR(sum / n, 1.0, 0.01);  // a convex surface sees the whole sky: irradiance / pi = L
}

struct BadSubdiv {
  std::string subdivision, mesh, path, message;
};

TEST(SubdivSceneFile, MalformedCagesNameTheJsonPath) {
  const BadSubdiv cases[] = {
      {R"(, "level": 0)", "", "scene.meshes[0].subdivision.level", "must be in [1, 10]"},
      {R"(, "face_sizes": [4,4,4,4,4])", "", "scene.meshes[0].subdivision.face_sizes", "add up to 20"},
      {R"(, "face_sizes": [4,4,4,4,4,2,2])", "", "scene.meshes[0].subdivision.face_sizes[5]",
       "at least 3 vertices"},
      {R"(, "creases": [[0, 9, 1]])", "", "scene.meshes[0].subdivision.creases[0][1]", "vertex index 9"},
      {R"(, "creases": [[0, 4, 2]])", "", "scene.meshes[0].subdivision.creases[0][2]", "in [0, 1]"},
      {R"(, "creases": [[0, 7, 1]])", "", "scene.meshes[0]", "crease 0 names the edge 0-7"},
      {R"(, "creases": [[0, 4]])", "", "scene.meshes[0].subdivision.creases[0]", "expected [vertex, vertex, crease]"},
      {R"(, "smooth": 1)", "", "scene.meshes[0].subdivision.smooth", "unknown field"},
      {"", R"(, "texture_uv": [0])", "scene.meshes[0].texture_uv", "not allowed together with \"subdivision\""},
      {"", R"(, "materials": [0, 0])", "scene.meshes[0].materials", "expected one material per face: 6, got 2"},
  };
  for (const BadSubdiv& c : cases) {
    SceneFile f;
    std::string entry = cube_entry(c.subdivision, c.mesh);
    if (c.subdivision.find("\"level\"") != std::string::npos) {
      const size_t at = entry.find(R"("level": 3, )");
      ASSERT_NE(at, std::string::npos);
      entry.erase(at, 11);  // drop the default level; the case gives its own
    }
    const std::string text = R"({"materials": [{"albedo": 0.5}], "meshes": [)" + entry + "]}";
    const std::string error = parse_text(text, f);
    ASSERT_NE(error, "") << "accepted: " << c.subdivision << c.mesh;
    EXPECT_EQ(error.rfind(c.path + ": ", 0), 0u) << error;
    EXPECT_NE(error.find(c.message), std::string::npos) << error;
  }
}

}  // namespace
}  // namespace plm::subdiv

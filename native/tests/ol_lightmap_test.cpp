#include "ol/orientation_lightmap.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "ol/area_estimation.h"
#include "util/error.h"

namespace plm::ol {
namespace {

Vec3d random_direction(std::mt19937_64& gen) {
  std::normal_distribution<double> g;
  for (;;) {
    const Vec3d d{g(gen), g(gen), g(gen)};
    if (dot(d, d) > 1e-12) return normalize(d);
  }
}

// Area of a sphere of radius r: exact per bin, no estimation noise.
void set_sphere_area(OrientationLightmap& ol, double r) {
  std::vector<double> area(ol.bins()), var(ol.bins(), 0.0);
  for (uint32_t b = 0; b < ol.bins(); ++b) area[b] = r * r * ol.grid().solid_angle(b);
  ol.set_area(area, var);
}

// One hit at each bin centre that makes the bin's radiosity f(centre),
// with photon_count 1.
template <typename F>
void fill_field(OrientationLightmap& ol, F f) {
  for (uint32_t b = 0; b < ol.bins(); ++b) {
    const float flux = float(f(ol.grid().centre(b)) * kPiD * ol.area(b));
    ol.add_hit(to_float(ol.grid().centre(b)), {flux, flux, flux}, 0);
  }
  ol.finalize(1);
}

TEST(OlLightmap, EnergyIsConserved) {
  OrientationLightmap ol(16, 8);
  std::mt19937_64 gen(5);
  // A sphere's area with the lower cap removed: hits there have no area and
  // must be moved, not lost. A 1x1-bin island of area tests the whole-OL spread.
  std::vector<double> area(ol.bins()), var(ol.bins(), 0.0);
  for (uint32_t b = 0; b < ol.bins(); ++b) area[b] = ol.grid().centre(b).z > -0.5 ? ol.grid().solid_angle(b) : 0.0;
  ol.set_area(area, var);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  double total[3] = {0, 0, 0};
  const uint64_t photons = 100000;
  for (uint64_t k = 0; k < photons; ++k) {
    const Vec3 rgb(float(uni(gen)), float(2 * uni(gen)), float(0.5 * uni(gen)));
    ol.add_hit(to_float(random_direction(gen)), rgb, uint32_t(k % 8));
    total[0] += rgb.x;
    total[1] += rgb.y;
    total[2] += rgb.z;
  }
  ol.finalize(photons);
  EXPECT_GT(ol.orphan_flux(), 0.0);
  for (int c = 0; c < 3; ++c) {
    double sum = 0.0;
    for (uint32_t b = 0; b < ol.bins(); ++b) sum += ol.radiosity(b, c) * kPiD * ol.area(b);
    EXPECT_NEAR(sum * photons, total[c], 1e-9 * total[c]) << "channel " << c;
  }
  // With no area near a hit at all, the flux goes to the whole OL.
  OrientationLightmap island(8, 2);
  std::vector<double> a1(island.bins(), 0.0), v1(island.bins(), 0.0);
  a1[island.grid().bin({0, 0, 1})] = 2.0;
  island.set_area(a1, v1);
  island.add_hit({0, 0, -1}, {3, 3, 3}, 1);
  island.finalize(1);
  EXPECT_NEAR(island.radiosity(island.grid().bin({0, 0, 1}), 0) * kPiD * 2.0, 3.0, 1e-12);
}

// The limit case where an OL is an ordinary lightmap ([Thesis §6.2]): a sphere
// under a sun, hits from uniform points on its surface weighted by the exact
// irradiance E max(0, n.L), bin areas from the area estimator.
TEST(OlLightmap, SphereUnderDirectionalLightMatchesExact) {
  const double r = 1.0, sun = 3.0;
  const Vec3d light = normalize(Vec3d{0.3, -0.5, 0.8});
  const auto exact = [&](Vec3d n) { return sun * std::fmax(0.0, dot(n, light)) / kPiD; };  // irradiance / pi
  OrientationLightmap ol(16, 16);
  AreaSettings as;
  as.samples = 2000000;
  ol.set_area(estimate_area(ol.grid(), {Patch::sphere({0, 0, 0}, r)}, as));
  std::mt19937_64 gen(9);
  const uint64_t photons = 2000000;
  for (uint64_t k = 0; k < photons; ++k) {
    const Vec3d n = random_direction(gen);  // uniform point on the sphere: pdf 1 / (4 pi r^2)
    const float flux = float(sun * std::fmax(0.0, dot(n, light)) * 4 * kPiD * r * r);
    ol.add_hit(to_float(n), {flux, flux, flux}, uint32_t(k % 16));
  }
  ol.finalize(photons);
  // Each bin against the exact field averaged over the bin (uniform in the
  // bin's uv square is uniform in solid angle: the map is equal-area).
  const uint32_t n = ol.resolution();
  double z2 = 0.0;
  int lit = 0;
  for (uint32_t b = 0; b < ol.bins(); ++b) {
    double avg = 0.0;
    for (int i = 0; i < 16; ++i)
      for (int j = 0; j < 16; ++j)
        avg += exact(oct_decode((b % n + (i + 0.5) / 16) / n, (b / n + (j + 0.5) / 16) / n)) / 256;
    const double got = ol.radiosity(b, 0), err = ol.radiosity_error(b);
    if (avg < 1e-3 * sun / kPiD) {  // dark side (or a sliver of light the 16^2 points miss)
      EXPECT_LT(got, 1e-3 * sun / kPiD) << "bin " << b;
      continue;
    }
    EXPECT_NEAR(got, avg, 4.5 * err) << "bin " << b;
    z2 += (got - avg) * (got - avg) / (err * err);
    ++lit;
  }
  RecordProperty("sun_bin_mean_z2", std::to_string(z2 / lit));
  EXPECT_GT(z2 / lit, 0.6);
  EXPECT_LT(z2 / lit, 1.6);
  // Interpolated lookups follow the exact field away from the terminator's
  // kink; the error is largest on the map's own seams (see lookup()).
  double worst = 0.0, sq = 0.0;
  int count = 0;
  for (int k = 0; k < 20000; ++k) {
    const Vec3d d = random_direction(gen);
    if (std::fabs(dot(d, light)) < 0.25) continue;
    const double e = std::fabs(ol.lookup(to_float(d)).x - exact(d));
    worst = std::max(worst, e);
    sq += e * e;
    ++count;
  }
  const double scale = sun / kPiD;
  EXPECT_LT(worst, 0.15 * scale);
  EXPECT_LT(std::sqrt(sq / count), 0.03 * scale);
  RecordProperty("sun_lookup_worst_rel", std::to_string(worst / scale));
  RecordProperty("sun_lookup_rms_rel", std::to_string(std::sqrt(sq / count) / scale));
}

TEST(OlLookup, ContinuousAcrossTheFold) {
  OrientationLightmap ol(12, 2);
  set_sphere_area(ol, 1.0);
  const auto f = [](Vec3d n) { return 1.0 + 0.5 * n.x + 0.3 * n.y - 0.4 * n.z + 0.2 * n.x * n.z; };
  fill_field(ol, f);
  // Pairs of points just inside the square on either side of a glued edge
  // are neighbours on the sphere: their values must agree.
  const double e = 1e-9;
  for (double t = 0.01; t < 1.0; t += 0.0137) {
    const float tol = 1e-5f;
    EXPECT_NEAR(ol.lookup(to_float(oct_decode(e, t))).x, ol.lookup(to_float(oct_decode(e, 1 - t))).x, tol);
    EXPECT_NEAR(ol.lookup(to_float(oct_decode(1 - e, t))).x, ol.lookup(to_float(oct_decode(1 - e, 1 - t))).x, tol);
    EXPECT_NEAR(ol.lookup(to_float(oct_decode(t, e))).x, ol.lookup(to_float(oct_decode(1 - t, e))).x, tol);
    EXPECT_NEAR(ol.lookup(to_float(oct_decode(t, 1 - e))).x, ol.lookup(to_float(oct_decode(1 - t, 1 - e))).x, tol);
  }
  // The four corners are the -z pole.
  const float pole = ol.lookup({0, 0, -1}).x;
  for (double u : {e, 1 - e})
    for (double v : {e, 1 - e}) EXPECT_NEAR(ol.lookup(to_float(oct_decode(u, v))).x, pole, 1e-5f);
  // Everywhere: Lipschitz in the angle, and close to the field.
  std::mt19937_64 gen(4);
  double worst_step = 0.0, worst_err = 0.0, sq = 0.0;
  const int count = 50000;
  for (int k = 0; k < count; ++k) {
    const Vec3d a = random_direction(gen), b = normalize(a + random_direction(gen) * 1e-4);
    const double step = std::fabs(ol.lookup(to_float(a)).x - ol.lookup(to_float(b)).x) / length(a - b);
    worst_step = std::max(worst_step, step);
    const double e = std::fabs(ol.lookup(to_float(a)).x - f(a));
    worst_err = std::max(worst_err, e);
    sq += e * e;
  }
  EXPECT_LT(worst_step, 10.0);  // the field's own slope is below 1
  // First order on the map's seams (measured 0.095 at 12^2 bins), second order elsewhere.
  EXPECT_LT(worst_err, 0.12);
  EXPECT_LT(std::sqrt(sq / count), 0.025);
  RecordProperty("fold_field_worst", std::to_string(worst_err));
  RecordProperty("fold_field_rms", std::to_string(std::sqrt(sq / count)));
}

TEST(OlLookup, ZeroAreaBinsFallBack) {
  OrientationLightmap ol(16, 2);
  std::vector<double> area(ol.bins()), var(ol.bins(), 0.0);
  for (uint32_t b = 0; b < ol.bins(); ++b) area[b] = ol.grid().centre(b).z > 0.2 ? ol.grid().solid_angle(b) : 0.0;
  ol.set_area(area, var);
  // A constant field stays constant up to the edge of the covered normals:
  // empty taps are dropped, not read as black.
  fill_field(ol, [](Vec3d) { return 2.0; });
  for (uint32_t b = 0; b < ol.bins(); ++b) {
    const Vec3d c = ol.grid().centre(b);
    if (c.z > 0.0) {
      EXPECT_NEAR(ol.lookup(to_float(c)).x, 2.0f, 1e-5f) << "bin " << b;
    }
  }
  // Where no tap has area, the OL's mean radiosity: total flux / (pi * total area).
  OrientationLightmap ramp = ol.empty_copy();
  fill_field(ramp, [](Vec3d n) { return 1.0 + n.x; });
  double flux = 0.0, total = 0.0;
  for (uint32_t b = 0; b < ramp.bins(); ++b) {
    flux += ramp.flux(b).x;
    total += ramp.area(b);
  }
  EXPECT_NEAR(ramp.mean_radiosity().x, flux / (kPiD * total), 1e-5);
  EXPECT_EQ(ramp.lookup({0, 0, -1}).x, ramp.mean_radiosity().x);
  EXPECT_EQ(ramp.lookup({1, 0, -1}).x, ramp.mean_radiosity().x);
}

TEST(OlLightmap, MergedCopiesEqualOneLightmap) {
  OrientationLightmap whole(8, 4);
  set_sphere_area(whole, 1.0);
  OrientationLightmap parts[2] = {whole.empty_copy(), whole.empty_copy()};
  std::mt19937_64 gen(6);
  for (int k = 0; k < 10000; ++k) {
    const Vec3 n = to_float(random_direction(gen));
    const Vec3 rgb(1.0f, 0.5f, 0.25f);
    whole.add_hit(n, rgb, k % 4);
    parts[k % 2].add_hit(n, rgb, k % 4);
  }
  parts[0].merge(parts[1]);
  whole.finalize(10000);
  parts[0].finalize(10000);
  for (uint32_t b = 0; b < whole.bins(); ++b) {
    EXPECT_EQ(whole.hits(b), parts[0].hits(b));
    EXPECT_NEAR(whole.radiosity(b, 1), parts[0].radiosity(b, 1), 1e-12);
    EXPECT_NEAR(whole.radiosity_error(b), parts[0].radiosity_error(b), 1e-12);
  }
}

// Triangles of scattered normals and areas, their areas and hits splatted
// (Splat::bilinear): the lookup at each triangle's normal, weighted by its
// area, gives back all the flux the OL received, and a uniform field reads
// the same in every bin. The same triangles in nearest bins do neither.
TEST(OlSplat, LookupAtTheTrianglesReturnsTheirFlux) {
  const OctGrid grid(16);
  std::mt19937_64 gen(12);
  std::uniform_real_distribution<double> area_of(0.02, 0.2);
  std::vector<Vec3d> normal(200);
  std::vector<double> area(normal.size());
  for (size_t t = 0; t < normal.size(); ++t) normal[t] = random_direction(gen), area[t] = area_of(gen);
  const Vec3d sun = normalize(Vec3d{0.3, -0.2, 1.0});
  for (bool splat : {true, false}) {
    for (bool uniform : {false, true}) {
      OrientationLightmap ol(16, 4);
      std::vector<double> bin_area(ol.bins(), 0.0);
      std::vector<Splat> splats;
      for (size_t t = 0; t < normal.size(); ++t) {
        splats.push_back(splat ? Splat::bilinear(grid, normal[t]) : Splat::nearest_only(grid.bin(normal[t])));
        splats.back().add_to(bin_area, area[t]);
      }
      ol.set_area(bin_area, std::vector<double>(ol.bins(), 0.0));
      // Radiosity f on each triangle: flux f pi A (photon count 1) in 4 hits.
      double flux = 0.0;
      for (size_t t = 0; t < normal.size(); ++t) {
        const double f = uniform ? 0.5 : std::max(0.0, dot(normal[t], sun));
        flux += f * kPiD * area[t];
        const float hit = float(f * kPiD * area[t] / 4.0);
        for (uint32_t k = 0; k < 4; ++k) ol.add_splat_hit(splats[t], {hit, hit, hit}, k);
      }
      ol.finalize(1);
      double resolved = 0.0;
      for (size_t t = 0; t < normal.size(); ++t) resolved += area[t] * kPiD * ol.lookup(to_float(normal[t])).x;
      double lo = 1e30, hi = 0.0;
      for (uint32_t b = 0; b < ol.bins(); ++b)
        if (ol.area(b) > 0.0) lo = std::min(lo, ol.radiosity(b, 0)), hi = std::max(hi, ol.radiosity(b, 0));
      std::printf("[ %s, %s field ] resolved / received flux %.6f, bins %.6f..%.6f\n",
                  splat ? "splatted" : "nearest bins", uniform ? "uniform" : "cosine", resolved / flux, lo, hi);
      EXPECT_EQ(ol.orphan_flux(), 0.0);
      if (uniform) {  // radiosity 0.5 everywhere: both ways read it in every bin
        EXPECT_NEAR(lo, 0.5, 1e-6);
        EXPECT_NEAR(hi, 0.5, 1e-6);
      }
      if (splat) {
        EXPECT_NEAR(resolved, flux, 1e-6 * flux);
      } else if (!uniform) {
        EXPECT_GT(std::fabs(resolved / flux - 1.0), 1e-3);  // the lookup loses the balance
      }
    }
  }
}

TEST(OlHierarchy, LevelChosenByHitCount) {
  // root covers children a and b; c is a child of a.
  OlTree tree;
  const uint32_t root = tree.add_node(OrientationLightmap(8, 2), -1);
  const uint32_t a = tree.add_node(OrientationLightmap(8, 2), int32_t(root));
  const uint32_t b = tree.add_node(OrientationLightmap(8, 2), int32_t(root));
  const uint32_t c = tree.add_node(OrientationLightmap(8, 2), int32_t(a));
  set_sphere_area(tree.node(b), 1.0);
  set_sphere_area(tree.node(c), 2.0);
  tree.sum_areas_from_children();  // a = c, root = a + b
  const uint32_t up = tree.node(root).grid().bin({0, 0, 1});
  EXPECT_NEAR(tree.node(a).area(up), 4.0 * tree.node(a).grid().solid_angle(up), 1e-12);
  EXPECT_NEAR(tree.node(root).area(up), 5.0 * tree.node(root).grid().solid_angle(up), 1e-12);

  const Vec3 z(0, 0, 1), x(1, 0, 0), y(0, 1, 0);
  for (int k = 0; k < 20; ++k) tree.add_hit(c, z, {1, 1, 1}, k % 2);  // c: 20 hits up
  for (int k = 0; k < 3; ++k) tree.add_hit(c, x, {1, 1, 1}, k % 2);   // c: 3 along x
  for (int k = 0; k < 8; ++k) tree.add_hit(b, x, {1, 1, 1}, k % 2);   // b: 8 along x
  for (int k = 0; k < 2; ++k) tree.add_hit(b, y, {1, 1, 1}, k % 2);   // b: 2 along y
  EXPECT_EQ(tree.node(root).hits(up), 20u);
  EXPECT_EQ(tree.node(a).hits(tree.node(a).bin_of(x)), 3u);
  EXPECT_EQ(tree.node(root).hits(tree.node(root).bin_of(x)), 11u);
  tree.finalize(100);

  const uint64_t k = 10;
  EXPECT_EQ(tree.choose(c, z, k), c);     // enough hits at the leaf
  EXPECT_EQ(tree.choose(c, x, k), root);  // c has 3, a has 3, root 11
  EXPECT_EQ(tree.choose(b, x, k), root);  // b has 8
  EXPECT_EQ(tree.choose(b, x, 8), b);
  EXPECT_EQ(tree.choose(b, y, k), root);  // root has only 2 either: it is the last resort
  EXPECT_EQ(tree.choose(a, z, k), a);
  EXPECT_EQ(tree.choose(c, y, 0), c);     // min_hits 0: always the leaf
  EXPECT_EQ(tree.lookup(c, x, k).x, tree.node(root).lookup(x).x);
  EXPECT_EQ(tree.lookup(c, z, k).x, tree.node(c).lookup(z).x);
  // The parent averages its children: root flux / root area at +z.
  EXPECT_NEAR(tree.node(root).radiosity(up, 0),
              20.0 / (100 * kPiD * 5.0 * tree.node(root).grid().solid_angle(up)), 1e-9);
}

TEST(OlInput, BadInputIsNamed) {
  const auto message = [](auto&& f) -> std::string {
    try {
      f();
    } catch (const Error& e) {
      return e.what();
    }
    return "no error";
  };
  const auto has = [](const std::string& s, const char* what) { return s.find(what) != std::string::npos; };
  OrientationLightmap ol(4, 2);
  EXPECT_TRUE(has(message([&] { ol.add_hit({NAN, 0, 1}, {1, 1, 1}, 0); }), "normal (nan, 0, 1) is not finite"));
  EXPECT_TRUE(has(message([&] { ol.add_hit({0, INFINITY, 1}, {1, 1, 1}, 0); }), "is not finite"));
  EXPECT_TRUE(has(message([&] { ol.add_hit({0, 0, 0}, {1, 1, 1}, 0); }), "normal is the zero vector"));
  EXPECT_TRUE(has(message([&] { ol.add_hit({0, 0, 1}, {NAN, 1, 1}, 0); }), "flux is not finite"));
  EXPECT_TRUE(has(message([&] { ol.add_hit({0, 0, 1}, {1, 1, 1}, 2); }), "batch 2 is out of range 0..1"));
  EXPECT_TRUE(has(message([&] { OrientationLightmap(0); }), "resolution 0 is out of range: must be 1..1024"));
  EXPECT_TRUE(has(message([&] { OrientationLightmap(5000); }), "resolution 5000 is out of range"));
  EXPECT_TRUE(has(message([&] { OrientationLightmap(8, 1); }), "batches 1 is out of range"));
  EXPECT_TRUE(has(message([&] { ol.lookup({0, 0, 1}); }), "lookup before finalize"));
  EXPECT_TRUE(has(message([&] { ol.finalize(0); }), "photon_count must be > 0"));
  EXPECT_TRUE(has(message([&] { ol.set_area({1.0}, {0.0}); }), "1 areas and 1 variances for 16 bins"));
  EXPECT_TRUE(has(message([&] { ol.set_area(std::vector<double>(16, -1.0), std::vector<double>(16, 0.0)); }),
                  "bin 0 has area -1"));
  EXPECT_TRUE(has(message([&] { ol.merge(OrientationLightmap(8, 2)); }), "merge"));
  // Hits but no area anywhere: nothing to spread them over.
  ol.add_hit({0, 0, 1}, {1, 1, 1}, 0);
  EXPECT_TRUE(has(message([&] { ol.finalize(1); }), "covers no area"));
  OlTree tree;
  EXPECT_TRUE(has(message([&] { tree.add_node(OrientationLightmap(4), 0); }), "parent 0 does not exist"));
  EXPECT_TRUE(has(message([&] { tree.choose(3, {0, 0, 1}, 1); }), "node 3 does not exist"));
  // Very small but valid normals are fine.
  EXPECT_EQ(ol.bin_of({0, 0, 1e-30f}), ol.bin_of({0, 0, 1}));
}

}  // namespace
}  // namespace plm::ol

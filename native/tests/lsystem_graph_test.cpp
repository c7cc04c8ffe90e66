// The L-system scene graph (lsystem/graph/graph.h) against truth: its flattening
// against the turtle on the derived string, and its first hits and
// occlusion against brute force over the flattened primitives.
#include <gtest/gtest.h>
#include <embree3/rtcore.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <iostream>
#include <random>
#include <string>
#include <vector>

#include "lsystem/graph/embree_callbacks.h"
#include "lsystem/graph/graph.h"
#include "lsystem/language/lsystem.h"
#include "lsystem/language/turtle.h"
#include "lsystem/lsystem_object.h"
#include "util/error.h"

namespace {

using namespace plm::lsystem;
using plm::Vec3d;

const char* kPlant =
    "angle: 25.7\nwidth: 0.1\naxiom: X\n"
    "X -> F[+X]F[-X]+X\n"
    "F -> FF\n";

// 3D: pitch, roll, widths and materials that cross node boundaries; F and S
// are non-terminal, so their end states carry the turtle on.
const char* kTree =
    "angle: 22.5\nwidth: 0.08\naxiom: !(0.12)A\n"
    "A -> [&FL!(0.06)A]/////'[&FLA]///////'[&FL!(0.04)A]\n"
    "F -> S/////F\n"
    "S -> FL\n"
    "L -> [^^@L(0.4)]@O\n";

const char* kStochastic =
    "angle: 25\nwidth: 0.1\naxiom: X\n"
    "X -> (1) F[+X]F[-X]+X\n"
    "X -> (1) F[+X]F\n"
    "X -> (2) F[-X][+'X]\n"
    "F -> FF\n";

GraphOptions options(int depth, uint64_t seed = 0) {
  GraphOptions o;
  o.depth = depth;
  o.seed = seed;
  return o;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const plm::Error& e) {
    return e.what();
  }
  return "";
}

struct Flat {
  std::vector<TurtlePrimitive> src;
  std::vector<plm::csg::Primitive> prims;
  explicit Flat(std::vector<TurtlePrimitive> p) : src(std::move(p)) {
    for (const TurtlePrimitive& t : src) {
      plm::csg::PrimitiveDesc d;
      switch (t.shape) {
        case ShapeKind::Cylinder: d.shape = plm::csg::Shape::Cylinder; break;
        case ShapeKind::Sphere: d.shape = plm::csg::Shape::Sphere; break;
        case ShapeKind::Cone: d.shape = plm::csg::Shape::Cone; break;
        case ShapeKind::Box: d.shape = plm::csg::Shape::Box; break;
      }
      std::copy(t.to_world, t.to_world + 12, d.to_world);
      prims.push_back(plm::csg::make_primitive(d));
    }
  }
  // Same rule as the graph: the first crossing with t in [tnear, tfar).
  bool first_hit(Vec3d o, Vec3d d, double tnear, double tfar, double* t_out, size_t* which, bool any) const {
    plm::csg::Crossing cr[plm::csg::kMaxPrimitiveCrossings];
    double best = tfar;
    bool found = false;
    for (size_t i = 0; i < prims.size(); ++i) {
      const int n = plm::csg::intersect(prims[i], o, d, 0.0, cr);
      for (int k = 0; k < n; ++k) {
        if (cr[k].t < tnear) continue;
        if (cr[k].t >= best) break;
        best = cr[k].t;
        *which = i;
        found = true;
        if (any) return true;
        break;
      }
    }
    *t_out = best;
    return found;
  }
};

struct Ray {
  Vec3d o, d;
  double tfar;
};

// Rays from outside the bounds aimed at primitive centres (jittered) and at
// random points of the bounds, plus rays starting inside the bounds.
std::vector<Ray> make_rays(const Graph& g, const std::vector<TurtlePrimitive>* prims, size_t n, uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  const Vec3d lo = g.bounds_lo(), hi = g.bounds_hi();
  const Vec3d c = 0.5 * (lo + hi);
  const double r = plm::length(hi - lo);
  auto in_box = [&] { return Vec3d{lo.x + u(rng) * (hi.x - lo.x), lo.y + u(rng) * (hi.y - lo.y), lo.z + u(rng) * (hi.z - lo.z)}; };
  auto on_sphere = [&] {
    const double z = 2 * u(rng) - 1, phi = 6.283185307179586 * u(rng), s = std::sqrt(1 - z * z);
    return Vec3d{s * std::cos(phi), s * std::sin(phi), z};
  };
  std::vector<Ray> rays;
  for (size_t i = 0; i < n; ++i) {
    Ray ray;
    const int kind = int(i % 4);
    Vec3d target;
    if (kind <= 1 && prims && !prims->empty()) {
      const TurtlePrimitive& p = (*prims)[size_t(u(rng) * double(prims->size())) % prims->size()];
      target = Vec3d{p.to_world[3], p.to_world[7], p.to_world[11]} + 0.05 * on_sphere();
    } else {
      target = in_box();
    }
    ray.o = kind == 3 ? in_box() : c + r * on_sphere();
    ray.d = kind == 3 ? on_sphere() * (0.5 + u(rng)) : target - ray.o;
    ray.tfar = kind == 2 ? 0.3 + 0.7 * u(rng) : INFINITY;  // some segments end early (occlusion)
    rays.push_back(ray);
  }
  return rays;
}

// Every ray: the same first hit (t to 1e-9 relative, shape, material) and occlusion as brute force.
void expect_matches_brute_force(const Graph& g, const Flat& flat, const std::vector<Ray>& rays, size_t* hits_out = nullptr) {
  size_t hits = 0, mismatches = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    const Ray& r = rays[i];
    GraphHit h;
    const bool gh = g.first_hit(r.o, r.d, 0.0, r.tfar, &h);
    double t = 0;
    size_t which = 0;
    const bool bh = flat.first_hit(r.o, r.d, 0.0, r.tfar, &t, &which, false);
    bool ok = gh == bh;
    if (ok && gh) {
      ok = std::fabs(h.t - t) <= 1e-9 * std::max(1.0, std::fabs(t)) && h.shape == flat.src[which].shape &&
           h.material == flat.src[which].material;
      ++hits;
    }
    double t2;
    size_t w2;
    ok = ok && g.occluded(r.o, r.d, 0.0, r.tfar) == flat.first_hit(r.o, r.d, 0.0, r.tfar, &t2, &w2, true);
    if (!ok && ++mismatches <= 5)
      ADD_FAILURE() << "ray " << i << ": graph " << gh << " t=" << h.t << " shape " << int(h.shape) << " mat "
                    << h.material << " vs brute " << bh << " t=" << t << " shape " << int(flat.src[which].shape)
                    << " mat " << flat.src[which].material;
  }
  EXPECT_EQ(mismatches, 0u);
  EXPECT_GT(hits, rays.size() / 5) << "too few rays hit anything to be a test";
  if (hits_out) *hits_out = hits;
}

void expect_same_primitives(const std::vector<TurtlePrimitive>& a, const std::vector<TurtlePrimitive>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(int(a[i].shape), int(b[i].shape)) << i;
    ASSERT_EQ(a[i].material, b[i].material) << i;
    for (int k = 0; k < 12; ++k) ASSERT_NEAR(a[i].to_world[k], b[i].to_world[k], 1e-9 * (1 + std::fabs(b[i].to_world[k]))) << i << "," << k;
  }
}

TEST(LSystemGraph, FlattenEqualsTurtleOnDerivedString) {
  for (const char* text : {kPlant, kTree}) {
    const LSystem sys = parse(text);
    for (int depth : {0, 1, 2, 4}) {
      SCOPED_TRACE(std::string(text).substr(0, 20) + " depth " + std::to_string(depth));
      const Graph g(sys, options(depth));
      DeriveOptions d;
      d.depth = depth;
      const TurtleResult t = interpret(sys, derive(sys, d));
      const FlattenResult f = g.flatten();
      EXPECT_FALSE(f.truncated);
      expect_same_primitives(f.primitives, t.primitives);
      EXPECT_EQ(g.stats().flattened_primitives, t.primitives.size());
      // The graph's bounds contain the turtle's.
      if (!t.primitives.empty())
        for (int a = 0; a < 3; ++a) {
          EXPECT_LE(g.bounds_lo()[a], t.lo[a]);
          EXPECT_GE(g.bounds_hi()[a], t.hi[a]);
        }
    }
  }
}

TEST(LSystemGraph, ParametricConstantPerDepthEqualsTurtle) {
  const LSystem sys = parse("angle: 30\naxiom: !(0.2)A(1,0.2)\nA(l,w) -> !(w)F(l)[+A(l*0.7,w*0.7)][-A(l*0.7,w*0.7)]&A(l*0.7,w*0.7)\n");
  const Graph g(sys, options(6));
  DeriveOptions d;
  d.depth = 6;
  expect_same_primitives(g.flatten().primitives, interpret(sys, derive(sys, d)).primitives);
  EXPECT_EQ(g.stats().classes, 1u + 6u);  // the root and one A per depth
}

TEST(LSystemGraph, BracketedPlantMatchesBruteForce) {
  const LSystem sys = parse(kPlant);
  for (int depth : {4, 6}) {
    const Graph g(sys, options(depth));
    const Flat flat(g.flatten().primitives);
    const auto rays = make_rays(g, &flat.src, depth == 4 ? 8000 : 20000, 11 + uint32_t(depth));
    expect_matches_brute_force(g, flat, rays);
  }
}

TEST(LSystemGraph, Tree3DMatchesBruteForce) {
  const LSystem sys = parse(kTree);
  for (int depth : {3, 5}) {
    const Graph g(sys, options(depth));
    const Flat flat(g.flatten().primitives);
    const auto rays = make_rays(g, &flat.src, 10000, 7 + uint32_t(depth));
    expect_matches_brute_force(g, flat, rays);
  }
}

TEST(LSystemGraph, HitNormalsAndPathKeys) {
  const LSystem sys = parse(kTree);
  const Graph g(sys, options(4));
  const Flat flat(g.flatten().primitives);
  const auto rays = make_rays(g, &flat.src, 2000, 5);
  const int levels = g.stats().levels;
  size_t checked = 0;
  for (const Ray& r : rays) {
    GraphHit h;
    if (!g.first_hit(r.o, r.d, 0, r.tfar, &h)) continue;
    double t;
    size_t which;
    ASSERT_TRUE(flat.first_hit(r.o, r.d, 0, r.tfar, &t, &which, false));
    // The normal is the flattened primitive's at the same point.
    const Vec3d n = plm::csg::normal(flat.prims[which], plm::csg::face_at(flat.prims[which], r.o + t * r.d), r.o + t * r.d);
    EXPECT_NEAR(plm::dot(n, h.n), 1.0, 1e-6);
    EXPECT_EQ(h.node_key, g.ancestor_key(h, h.levels));
    EXPECT_EQ(h.instance_key, Graph::child_key(h.node_key, h.prim));
    EXPECT_EQ(g.ancestor_key(h, 0), g.root_key());
    // Depth path: the class at level k has k fewer derivation steps left than the root.
    for (int k = 0; k <= h.levels; ++k) EXPECT_EQ(g.node_class(h.classes[k]).depth, levels - k);
    ++checked;
  }
  EXPECT_GT(checked, 200u);
}

TEST(LSystemGraph, StochasticMatchesItsFlatteningAndSeedsDiffer) {
  const LSystem sys = parse(kStochastic);
  const Graph a(sys, options(6, 1)), a2(sys, options(6, 1)), b(sys, options(6, 2));
  const FlattenResult fa = a.flatten(), fa2 = a2.flatten(), fb = b.flatten();
  expect_same_primitives(fa.primitives, fa2.primitives);  // deterministic for a seed
  bool differ = fa.primitives.size() != fb.primitives.size();
  for (size_t i = 0; !differ && i < fa.primitives.size(); ++i)
    for (int k = 0; k < 12; ++k) differ = differ || fa.primitives[i].to_world[k] != fb.primitives[i].to_world[k];
  EXPECT_TRUE(differ);
  EXPECT_TRUE(a.node_class(0).path_dependent);
  EXPECT_GE(a.stats().flattened_primitives, fa.primitives.size());  // an upper bound
  // Bounds are the union over productions: they contain every seed's plant.
  for (const Graph* g : {&a, &b})
    for (const TurtlePrimitive& p : g->flatten().primitives)
      for (int r = 0; r < 3; ++r) {
        EXPECT_GE(p.to_world[4 * r + 3], a.bounds_lo()[r]);
        EXPECT_LE(p.to_world[4 * r + 3], a.bounds_hi()[r]);
      }
  for (const Graph* g : {&a, &b}) {
    const Flat flat(g->flatten().primitives);
    expect_matches_brute_force(*g, flat, make_rays(*g, &flat.src, 10000, 3));
  }
}

TEST(LSystemGraph, TinyLruCacheGivesIdenticalResults) {
  const LSystem sys = parse(kStochastic);
  GraphOptions big = options(6, 4), tiny = big;
  tiny.cache_entries = 3;
  const Graph gb(sys, big), gt(sys, tiny);
  const auto rays = make_rays(gb, nullptr, 5000, 9);
  for (const Ray& r : rays) {
    GraphHit hb, ht;
    const bool b = gb.first_hit(r.o, r.d, 0, r.tfar, &hb), t = gt.first_hit(r.o, r.d, 0, r.tfar, &ht);
    ASSERT_EQ(b, t);
    if (!b) continue;
    ASSERT_EQ(hb.t, ht.t);
    ASSERT_EQ(hb.instance_key, ht.instance_key);
    ASSERT_EQ(hb.material, ht.material);
  }
  const GraphStats sb = gb.stats(), st = gt.stats();
  EXPECT_EQ(sb.cache_hits + sb.cache_misses, st.cache_hits + st.cache_misses);  // same lookups
  EXPECT_GT(st.cache_misses, sb.cache_misses);
  EXPECT_GT(st.evictions, 0u);
  EXPECT_EQ(sb.evictions, 0u);
  EXPECT_LE(st.cached_entries, 3u);
  EXPECT_EQ(st.cache_misses - st.evictions - st.bypassed, st.cached_entries);
  EXPECT_EQ(sb.bypassed, 0u);
  std::cout << "[lru] capacity 3: hits " << st.cache_hits << " misses " << st.cache_misses << " evictions "
            << st.evictions << "; unbounded: hits " << sb.cache_hits << " misses " << sb.cache_misses << " ("
            << sb.cached_entries << " entries, " << sb.cached_bytes << " bytes)\n";
  gt.reset_cache();
  EXPECT_EQ(gt.stats().cache_misses, 0u);
  EXPECT_EQ(gt.stats().cached_entries, 0u);
}

TEST(LSystemGraph, DeepPlantStaysSmall) {
  const LSystem sys = parse(kPlant);
  const int depth = 13;
  GraphOptions o = options(depth);
  o.cache_entries = 256;
  const Graph g(sys, o);
  // Flattened count by the recurrence: F(d) draws 2^d cylinders, X(d) = 2 F(d-1) + 3 X(d-1), X(0) = 0.
  uint64_t x = 0;
  for (int d = 1; d <= depth; ++d) x = 2 * (uint64_t(1) << (d - 1)) + 3 * x;
  GraphStats s = g.stats();
  EXPECT_EQ(s.flattened_primitives, x);
  EXPECT_GT(x, 2'000'000u);
  EXPECT_LE(s.classes, 1u + 2u * depth);  // root + X and F per depth
  EXPECT_LE(s.class_bytes, size_t(1) << 20);
  // Aim at a sample of the plant (the first primitives in string order) and at its bounds.
  const FlattenResult sample = g.flatten(20000);
  const auto rays = make_rays(g, &sample.primitives, 4000, 21);
  g.reset_cache();
  size_t hits = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (const Ray& r : rays) {
    GraphHit h;
    hits += g.first_hit(r.o, r.d, 0, r.tfar, &h);
  }
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  s = g.stats();
  EXPECT_GT(hits, 100u);
  EXPECT_LE(s.cached_entries, 256u);
  std::cout << "[deep] depth " << depth << ": " << s.classes << " classes (" << s.class_bytes << " bytes), "
            << s.flattened_primitives << " primitives if flattened (~" << s.flattened_primitives * sizeof(TurtlePrimitive) / (1 << 20)
            << " MiB as TurtlePrimitive); " << rays.size() << " rays, " << hits << " hits, " << double(rays.size()) / secs
            << " rays/s; cache " << s.cached_entries << " entries / " << s.cached_bytes << " bytes (peak " << s.peak_cached_bytes
            << "), hit rate " << double(s.cache_hits) / double(s.cache_hits + s.cache_misses) << ", evictions " << s.evictions << "\n";
  // A stochastic plant as deep: every instance is its own node, held only while in the LRU cache.
  GraphOptions so = options(12, 5);
  so.cache_entries = 2048;
  const Graph sg(parse(kStochastic), so);
  const FlattenResult ssample = sg.flatten(20000);
  const auto srays = make_rays(sg, &ssample.primitives, 4000, 23);
  sg.reset_cache();
  size_t shits = 0;
  const auto t1 = std::chrono::steady_clock::now();
  for (const Ray& r : srays) {
    GraphHit h;
    shits += sg.first_hit(r.o, r.d, 0, r.tfar, &h);
  }
  const double ssecs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  const GraphStats ss = sg.stats();
  EXPECT_LE(ss.cached_entries, 2048u);
  // Its classes' boxes for inlining are the union over productions, kept
  // only as deep as kGraphInlineDescBoxes allow.
  EXPECT_LE(ss.class_bytes, size_t(8) << 20);
  EXPECT_GT(shits, 100u);
  std::cout << "[deep stochastic] depth 12: " << ss.classes << " classes (" << ss.class_bytes << " bytes), <= " << ss.flattened_primitives
            << " primitives if flattened; " << srays.size() << " rays, " << shits << " hits, "
            << double(srays.size()) / ssecs << " rays/s; cache " << ss.cached_entries << " entries / "
            << ss.cached_bytes << " bytes (peak " << ss.peak_cached_bytes << "), hit rate "
            << double(ss.cache_hits) / double(ss.cache_hits + ss.cache_misses) << ", misses " << ss.cache_misses
            << ", evictions " << ss.evictions << "\n";
  // Flattening is refused beyond the cap instead of running away.
  const FlattenResult f = g.flatten(1000);
  EXPECT_TRUE(f.truncated);
  EXPECT_EQ(f.primitives.size(), 1000u);
}

TEST(LSystemGraph, ThroughputAndThreads) {
  const LSystem sys = parse(kPlant);
  const Graph g(sys, options(7));
  const Flat flat(g.flatten().primitives);
  const auto rays = make_rays(g, &flat.src, 4000, 31);
  std::vector<double> serial(rays.size(), -1);
  auto t0 = std::chrono::steady_clock::now();
  for (size_t i = 0; i < rays.size(); ++i) {
    GraphHit h;
    if (g.first_hit(rays[i].o, rays[i].d, 0, rays[i].tfar, &h)) serial[i] = h.t;
  }
  const double graph_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const size_t brute_n = 400;
  t0 = std::chrono::steady_clock::now();
  for (size_t i = 0; i < brute_n; ++i) {
    double t;
    size_t w;
    flat.first_hit(rays[i].o, rays[i].d, 0, rays[i].tfar, &t, &w, false);
  }
  const double brute_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const GraphStats s = g.stats();
  std::cout << "[throughput] depth 7, " << flat.src.size() << " primitives, " << s.classes << " classes: graph "
            << double(rays.size()) / graph_s << " rays/s, brute force " << double(brute_n) / brute_s
            << " rays/s; cache hit rate " << double(s.cache_hits) / double(s.cache_hits + s.cache_misses) << "\n";
  // Many threads, one graph: the same answers.
  std::vector<double> parallel(rays.size(), -1);
  t0 = std::chrono::steady_clock::now();
  for (int rep = 0; rep < 4; ++rep)
    tbb::parallel_for(size_t(0), rays.size(), [&](size_t i) {
      GraphHit h;
      if (g.first_hit(rays[i].o, rays[i].d, 0, rays[i].tfar, &h)) parallel[i] = h.t;
    });
  const double par_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::cout << "[throughput] parallel (all cores, per-thread caches): " << 4.0 * double(rays.size()) / par_s
            << " rays/s\n";
  EXPECT_EQ(serial, parallel);
}

TEST(LSystemGraph, EmbreeUserGeometryMatchesDirectCalls) {
  const LSystem sys = parse(kTree);
  const Graph g(sys, options(4));
  RTCDevice device = rtcNewDevice(nullptr);
  RTCScene scene = rtcNewScene(device);
  const unsigned id = attach_graph(device, scene, g);
  rtcCommitScene(scene);
  const Flat flat(g.flatten().primitives);
  const auto rays = make_rays(g, &flat.src, 2000, 17);
  size_t hits = 0;
  GraphHit record;
  for (const Ray& r : rays) {
    plm::HitContext context;
    context.graph_hits = &record;
    RTCIntersectContext& ctx = context.context;
    RTCRayHit rh{};
    rh.ray.org_x = float(r.o.x);
    rh.ray.org_y = float(r.o.y);
    rh.ray.org_z = float(r.o.z);
    rh.ray.dir_x = float(r.d.x);
    rh.ray.dir_y = float(r.d.y);
    rh.ray.dir_z = float(r.d.z);
    rh.ray.tnear = 0;
    rh.ray.tfar = std::isinf(r.tfar) ? INFINITY : float(r.tfar);
    rh.ray.mask = 0xFFFFFFFF;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    const float tfar0 = rh.ray.tfar;
    rtcIntersect1(scene, &ctx, &rh);
    // The same ray in float precision, traced directly.
    const Vec3d o{rh.ray.org_x, rh.ray.org_y, rh.ray.org_z}, d{rh.ray.dir_x, rh.ray.dir_y, rh.ray.dir_z};
    GraphHit h;
    const bool direct = g.first_hit(o, d, 0, tfar0, &h);
    ASSERT_EQ(direct, rh.hit.geomID == id);
    if (!direct) continue;
    ++hits;
    EXPECT_NEAR(rh.ray.tfar, h.t, 1e-5 * std::max(1.0, h.t));
    EXPECT_EQ(rh.hit.primID, unsigned(h.material));
    EXPECT_EQ(int(rh.hit.u), int(h.shape));
    EXPECT_EQ(record.instance_key, h.instance_key);
    RTCRay occ = rh.ray;
    occ.tfar = INFINITY;
    rtcOccluded1(scene, &ctx, &occ);
    EXPECT_EQ(occ.tfar, -INFINITY);
  }
  EXPECT_GT(hits, 300u);
  rtcReleaseScene(scene);
  rtcReleaseDevice(device);
}

// The L-system user geometry has a sentinel primitive (util/user_geometry.h)
// so that Embree tests the object's box before calling it: a ray that misses
// the box never reaches the callbacks, a ray through the sentinel's corner
// gets no hit from it. (With one primitive Embree calls the callback for every
// ray of the scene: printed, not asserted, as it is Embree's behaviour.)
struct CountingObject {
  mutable int calls = 0;
  bool first_hit(Vec3d, Vec3d, double, double, GraphHit*) const { ++calls; return false; }
  bool occluded(Vec3d, Vec3d, double, double) const { ++calls; return false; }
};

void counting_bounds(const RTCBoundsFunctionArguments* args) {
  plm::write_bounds(Vec3d{0, 0, 0}, Vec3d{1, 1, 1}, 0.0, args->bounds_o);
}

TEST(LSystemGraph, EmbreeTestsTheObjectBoxBeforeTheCallback) {
  RTCDevice device = rtcNewDevice(nullptr);
  int calls_one = 0;
  for (const bool sentinel : {true, false}) {
    CountingObject obj;
    RTCScene scene = rtcNewScene(device);
    if (sentinel) {
      plm::attach_user_geometry<counting_bounds, intersect_n<CountingObject>, occluded_n<CountingObject>>(device, scene,
                                                                                                        &obj);
    } else {  // one primitive, as before the sentinel
      RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
      rtcSetGeometryUserPrimitiveCount(geom, 1);
      rtcSetGeometryUserData(geom, &obj);
      rtcSetGeometryBoundsFunction(geom, counting_bounds, nullptr);
      rtcSetGeometryIntersectFunction(geom, intersect_n<CountingObject>);
      rtcSetGeometryOccludedFunction(geom, occluded_n<CountingObject>);
      rtcCommitGeometry(geom);
      rtcAttachGeometry(scene, geom);
      rtcReleaseGeometry(geom);
    }
    rtcCommitScene(scene);
    // 100 rays that miss the unit box, 50 through its centre, 10 through the
    // lower corner (the sentinel's point), each traced closest and occluded.
    std::mt19937_64 gen(3);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    int hits = 0, miss_calls = 0, centre_calls = 0, corner_calls = 0;
    for (int i = 0; i < 160; ++i) {
      const int calls_before = obj.calls;
      const Vec3d target = i < 100 ? Vec3d{5 + u(gen), 5 + u(gen), 5 + u(gen)}
                                   : i < 150 ? Vec3d{0.5, 0.5, 0.5} : Vec3d{0, 0, 0};
      const Vec3d o = target + 10.0 * Vec3d{u(gen), u(gen), 1.5};
      const Vec3d d = target - o;
      plm::HitContext context;
      RTCIntersectContext& ctx = context.context;
      RTCRayHit rh{};
      rh.ray.org_x = float(o.x), rh.ray.org_y = float(o.y), rh.ray.org_z = float(o.z);
      rh.ray.dir_x = float(d.x), rh.ray.dir_y = float(d.y), rh.ray.dir_z = float(d.z);
      rh.ray.tnear = 0;
      rh.ray.tfar = INFINITY;
      rh.ray.mask = 0xFFFFFFFF;
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      RTCRay occ = rh.ray;
      rtcIntersect1(scene, &ctx, &rh);
      rtcOccluded1(scene, &ctx, &occ);
      hits += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
      hits += occ.tfar < 0;
      (i < 100 ? miss_calls : i < 150 ? centre_calls : corner_calls) += obj.calls - calls_before;
    }
    EXPECT_EQ(hits, 0);
    if (sentinel) {
      // One closest and one occlusion query per ray through the box, none for
      // a ray that misses it. A ray aimed at the box's corner passes it by
      // float rounding, inside or out, and Embree's box test (its code path
      // differs per CPU) may go either way: at most two calls each.
      EXPECT_EQ(miss_calls, 0);
      EXPECT_EQ(centre_calls, 2 * 50);
      EXPECT_LE(corner_calls, 2 * 10);
    } else {
      calls_one = obj.calls;
    }
    rtcReleaseScene(scene);
  }
  std::cout << "[ measured ] callbacks for 160 rays (60 through the box), closest + occluded: one primitive "
            << calls_one << "\n";
  rtcReleaseDevice(device);
}

TEST(LSystemGraph, RejectsWhatItCannotRepresent) {
  const LSystem plant = parse(kPlant);
  GraphOptions deep = options(80);
  EXPECT_NE(error_of([&] { Graph g(plant, deep); }).find("over the limit of 64"), std::string::npos);
  GraphOptions shallow = options(10);
  shallow.max_levels = 8;
  EXPECT_NE(error_of([&] { Graph g(plant, shallow); }).find("max_levels"), std::string::npos);
  // Parameters that differ per instance at one depth.
  const LSystem diverging = parse("axiom: A(1)\nA(l) -> F(l)[+A(l*0.7)][-A(l*0.5+0.1)]\n");
  EXPECT_NE(error_of([&] { Graph g(diverging, options(10)); }).find("parametric productions need the flattened path"),
            std::string::npos);
  EXPECT_NO_THROW(Graph(diverging, options(5)));  // 2^5 states per depth is still within the limit
  EXPECT_NE(error_of([&] { Graph g(parse("axiom: AB\nA < B -> F\n"), options(2)); }).find("context-sensitive"),
            std::string::npos);
  EXPECT_NE(error_of([&] { Graph g(parse("axiom: A\nA -> F(rand())A\n"), options(2)); }).find("rand()"),
            std::string::npos);
  // A stochastic module that ends in different places and is followed by drawing.
  EXPECT_NE(error_of([&] { Graph g(parse("axiom: XF\nX -> (1) F\nX -> (1) FF\n"), options(1)); })
                .find("end in different turtle states"),
            std::string::npos);
  EXPECT_NO_THROW(Graph(parse("axiom: [X]F\nX -> (1) F\nX -> (1) FF\n"), options(1)));
  // Brackets across node boundaries.
  EXPECT_NE(error_of([&] { Graph g(parse("axiom: AF]\nA -> [F\n"), options(1)); }).find("brackets may not cross"),
            std::string::npos);
  // A class limit stops a runaway set-up.
  GraphOptions few = options(12);
  few.max_classes = 5;
  EXPECT_NE(error_of([&] { Graph g(plant, few); }).find("max_classes"), std::string::npos);
}

}  // namespace

// Parameters equal but for rounding (l * r1 * r2 and l * r2 * r1) are one node
// state: the sympodial tree (two branch ratios) builds at depth 15 (32,767
// cylinders) with node classes growing linearly in the depth, and flattens
// to the same primitive count as the derivation.
TEST(LSystemGraph, RoundingDoesNotSplitParameterStates) {
  const char* rules =
      "const r1 = 0.9\nconst r2 = 0.7\nconst a1 = 10\nconst a2 = 60\nconst wr = 0.707\n"
      "axiom: A(1, 0.1)\n"
      "A(l, w) -> !(w) F(l) [ &(a1) B(l*r1, w*wr) ] /(180) [ &(a2) B(l*r2, w*wr) ]\n"
      "B(l, w) -> !(w) F(l) [ +(a1) B(l*r1, w*wr) ] [ -(a2) B(l*r2, w*wr) ]\n";
  const plm::lsystem::LSystem sys = plm::lsystem::parse(rules);
  plm::lsystem::GraphOptions opt;
  opt.depth = 15;
  const plm::lsystem::Graph g(sys, opt);
  const plm::lsystem::GraphStats st = g.stats();
  EXPECT_EQ(st.flattened_primitives, 32767u);
  EXPECT_LT(st.classes, 16u * 17u * 2u) << "node states split by rounding";
  opt.depth = 10;
  const plm::lsystem::Graph small(sys, opt);
  plm::lsystem::DeriveOptions d;
  d.depth = 10;
  const plm::lsystem::TurtleResult flat = plm::lsystem::interpret(sys, plm::lsystem::derive(sys, d));
  EXPECT_EQ(small.flatten().primitives.size(), flat.primitives.size());
}

namespace {

// The exact box of flattened primitives, by the turtle's per-shape extents.
void exact_box(const std::vector<TurtlePrimitive>& prims, Vec3d* lo, Vec3d* hi) {
  *lo = Vec3d{INFINITY, INFINITY, INFINITY};
  *hi = Vec3d{-INFINITY, -INFINITY, -INFINITY};
  for (const TurtlePrimitive& p : prims)
    for (int r = 0; r < 3; ++r) {
      const double* m = p.to_world + 4 * r;
      const double e = p.shape == ShapeKind::Sphere ? std::sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
                       : p.shape == ShapeKind::Box  ? std::fabs(m[0]) + std::fabs(m[1]) + std::fabs(m[2])
                                                    : std::sqrt(m[0] * m[0] + m[1] * m[1]) + std::fabs(m[2]);
      (*lo)[r] = std::min((*lo)[r], m[3] - e);
      (*hi)[r] = std::max((*hi)[r], m[3] + e);
    }
}

plm::Affine3d compose_for_test(const plm::Affine3d& a, const plm::Affine3d& b) {
  plm::Affine3d c;
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 4; ++k)
      c.m[4 * r + k] = a.m[4 * r] * b.m[k] + a.m[4 * r + 1] * b.m[4 + k] + a.m[4 * r + 2] * b.m[8 + k] +
                       (k == 3 ? a.m[4 * r + 3] : 0.0);
  return c;
}

double volume(Vec3d lo, Vec3d hi) { return (hi.x - lo.x) * (hi.y - lo.y) * (hi.z - lo.z); }

}  // namespace

// Bounds (lsystem/graph/graph_bounds.h): child boxes are the exact boxes of their subtrees,
// found by unfolding; GraphOptions::bounds_budget = 0 gives the looser boxes
// of mapped child boxes (8 corners, level by level), a small budget lies in
// between. The root box holds every flattened primitive (for a deterministic
// plant it is their exact box up to the padding); the hits are the same
// whatever the budget: the same t, shape and material, and the same
// primitive instance except where two primitives are hit at exactly the same
// t (kTree draws some leaves twice at one place: then the order of the
// visits, which the boxes change, picks one).
TEST(LSystemGraph, ExactBoundsHoldThePlantAndAreTighter) {
  const char* sympodial =
      "const r1 = 0.9\nconst r2 = 0.7\nconst a1 = 10\nconst a2 = 60\nconst wr = 0.707\n"
      "axiom: A(0, 0)\n"
      "A(i, j) -> !(0.1*wr^(i+j)) F(r1^i*r2^j) [ &(a1) B(i+1, j) ] /(180) [ &(a2) B(i, j+1) ]\n"
      "B(i, j) -> !(0.1*wr^(i+j)) F(r1^i*r2^j) [ +(a1) B(i+1, j) ] [ -(a2) B(i, j+1) ]\n";
  for (const char* text : {kTree, kStochastic, sympodial}) {
    SCOPED_TRACE(std::string(text).substr(0, 30));
    const LSystem sys = parse(text);
    const bool stochastic = text == kStochastic;
    GraphOptions exact = options(text == sympodial ? 9 : 5, 3), loose = exact, small = exact;
    loose.bounds_budget = 0;
    small.bounds_budget = 2;
    const Graph ge(sys, exact), gl(sys, loose), gs(sys, small);
    const FlattenResult f = ge.flatten();
    Vec3d lo, hi;
    exact_box(f.primitives, &lo, &hi);
    const double tol = 1e-8 * (plm::max_abs_component(lo) + plm::max_abs_component(hi));
    for (int a = 0; a < 3; ++a) {
      EXPECT_LE(ge.bounds_lo()[a], lo[a]);
      EXPECT_GE(ge.bounds_hi()[a], hi[a]);
      if (!stochastic) {  // a stochastic class's box is the union over its productions
        EXPECT_NEAR(ge.bounds_lo()[a], lo[a], tol);
        EXPECT_NEAR(ge.bounds_hi()[a], hi[a], tol);
      }
      EXPECT_LE(gs.bounds_lo()[a], ge.bounds_lo()[a] + tol);
      EXPECT_GE(gs.bounds_hi()[a], ge.bounds_hi()[a] - tol);
      EXPECT_LE(gl.bounds_lo()[a], gs.bounds_lo()[a] + tol);
      EXPECT_GE(gl.bounds_hi()[a], gs.bounds_hi()[a] - tol);
    }
    const double ve = volume(ge.bounds_lo(), ge.bounds_hi()), vl = volume(gl.bounds_lo(), gl.bounds_hi());
    std::cout << "[bounds] root box volume: exact " << ve << ", budget 2 " << volume(gs.bounds_lo(), gs.bounds_hi())
              << ", mapped boxes (budget 0) " << vl << "\n";
    EXPECT_LT(ve, 0.9 * vl) << "the exact unfolding should be clearly tighter";
    // Hits: the same rays, the same answers, whatever the bounds.
    const Flat flat(f.primitives);
    const auto rays = make_rays(ge, &flat.src, 4000, 41);
    size_t hits = 0, ties = 0;
    for (const Ray& r : rays) {
      GraphHit he, hl, hs;
      const bool be = ge.first_hit(r.o, r.d, 0, r.tfar, &he), bl = gl.first_hit(r.o, r.d, 0, r.tfar, &hl),
                 bs = gs.first_hit(r.o, r.d, 0, r.tfar, &hs);
      ASSERT_EQ(be, bl);
      ASSERT_EQ(be, bs);
      EXPECT_EQ(ge.occluded(r.o, r.d, 0, r.tfar), be);
      EXPECT_EQ(gl.occluded(r.o, r.d, 0, r.tfar), be);
      if (!be) continue;
      ++hits;
      EXPECT_EQ(he.t, hl.t);
      EXPECT_EQ(he.t, hs.t);
      EXPECT_EQ(int(he.shape), int(hl.shape));
      EXPECT_EQ(he.material, hl.material);
      ties += he.instance_key != hl.instance_key || he.instance_key != hs.instance_key;
    }
    EXPECT_GT(hits, rays.size() / 20);
    std::cout << "[bounds] " << hits << " hits, " << ties << " on coincident primitives of other instances\n";
    // The tree of docs/benchmarks/geometry.md's ray-cost bench against brute force over
    // its flattened primitives (its thin twigs: fewer rays hit than elsewhere).
    if (text != sympodial) continue;
    size_t bhits = 0, mismatches = 0;
    for (const Ray& r : make_rays(ge, &flat.src, 8000, 43)) {
      GraphHit h;
      const bool gh = ge.first_hit(r.o, r.d, 0.0, r.tfar, &h);
      double t = 0, t2 = 0;
      size_t which = 0, w2 = 0;
      const bool bh = flat.first_hit(r.o, r.d, 0.0, r.tfar, &t, &which, false);
      bool ok = gh == bh && ge.occluded(r.o, r.d, 0.0, r.tfar) == flat.first_hit(r.o, r.d, 0.0, r.tfar, &t2, &w2, true);
      if (ok && gh) ok = std::fabs(h.t - t) <= 1e-9 * std::max(1.0, t) && h.shape == flat.src[which].shape;
      bhits += gh;
      mismatches += !ok;
    }
    EXPECT_EQ(mismatches, 0u);
    EXPECT_GT(bhits, 500u);
  }
}

// A stochastic class's bounds unfold the union of its productions: here 10
// X children between three productions, so a class's subtree holds ~10^depth
// nodes while one derivation holds ~3.3^depth. Each child reference's
// unfolding (with the boxes views inline) stops at bounds_budget nodes and
// the set-up's at bounds_total; without those caps the set-up's time grows
// as ~10^depth, so ctest's timeout guards them. Boxes past a cap are the
// looser mapped ones; the hits stay those of the flattened plant.
TEST(LSystemGraph, WideStochasticSetUpIsBounded) {
  const char* wide =
      "angle: 30\nwidth: 0.1\naxiom: X\n"
      "X -> (1) F[+X][-X]F[&X]X\n"
      "X -> (1) F[^X][/X]X\n"
      "X -> (1) F[+X]F[-X]X\n"
      "F -> FF\n";
  const LSystem sys = parse(wide);
  GraphOptions o = options(10, 9), tiny = o;
  tiny.bounds_total = 500;
  const Graph g(sys, o), gt(sys, tiny);
  const GraphStats s = g.stats(), st = gt.stats();
  EXPECT_LE(s.bounds_visits, o.bounds_total);
  EXPECT_GT(s.bounds_visits, tiny.bounds_total);
  EXPECT_LE(st.bounds_visits, tiny.bounds_total);
  const FlattenResult f = g.flatten();
  ASSERT_FALSE(f.truncated);
  Vec3d lo, hi;
  exact_box(f.primitives, &lo, &hi);
  for (int a = 0; a < 3; ++a) {
    EXPECT_LE(g.bounds_lo()[a], lo[a]);
    EXPECT_GE(g.bounds_hi()[a], hi[a]);
    EXPECT_LE(gt.bounds_lo()[a], g.bounds_lo()[a]);
    EXPECT_GE(gt.bounds_hi()[a], g.bounds_hi()[a]);
  }
  std::cout << "[wide stochastic] depth 10: " << s.classes << " classes, " << f.primitives.size()
            << " primitives flattened; set-up unfoldings visited " << s.bounds_visits << " nodes (" << st.bounds_visits
            << " with bounds_total 500); root box volume " << volume(g.bounds_lo(), g.bounds_hi()) << " against "
            << volume(lo, hi) << " exact, " << volume(gt.bounds_lo(), gt.bounds_hi()) << " with bounds_total 500\n";
  const Flat flat(f.primitives);
  const auto rays = make_rays(g, &flat.src, 160, 53);
  size_t hits = 0, mismatches = 0;
  for (const Ray& r : rays) {
    GraphHit h, ht;
    const bool gh = g.first_hit(r.o, r.d, 0.0, r.tfar, &h), th = gt.first_hit(r.o, r.d, 0.0, r.tfar, &ht);
    double t = 0;
    size_t which = 0;
    const bool bh = flat.first_hit(r.o, r.d, 0.0, r.tfar, &t, &which, false);
    bool ok = gh == bh && th == bh && gt.occluded(r.o, r.d, 0.0, r.tfar) == bh;
    if (ok && gh) ok = std::fabs(h.t - t) <= 1e-9 * std::max(1.0, t) && h.t == ht.t;
    hits += gh;
    mismatches += !ok;
  }
  EXPECT_EQ(mismatches, 0u);
  EXPECT_GT(hits, 50u);
}

// The graph's expansions hold trace_primitive(d): make_primitive(d) without
// the (numerically integrated) face areas; every other field bit for bit.
TEST(LSystemGraph, TracePrimitiveMatchesMakePrimitive) {
  std::mt19937_64 rng(77);
  std::uniform_real_distribution<double> u(-2, 2);
  const plm::csg::Shape shapes[] = {plm::csg::Shape::Sphere, plm::csg::Shape::Cylinder, plm::csg::Shape::Cone,
                                    plm::csg::Shape::Box};
  int checked = 0;
  for (int i = 0; i < 400; ++i) {
    plm::csg::PrimitiveDesc d;
    d.shape = shapes[i % 4];
    for (double& v : d.to_world) v = u(rng);
    if (i % 3 == 0) {  // a similarity (the turtle's spheres): rotation * uniform scale
      const double s = 0.5 + std::fabs(u(rng));
      const double a = u(rng), c = std::cos(a), sn = std::sin(a);
      const double m[12] = {s * c, -s * sn, 0, u(rng), s * sn, s * c, 0, u(rng), 0, 0, s, u(rng)};
      std::copy(m, m + 12, d.to_world);
    }
    if (!plm::csg::check_primitive(d).empty()) continue;
    const plm::csg::Primitive a = plm::csg::make_primitive(d), b = trace_primitive(d);
    ++checked;
    ASSERT_EQ(a.shape, b.shape);
    ASSERT_EQ(a.major, b.major);
    ASSERT_EQ(a.minor, b.minor);
    for (int k = 0; k < 12; ++k) {
      ASSERT_EQ(a.to_world.m[k], b.to_world.m[k]) << i;
      ASSERT_EQ(a.to_local.m[k], b.to_local.m[k]) << i;
    }
    for (int k = 0; k < 3; ++k) {
      ASSERT_EQ(a.lo[k], b.lo[k]) << i;
      ASSERT_EQ(a.hi[k], b.hi[k]) << i;
    }
    ASSERT_EQ(a.size, b.size) << i;
    ASSERT_EQ(a.stretch, b.stretch) << i;
    ASSERT_EQ(a.similarity, b.similarity) << i;
    ASSERT_EQ(a.area_weight_max, b.area_weight_max) << i;
    for (const double ar : b.area) ASSERT_TRUE(std::isnan(ar));
  }
  EXPECT_GT(checked, 300);
}

// An object's world box (Graph::world_bounds_lo / hi, LSystemObject's Embree
// bounds): the exact box of the placed primitives, also when the placement
// rotates (the 8 mapped corners of the graph's box are looser there).
TEST(LSystemGraph, WorldBoundsAreTheExactBoxOfThePlacedPlant) {
  const char* sympodial =
      "const r1 = 0.9\nconst r2 = 0.7\nconst a1 = 10\nconst a2 = 60\nconst wr = 0.707\n"
      "axiom: A(0, 0)\n"
      "A(i, j) -> !(0.1*wr^(i+j)) F(r1^i*r2^j) [ &(a1) B(i+1, j) ] /(180) [ &(a2) B(i, j+1) ]\n"
      "B(i, j) -> !(0.1*wr^(i+j)) F(r1^i*r2^j) [ +(a1) B(i+1, j) ] [ -(a2) B(i, j+1) ]\n";
  // Rotation by 37 degrees about z, then 20 about x, scale 1.3, translation.
  const double cz = std::cos(0.6458), sz = std::sin(0.6458), cx = std::cos(0.3491), sx = std::sin(0.3491), k = 1.3;
  const plm::Affine3d world{{k * cz, -k * sz, 0, 4.0,                    //
                                k * cx * sz, k * cx * cz, -k * sx, -2.0,  //
                                k * sx * sz, k * sx * cz, k * cx, 0.5}};
  for (const char* text : {kTree, sympodial}) {
    SCOPED_TRACE(std::string(text).substr(0, 30));
    GraphOptions o = options(text == sympodial ? 9 : 4, 3), tight_budget = o;
    o.world = world;
    tight_budget.world = world;
    tight_budget.bounds_budget = 3;  // runs out: mapped class boxes below, still conservative
    const Graph g(parse(text), o), gb(parse(text), tight_budget);
    // Truth: the exact boxes of the flattened primitives, placed.
    FlattenResult f = g.flatten();
    for (TurtlePrimitive& p : f.primitives) {
      const plm::Affine3d m = plm::Affine3d::from_array(p.to_world);
      const plm::Affine3d w = compose_for_test(world, m);
      std::copy(w.m, w.m + 12, p.to_world);
    }
    Vec3d lo, hi;
    exact_box(f.primitives, &lo, &hi);
    const Vec3d wlo = g.world_bounds_lo(), whi = g.world_bounds_hi();
    const double tol = 1e-8 * (plm::max_abs_component(lo) + plm::max_abs_component(hi));
    // The 8 corners of the graph's box, mapped (the box before this change).
    Vec3d clo{INFINITY, INFINITY, INFINITY}, chi{-INFINITY, -INFINITY, -INFINITY};
    for (int c = 0; c < 8; ++c) {
      const Vec3d a = g.bounds_lo(), b = g.bounds_hi();
      const Vec3d p = world.point({c & 1 ? b.x : a.x, c & 2 ? b.y : a.y, c & 4 ? b.z : a.z});
      clo = plm::min(clo, p);
      chi = plm::max(chi, p);
    }
    for (int a = 0; a < 3; ++a) {
      EXPECT_LE(wlo[a], lo[a]);
      EXPECT_GE(whi[a], hi[a]);
      EXPECT_NEAR(wlo[a], lo[a], tol);
      EXPECT_NEAR(whi[a], hi[a], tol);
      EXPECT_LE(gb.world_bounds_lo()[a], lo[a]);
      EXPECT_GE(gb.world_bounds_hi()[a], hi[a]);
      EXPECT_LE(gb.world_bounds_lo()[a], wlo[a] + tol);
      EXPECT_GE(gb.world_bounds_hi()[a], whi[a] - tol);
    }
    const double ve = volume(wlo, whi), vc = volume(clo, chi);
    std::cout << "[world bounds] volume: exact " << ve << ", budget 3 "
              << volume(gb.world_bounds_lo(), gb.world_bounds_hi()) << ", mapped corners " << vc << "\n";
    EXPECT_LT(ve, 0.9 * vc) << "the rotated plant's exact box should be clearly tighter";
    // The object built through the C API's settings uses it.
    plm_lsystem_settings st = default_lsystem_settings();
    st.depth = uint32_t(o.depth);
    st.seed = o.seed;
    std::copy(world.m, world.m + 12, st.matrix);
    const LSystemObject obj("tree", text, st, 1);
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(obj.bounds_lo()[a], wlo[a]);
      EXPECT_EQ(obj.bounds_hi()[a], whi[a]);
    }
  }
}

// A byte budget far below the working set (the sympodial tree at depth 12 in
// 32 KiB): the same hits as an unbounded cache, the cache within its budget
// between rays, and a hit rate that does not collapse.
TEST(LSystemGraph, SmallByteBudgetDegradesGracefully) {
  const char* sympodial =
      "const r1 = 0.9\nconst r2 = 0.7\nconst a1 = 10\nconst a2 = 60\nconst wr = 0.707\n"
      "axiom: A(0, 0)\n"
      "A(i, j) -> !(0.1*wr^(i+j)) F(r1^i*r2^j) [ &(a1) B(i+1, j) ] /(180) [ &(a2) B(i, j+1) ]\n"
      "B(i, j) -> !(0.1*wr^(i+j)) F(r1^i*r2^j) [ +(a1) B(i+1, j) ] [ -(a2) B(i, j+1) ]\n";
  const LSystem sys = parse(sympodial);
  GraphOptions big = options(12), small = big;
  small.cache_bytes = 32 << 10;
  const Graph gb(sys, big), gs(sys, small);
  const FlattenResult f = gb.flatten();
  const auto rays = make_rays(gb, &f.primitives, 6000, 51);
  // A big cache's views inline descendants (primitives placed in the view's
  // frame, composed transforms) and a small one's do not: the hits agree up
  // to rounding (lsystem/graph/graph_view.h); the same primitive wins on these rays.
  size_t hits = 0, same_bits = 0;
  double max_dt = 0, max_dn = 0;
  for (const Ray& r : rays) {
    GraphHit hb, hs;
    const bool b = gb.first_hit(r.o, r.d, 0, r.tfar, &hb), s = gs.first_hit(r.o, r.d, 0, r.tfar, &hs);
    ASSERT_EQ(b, s);
    ASSERT_EQ(gs.occluded(r.o, r.d, 0, r.tfar), b);
    if (!b) continue;
    ++hits;
    max_dt = std::max(max_dt, std::fabs(hb.t - hs.t) / std::max(1.0, std::fabs(hb.t)));
    ASSERT_NEAR(hb.t, hs.t, 1e-12 * std::max(1.0, std::fabs(hb.t)));
    ASSERT_EQ(hb.instance_key, hs.instance_key);
    ASSERT_EQ(hb.levels, hs.levels);
    for (int a = 0; a < 3; ++a) {
      max_dn = std::max(max_dn, std::fabs(hb.n[a] - hs.n[a]));
      ASSERT_NEAR(hb.n[a], hs.n[a], 1e-9);
    }
    same_bits += hb.t == hs.t;
  }
  std::cout << "[small cache] inlined vs not: max |dt| / max(1, t) " << max_dt << ", max |dn| " << max_dn << ", "
            << same_bits << " of " << hits << " hits with the same t bits\n";
  const GraphStats sb = gb.stats(), ss = gs.stats();
  const double rate = double(ss.cache_hits) / double(ss.cache_hits + ss.cache_misses);
  std::cout << "[small cache] " << hits << " hits; 32 KiB: hit rate " << rate << ", " << ss.cache_misses
            << " misses (" << ss.bypassed << " not admitted), " << ss.cached_bytes << " bytes; unbounded: "
            << sb.cached_entries << " entries, " << sb.cached_bytes << " bytes\n";
  EXPECT_GT(hits, 500u);
  EXPECT_GT(sb.cached_bytes, 2u * small.cache_bytes);
  EXPECT_LE(ss.cached_bytes, small.cache_bytes);
  EXPECT_GT(ss.bypassed, 0u);
  EXPECT_GT(rate, 0.8);
}

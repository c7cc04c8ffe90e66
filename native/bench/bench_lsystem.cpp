// Ray cost of an L-system traced as a cyclic scene graph against the same
// plant flattened (docs/benchmarks/geometry.md, "L-system objects").
//   build/bin/photonlm_bench_lsystem [--depth 15] [--rays 200000] [--repeats 5] [--bounds-budget N]
//                                    [--cache-bytes N: the graph's per-thread cache, default 64 MiB]
//                                    [--summary: only the summary | --no-summary] [Google Benchmark flags]
//
// The plant is docs/bench_lsystem.py's SYMPODIAL_TREE (the add-on preset with
// integer branch counts): 2^depth - 1 cylinders. Three Embree scenes, each
// traced with rtcIntersect1 / rtcOccluded1 on the SAME float rays, one thread:
//   graph      the L-system graph as one user geometry (lsystem::attach_graph)
//   flat       one user geometry with one Embree primitive per flattened
//              cylinder, bounds = the primitive's box, intersect = the same
//              csg::intersect the graph calls (first crossing in [tnear, tfar),
//              normal by csg::normal): Embree's SAH BVH against the graph's
//              own hierarchy, same primitive code on both sides
//   flat_csg   each flattened cylinder as its own one-leaf CSG solid
//              (csg::attach_csg), the engine's flattened path
// Ray kinds (all aimed so that most meet the crown's bounds):
//   aimed      from a sphere around the plant to uniform points of its bounds
//   sun        parallel rays from a disk above the plant, 40 degrees elevation
//   bounce     from the sun rays' flattened hits, cosine-distributed about the
//              hit normal (photon bounces inside the crown)
// The summary (printed first) times graph, flat and flat_csg interleaved,
// `repeats` times, in thread CPU time, and reports the median ns/ray and the
// ratios graph / flat and graph / flat_csg; it also
// counts rays whose hits differ (t beyond 1e-5 relative, or hit vs miss).
#include <benchmark/benchmark.h>
#include <embree3/rtcore.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <time.h>

#include "accel/surface_hit.h"
#include "csg/csg.h"
#include "csg/csg_geometry.h"
#include "lsystem/graph/graph.h"
#include "lsystem/language/lsystem.h"

namespace {

using plm::Vec3d;
namespace ls = plm::lsystem;

const char* kTree =
    "const r1 = 0.9\n"
    "const r2 = 0.7\n"
    "const a1 = 10\n"
    "const a2 = 60\n"
    "const wr = 0.707\n"
    "axiom: A(0, 0)\n"
    "A(i, j) -> !(0.1*wr^(i+j)) F(r1^i*r2^j) [ &(a1) B(i+1, j) ] /(180) [ &(a2) B(i, j+1) ]\n"
    "B(i, j) -> !(0.1*wr^(i+j)) F(r1^i*r2^j) [ +(a1) B(i+1, j) ] [ -(a2) B(i, j+1) ]\n";

int g_depth = 15;
size_t g_rays = 200000;
int g_repeats = 5;
long long g_budget = -1;  // < 0: GraphOptions' default
long long g_cache_bytes = -1;  // < 0: GraphOptions' default (64 MiB)

// ---- the flattened plant: csg::intersect per primitive in Embree's BVH ----

struct FlatPlant {
  std::vector<plm::csg::Primitive> prims;
};

void flat_bounds(const RTCBoundsFunctionArguments* a) {
  const FlatPlant& f = *static_cast<const FlatPlant*>(a->geometryUserPtr);
  const plm::csg::Primitive& p = f.prims[a->primID];
  RTCBounds* b = a->bounds_o;
  b->lower_x = std::nextafter(float(p.lo.x), -INFINITY);
  b->lower_y = std::nextafter(float(p.lo.y), -INFINITY);
  b->lower_z = std::nextafter(float(p.lo.z), -INFINITY);
  b->upper_x = std::nextafter(float(p.hi.x), INFINITY);
  b->upper_y = std::nextafter(float(p.hi.y), INFINITY);
  b->upper_z = std::nextafter(float(p.hi.z), INFINITY);
}

// The first crossing of primitive i with t in [tnear, tfar), as the graph does.
inline bool flat_first(const plm::csg::Primitive& p, Vec3d o, Vec3d d, double tnear, double tfar, double* t,
                       int* face) {
  plm::csg::Crossing cr[plm::csg::kMaxPrimitiveCrossings];
  const int n = plm::csg::intersect(p, o, d, 0.0, cr);
  for (int k = 0; k < n; ++k) {
    if (cr[k].t < tnear) continue;
    if (cr[k].t >= tfar) return false;
    *t = cr[k].t;
    *face = cr[k].face;
    return true;
  }
  return false;
}

void flat_intersect(const RTCIntersectFunctionNArguments* a) {
  const FlatPlant& f = *static_cast<const FlatPlant*>(a->geometryUserPtr);
  RTCRayN* rays = RTCRayHitN_RayN(a->rayhit, a->N);
  RTCHitN* hits = RTCRayHitN_HitN(a->rayhit, a->N);
  for (unsigned i = 0; i < a->N; ++i) {
    if (!a->valid[i]) continue;
    const Vec3d o{RTCRayN_org_x(rays, a->N, i), RTCRayN_org_y(rays, a->N, i), RTCRayN_org_z(rays, a->N, i)};
    const Vec3d d{RTCRayN_dir_x(rays, a->N, i), RTCRayN_dir_y(rays, a->N, i), RTCRayN_dir_z(rays, a->N, i)};
    const plm::csg::Primitive& p = f.prims[a->primID];
    double t;
    int face;
    if (!flat_first(p, o, d, RTCRayN_tnear(rays, a->N, i), RTCRayN_tfar(rays, a->N, i), &t, &face)) continue;
    const Vec3d n = plm::csg::normal(p, face, o + t * d);
    RTCRayN_tfar(rays, a->N, i) = float(t);
    RTCHitN_Ng_x(hits, a->N, i) = float(n.x);
    RTCHitN_Ng_y(hits, a->N, i) = float(n.y);
    RTCHitN_Ng_z(hits, a->N, i) = float(n.z);
    RTCHitN_u(hits, a->N, i) = float(face);
    RTCHitN_v(hits, a->N, i) = 0.0f;
    RTCHitN_primID(hits, a->N, i) = a->primID;
    RTCHitN_geomID(hits, a->N, i) = a->geomID;
    RTCHitN_instID(hits, a->N, i, 0) = a->context->instID[0];
  }
}

void flat_occluded(const RTCOccludedFunctionNArguments* a) {
  const FlatPlant& f = *static_cast<const FlatPlant*>(a->geometryUserPtr);
  for (unsigned i = 0; i < a->N; ++i) {
    if (!a->valid[i]) continue;
    const Vec3d o{RTCRayN_org_x(a->ray, a->N, i), RTCRayN_org_y(a->ray, a->N, i), RTCRayN_org_z(a->ray, a->N, i)};
    const Vec3d d{RTCRayN_dir_x(a->ray, a->N, i), RTCRayN_dir_y(a->ray, a->N, i), RTCRayN_dir_z(a->ray, a->N, i)};
    double t;
    int face;
    if (flat_first(f.prims[a->primID], o, d, RTCRayN_tnear(a->ray, a->N, i), RTCRayN_tfar(a->ray, a->N, i), &t, &face))
      RTCRayN_tfar(a->ray, a->N, i) = -INFINITY;
  }
}

struct Rays {
  std::vector<RTCRay> r;
};

struct Setup {
  RTCDevice device = nullptr;
  std::unique_ptr<ls::Graph> graph;
  FlatPlant flat;
  std::vector<std::unique_ptr<plm::csg::CsgObject>> solids;
  RTCScene graph_scene = nullptr, flat_scene = nullptr, csg_scene = nullptr;
  Rays aimed, sun, bounce;
  double setup_graph_s = 0, setup_flat_s = 0;

  Setup() {
    device = rtcNewDevice("threads=1");
    ls::GraphOptions o;
    o.depth = g_depth;
    if (g_budget >= 0) o.bounds_budget = size_t(g_budget);
    if (g_cache_bytes >= 0) o.cache_bytes = size_t(g_cache_bytes);
    auto t0 = std::chrono::steady_clock::now();
    graph = std::make_unique<ls::Graph>(ls::parse(kTree), o);
    graph_scene = rtcNewScene(device);
    ls::attach_graph(device, graph_scene, *graph);
    rtcCommitScene(graph_scene);
    setup_graph_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const ls::FlattenResult fr = graph->flatten();
    t0 = std::chrono::steady_clock::now();
    for (const ls::TurtlePrimitive& tp : fr.primitives) {
      plm::csg::PrimitiveDesc d;
      d.shape = plm::csg::Shape::Cylinder;  // the tree draws only cylinders
      std::copy(tp.to_world, tp.to_world + 12, d.to_world);
      flat.prims.push_back(plm::csg::make_primitive(d));
    }
    flat_scene = rtcNewScene(device);
    RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(g, unsigned(flat.prims.size()));
    rtcSetGeometryUserData(g, &flat);
    rtcSetGeometryBoundsFunction(g, flat_bounds, nullptr);
    rtcSetGeometryIntersectFunction(g, flat_intersect);
    rtcSetGeometryOccludedFunction(g, flat_occluded);
    rtcCommitGeometry(g);
    rtcAttachGeometry(flat_scene, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(flat_scene);
    setup_flat_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    csg_scene = rtcNewScene(device);
    for (size_t i = 0; i < fr.primitives.size(); ++i) {
      plm::csg::CsgDesc d;
      d.name = "c" + std::to_string(i);
      plm::csg::PrimitiveDesc p;
      p.shape = plm::csg::Shape::Cylinder;
      std::copy(fr.primitives[i].to_world, fr.primitives[i].to_world + 12, p.to_world);
      d.primitives.push_back(p);
      d.materials.push_back(0);
      d.nodes.push_back(plm::csg::NodeDesc{});
      solids.push_back(std::make_unique<plm::csg::CsgObject>(d));
      plm::csg::attach_csg(device, csg_scene, *solids.back());
    }
    rtcCommitScene(csg_scene);
    make_rays();
  }

  static RTCRay ray(Vec3d o, Vec3d d) {
    RTCRay r{};
    r.org_x = float(o.x);
    r.org_y = float(o.y);
    r.org_z = float(o.z);
    r.dir_x = float(d.x);
    r.dir_y = float(d.y);
    r.dir_z = float(d.z);
    r.tnear = 0;
    r.tfar = INFINITY;
    r.mask = 0xFFFFFFFF;
    r.flags = 0;
    return r;
  }

  void make_rays() {
    std::mt19937_64 rng(12345);
    std::uniform_real_distribution<double> u(0, 1);
    const Vec3d lo = graph->bounds_lo(), hi = graph->bounds_hi();
    // The flattened plant's own box (the graph's bounds may be looser).
    Vec3d flo{INFINITY, INFINITY, INFINITY}, fhi{-INFINITY, -INFINITY, -INFINITY};
    for (const auto& p : flat.prims) {
      flo = plm::min(flo, p.lo);
      fhi = plm::max(fhi, p.hi);
    }
    (void)lo;
    (void)hi;
    const Vec3d c = 0.5 * (flo + fhi);
    const double rad = 0.5 * plm::length(fhi - flo);
    auto on_sphere = [&] {
      const double z = 2 * u(rng) - 1, phi = 6.283185307179586 * u(rng), s = std::sqrt(1 - z * z);
      return Vec3d{s * std::cos(phi), s * std::sin(phi), z};
    };
    for (size_t i = 0; i < g_rays; ++i) {
      const Vec3d target{flo.x + u(rng) * (fhi.x - flo.x), flo.y + u(rng) * (fhi.y - flo.y),
                         flo.z + u(rng) * (fhi.z - flo.z)};
      const Vec3d o = c + 1.5 * rad * on_sphere();
      aimed.r.push_back(ray(o, plm::normalize(target - o)));
    }
    // Sun at 40 degrees elevation from azimuth 30 degrees; origins on a disk
    // perpendicular to it, covering the plant's bounding sphere.
    const double el = 40 * M_PI / 180, az = 30 * M_PI / 180;
    const Vec3d to_sun{std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)};
    Vec3d e1 = plm::normalize(plm::cross(to_sun, Vec3d{0, 0, 1}));
    Vec3d e2 = plm::cross(to_sun, e1);
    for (size_t i = 0; i < g_rays; ++i) {
      const double r = rad * std::sqrt(u(rng)), phi = 6.283185307179586 * u(rng);
      const Vec3d o = c + 2 * rad * to_sun + r * std::cos(phi) * e1 + r * std::sin(phi) * e2;
      sun.r.push_back(ray(o, -1.0 * to_sun));
    }
    // Bounces from the sun rays' hits on the flattened plant.
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    for (size_t i = 0, tries = 0; bounce.r.size() < g_rays && tries < 100 * g_rays; i = (i + 1) % sun.r.size(), ++tries) {
      RTCRayHit rh{};
      rh.ray = sun.r[i];
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(flat_scene, &ctx, &rh);
      if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
      const Vec3d n = plm::normalize(Vec3d{rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z});
      const Vec3d p = Vec3d{rh.ray.org_x, rh.ray.org_y, rh.ray.org_z} +
                      double(rh.ray.tfar) * Vec3d{rh.ray.dir_x, rh.ray.dir_y, rh.ray.dir_z};
      const double a = std::sqrt(u(rng)), phi = 6.283185307179586 * u(rng);
      Vec3d t = plm::normalize(plm::cross(std::fabs(n.x) > 0.5 ? Vec3d{0, 1, 0} : Vec3d{1, 0, 0}, n));
      Vec3d b = plm::cross(n, t);
      const Vec3d d = a * std::cos(phi) * t + a * std::sin(phi) * b + std::sqrt(std::max(0.0, 1 - a * a)) * n;
      bounce.r.push_back(ray(p + 1e-5 * rad * n, d));
    }
  }
};

Setup& setup() {
  static Setup s;
  return s;
}

// Traces all rays; returns hits (closest) or occluded count.
size_t trace(RTCScene scene, const Rays& rays, bool occlusion, std::vector<float>* t_out = nullptr) {
  plm::HitContext hits;  // the graph's closest-hit callback reads it (no GraphHit wanted)
  RTCIntersectContext& ctx = hits.context;
  size_t n = 0;
  for (size_t i = 0; i < rays.r.size(); ++i) {
    if (occlusion) {
      RTCRay r = rays.r[i];
      rtcOccluded1(scene, &ctx, &r);
      n += r.tfar < 0;
      if (t_out) (*t_out)[i] = r.tfar < 0 ? 1.0f : 0.0f;
    } else {
      RTCRayHit rh{};
      rh.ray = rays.r[i];
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(scene, &ctx, &rh);
      const bool hit = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
      n += hit;
      if (t_out) (*t_out)[i] = hit ? rh.ray.tfar : -1.0f;
    }
  }
  return n;
}

// Thread CPU seconds (less sensitive than wall time to other processes on a shared machine).
double cpu_now() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

double seconds_of(RTCScene scene, const Rays& rays, bool occlusion) {
  const double t0 = cpu_now();
  benchmark::DoNotOptimize(trace(scene, rays, occlusion));
  return cpu_now() - t0;
}

void summary() {
  Setup& s = setup();
  const ls::GraphStats gs = s.graph->stats();
  std::printf("SYMPODIAL_TREE depth %d: %zu cylinders, %zu graph classes; set-up graph %.3f s, flat BVH %.3f s\n",
              g_depth, s.flat.prims.size(), gs.classes, s.setup_graph_s, s.setup_flat_s);
  const Vec3d glo = s.graph->bounds_lo(), ghi = s.graph->bounds_hi();
  Vec3d flo{INFINITY, INFINITY, INFINITY}, fhi{-INFINITY, -INFINITY, -INFINITY};
  for (const auto& p : s.flat.prims) {
    flo = plm::min(flo, p.lo);
    fhi = plm::max(fhi, p.hi);
  }
  auto vol = [](Vec3d a, Vec3d b) { return (b.x - a.x) * (b.y - a.y) * (b.z - a.z); };
  std::printf("root bounds volume: graph %.4g, flattened primitives %.4g (ratio %.3f)\n", vol(glo, ghi),
              vol(flo, fhi), vol(glo, ghi) / vol(flo, fhi));
  std::printf("%-7s %-9s %8s %9s %9s %9s %7s %7s %9s\n", "rays", "query", "hits", "graph ns", "flat ns",
              "csg ns", "g/flat", "g/csg", "differ");
  const struct {
    const char* name;
    const Rays* rays;
  } kinds[] = {{"aimed", &s.aimed}, {"sun", &s.sun}, {"bounce", &s.bounce}};
  for (const auto& k : kinds)
    for (int occ = 0; occ < 2; ++occ) {
      const size_t n = k.rays->r.size();
      std::vector<float> tg(n), tf(n);
      const size_t hits = trace(s.graph_scene, *k.rays, occ, &tg);
      trace(s.flat_scene, *k.rays, occ, &tf);
      size_t differ = 0;
      for (size_t i = 0; i < n; ++i)
        if ((tg[i] < 0) != (tf[i] < 0) || std::fabs(tg[i] - tf[i]) > 1e-5f * std::max(1.0f, std::fabs(tf[i])))
          ++differ;
      std::vector<double> g, f, c;
      for (int r = 0; r < g_repeats; ++r) {
        g.push_back(seconds_of(s.graph_scene, *k.rays, occ));
        f.push_back(seconds_of(s.flat_scene, *k.rays, occ));
        c.push_back(seconds_of(s.csg_scene, *k.rays, occ));
      }
      auto median = [](std::vector<double> v) {
        std::sort(v.begin(), v.end());
        return v[v.size() / 2];
      };
      const double gn = median(g) / double(n) * 1e9, fn = median(f) / double(n) * 1e9, cn = median(c) / double(n) * 1e9;
      std::printf("%-7s %-9s %8zu %9.1f %9.1f %9.1f %7.3f %7.3f %9zu\n", k.name, occ ? "occluded" : "closest", hits,
                  gn, fn, cn, gn / fn, gn / cn, differ);
    }
  const ls::GraphStats after = s.graph->stats();
  std::printf("graph cache (limit %lld bytes): %zu entries, %.3f MB, peak %.3f MB, hit rate %.4f, %llu misses (%llu not admitted)\n",
              g_cache_bytes < 0 ? (long long)ls::GraphOptions{}.cache_bytes : g_cache_bytes, after.cached_entries,
              double(after.cached_bytes) / 1e6, double(after.peak_cached_bytes) / 1e6,
              double(after.cache_hits) / double(std::max<uint64_t>(1, after.cache_hits + after.cache_misses)),
              (unsigned long long)after.cache_misses, (unsigned long long)after.bypassed);
  std::fflush(stdout);
}

void BM_Rays(benchmark::State& state, int variant, int kind, bool occlusion) {
  Setup& s = setup();
  const RTCScene scene[] = {s.graph_scene, s.flat_scene, s.csg_scene};
  const Rays* rays[] = {&s.aimed, &s.sun, &s.bounce};
  for (auto _ : state) benchmark::DoNotOptimize(trace(scene[variant], *rays[kind], occlusion));
  // Seconds per ray (printed with an SI prefix: 250n = 250 ns).
  state.counters["per_ray"] = benchmark::Counter(double(rays[kind]->r.size()),
                                                 benchmark::Counter::kIsIterationInvariantRate |
                                                     benchmark::Counter::kInvert);
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<char*> rest;
  bool summary_only = false, no_summary = false;
  for (int i = 0; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--depth" && i + 1 < argc) {
      g_depth = std::atoi(argv[++i]);
    } else if (a == "--rays" && i + 1 < argc) {
      g_rays = size_t(std::atoll(argv[++i]));
    } else if (a == "--repeats" && i + 1 < argc) {
      g_repeats = std::max(1, std::atoi(argv[++i]));
    } else if (a == "--bounds-budget" && i + 1 < argc) {
      g_budget = std::atoll(argv[++i]);
    } else if (a == "--cache-bytes" && i + 1 < argc) {
      g_cache_bytes = std::atoll(argv[++i]);
    } else if (a == "--summary") {
      summary_only = true;
    } else if (a == "--no-summary") {
      no_summary = true;
    } else {
      rest.push_back(argv[i]);
    }
  }
  if (!no_summary) summary();
  if (summary_only) return 0;
  const char* variants[] = {"graph", "flat", "flat_csg"};
  const char* kinds[] = {"aimed", "sun", "bounce"};
  for (int v = 0; v < 3; ++v)
    for (int k = 0; k < 3; ++k)
      for (int occ = 0; occ < 2; ++occ)
        benchmark::RegisterBenchmark((std::string("BM_Rays/") + variants[v] + "/" + kinds[k] + (occ ? "/occluded" : "/closest")).c_str(),
                                     BM_Rays, v, k, occ != 0)
            ->Unit(benchmark::kMillisecond);
  int n = int(rest.size());
  benchmark::Initialize(&n, rest.data());
  benchmark::RunSpecifiedBenchmarks();
  return 0;
}

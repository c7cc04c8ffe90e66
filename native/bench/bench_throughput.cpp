// Photon-pass throughput against raw Embree on statistically the same rays,
// and the direct pass's rays one by one against packets of eight.
//   build/bin/photonlm_bench_throughput
// 1. The engine bakes the Cornell box, photons only, one thread: rays/s of the
//    photon pass (emission, intersection, deposit, bounce, merge).
// 2. The same emitters and bounce rules generate the same number of rays,
//    recorded; then Embree alone casts them (rtcIntersect1, one thread).
// The ratio is the share of raw ray-casting speed the photon pass keeps.
// Both sides are timed by the wall clock (the photon pass's own
// seconds_trace) and by process CPU time (the whole plm_bake call, set-up
// included, for the engine): on a shared machine the wall clock also counts
// time the process waited for a core. The two sides alternate in rounds
// and each counter is a median over the rounds (see the benchmark).
#include <benchmark/benchmark.h>

#include <time.h>

#include <algorithm>
#include <chrono>
#include <limits>
#include <vector>

#include "accel/embree_scene.h"
#include "api/handles.h"
#include "demo_scenes.h"
#include "transport/lights/emitters.h"
#include "transport/rays/tracing.h"
#include "util/rng.h"

namespace {

double process_cpu_seconds() {
  timespec t;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

// The q-quantile of v (sorted in place), by the nearest rank.
double quantile(std::vector<double>& v, double q) {
  std::sort(v.begin(), v.end());
  return v[size_t(q * double(v.size() - 1) + 0.5)];
}

struct Recorded {
  std::vector<plm::Vec3> org, dir;
};

// Photon paths as the engine traces them (light choice by power, cosine
// bounces, Russian roulette on albedo), recording every ray.
Recorded record_rays(const plm::Scene& scene, const plm::EmbreeScene& accel, uint64_t rays_wanted) {
  using namespace plm;
  const Vec3 lo = accel.bounds_min(), hi = accel.bounds_max();
  const std::vector<Emitter> emitters = build_emitters(scene, (lo + hi) * 0.5f, 0.5f * length(hi - lo) * 1.01f);
  std::vector<double> cdf;
  double total = 0.0;
  for (const Emitter& e : emitters) cdf.push_back(total += average(e.flux));
  Recorded out;
  TraceContext tc;
  for (uint64_t i = 0; out.org.size() < rays_wanted; ++i) {
    Rng rng(7, i);
    const double u_pick = rng.next_float() * total;
    size_t k = 0;
    while (k + 1 < cdf.size() && cdf[k] < u_pick) ++k;
    const float u[4] = {rng.next_float(), rng.next_float(), rng.next_float(), rng.next_float()};
    const EmitterSample s = sample_emitter(emitters[k], u);
    Vec3 org = s.origin, dir = s.direction;
    tc.skip_geom = tc.skip_prim = RTC_INVALID_GEOMETRY_ID;
    while (out.org.size() < rays_wanted) {
      out.org.push_back(org);
      out.dir.push_back(dir);
      RTCRayHit rh;
      rh.ray = make_ray(org, dir, std::numeric_limits<float>::infinity());
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(accel.handle(), tc.context(), &rh);
      if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) break;
      const Mesh& mesh = scene.meshes[rh.hit.geomID];
      const uint32_t tri = rh.hit.primID;
      const Vec3 p0 = mesh.vertex(tri, 0), p1 = mesh.vertex(tri, 1), p2 = mesh.vertex(tri, 2);
      const Vec3 hit = p0 * (1.0f - rh.hit.u - rh.hit.v) + p1 * rh.hit.u + p2 * rh.hit.v;
      Vec3 n = normalize(cross(p1 - p0, p2 - p0));
      if (dot(n, dir) > 0.0f) n = -n;
      const float q = max_component(scene.materials[mesh.material_ids[tri]].albedo);
      if (rng.next_float() >= q) break;
      const Vec3 local = cosine_hemisphere(rng.next_float(), rng.next_float());
      Vec3 t, b;
      make_frame(n, t, b);
      dir = t * local.x + b * local.y + n * local.z;
      org = offset_origin(hit, n, 1e-6f * length(hi - lo));
      tc.skip_geom = rh.hit.geomID;
      tc.skip_prim = tri;
    }
  }
  return out;
}

// One round = one engine bake, then raw Embree on as many recorded rays,
// back to back, so both see the host at the same speed; the counters are
// medians over the rounds of each round's own ratio (a shared machine's
// speed drifts by several percent within seconds, more than the effects
// measured here). Wall clock: the engine's seconds_trace against the raw
// loop; CPU time: the whole plm_bake call (set-up included) against the raw
// loop. state.range(0): photons per round.
void BM_PhotonPassVersusRawEmbree(benchmark::State& state) {
  constexpr int kRounds = 15;
  plm_demo::SceneBuilder b;
  plm_demo::build_cornell(b, 32);
  plm_bake_settings s;
  plm_bake_settings_default(&s);
  s.photon_count = uint64_t(state.range(0));
  s.thread_count = 1;
  s.direct_samples = 0;  // every ray is a photon ray
  s.filter_radius = 0;
  const plm::Scene& scene = b.scene->scene;
  plm::EmbreeScene accel(scene, 1);
  Recorded rays;
  std::vector<double> share, cpu_share, engine_rate, raw_rate;
  for (auto _ : state) {
    for (int round = 0; round < kRounds; ++round) {
      plm_result* r = nullptr;
      const double c0 = process_cpu_seconds();
      if (plm_bake(b.scene, &s, nullptr, nullptr, &r) != PLM_OK) {
        state.SkipWithError(plm_last_error());
        return;
      }
      const double engine_cpu = process_cpu_seconds() - c0;
      const plm_bake_stats st = r->output.stats;
      plm_result_release(r);
      if (rays.org.empty()) rays = record_rays(scene, accel, st.rays_traced);  // the same count every round

      plm::TraceContext tc;
      const double rc0 = process_cpu_seconds();
      const auto t0 = std::chrono::steady_clock::now();
      uint64_t hits = 0;
      for (size_t i = 0; i < rays.org.size(); ++i) {
        RTCRayHit rh;
        rh.ray = plm::make_ray(rays.org[i], rays.dir[i], std::numeric_limits<float>::infinity());
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(accel.handle(), tc.context(), &rh);
        hits += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
      }
      const double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      const double raw_cpu = process_cpu_seconds() - rc0;
      benchmark::DoNotOptimize(hits);
      const double n = double(rays.org.size());
      share.push_back(100.0 * dt / st.seconds_trace);
      cpu_share.push_back(100.0 * raw_cpu / engine_cpu);
      engine_rate.push_back(n / engine_cpu * 1e-6);
      raw_rate.push_back(n / raw_cpu * 1e-6);
    }
  }
  state.counters["engine_share_pct"] = quantile(share, 0.5);
  state.counters["engine_cpu_share_pct"] = quantile(cpu_share, 0.5);
  state.counters["cpu_share_q1"] = quantile(cpu_share, 0.25);
  state.counters["cpu_share_q3"] = quantile(cpu_share, 0.75);
  state.counters["engine_cpu_Mrays_per_s"] = quantile(engine_rate, 0.5);
  state.counters["raw_embree_cpu_Mrays_per_s"] = quantile(raw_rate, 0.5);
}
BENCHMARK(BM_PhotonPassVersusRawEmbree)->Arg(1000000)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);

// Rays as the direct pass and the final gather cast them: 16 points in each
// of the Cornell floor's 32 x 32 texels, a shadow ray from each to a point on
// the ceiling light and a cosine-distributed gather ray; one by one
// (rtcOccluded1 / rtcIntersect1) against plm::RayPacket (eight rays of one
// texel per call). Counters: ns per ray, best of the iterations.
void BM_TexelRaysOneByOneVersusPackets(benchmark::State& state) {
  using namespace plm;
  plm_demo::SceneBuilder b;
  plm_demo::build_cornell(b, 32);
  const Scene& scene = b.scene->scene;
  EmbreeScene accel(scene, 1);
  std::vector<Vec3> org, to_light, gather;
  Rng rng(11, 0);
  for (int texel = 0; texel < 32 * 32; ++texel) {
    for (int j = 0; j < 16; ++j) {
      const Vec3 p{-1.0f + (float(texel % 32) + rng.next_float()) / 16.0f,
                   -1.0f + (float(texel / 32) + rng.next_float()) / 16.0f, 1e-4f};
      const Vec3 q{0.5f * rng.next_float() - 0.25f, 0.5f * rng.next_float() - 0.25f, 1.98f};
      org.push_back(p);
      to_light.push_back(q - p);  // tfar 1: up to the light
      gather.push_back(cosine_hemisphere(rng.next_float(), rng.next_float()));
    }
  }
  const float inf = std::numeric_limits<float>::infinity();
  double best[4] = {inf, inf, inf, inf};
  uint64_t counts[4] = {};
  auto time = [&](int slot, auto&& cast) {
    const auto t0 = std::chrono::steady_clock::now();
    counts[slot] = cast();
    best[slot] = std::min(best[slot], std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  };
  for (auto _ : state) {
    TraceContext tc;
    RayPacket packet;
    time(0, [&] {
      uint64_t n = 0;
      for (size_t i = 0; i < org.size(); ++i) {
        RTCRay r = make_ray(org[i], to_light[i], 0.9999f);
        rtcOccluded1(accel.handle(), tc.context(), &r);
        n += r.tfar < 0.0f;
      }
      return n;
    });
    time(1, [&] {
      uint64_t n = 0;
      for (size_t i = 0; i < org.size(); i += RayPacket::kLanes) {
        for (size_t l = i; l < i + RayPacket::kLanes; ++l)
          packet.add(org[l], to_light[l], 0.9999f, RTC_INVALID_GEOMETRY_ID, RTC_INVALID_GEOMETRY_ID);
        packet.occluded(accel.handle());
        for (unsigned l = 0; l < RayPacket::kLanes; ++l) n += packet.blocked(l);
      }
      return n;
    });
    time(2, [&] {
      uint64_t n = 0;
      for (size_t i = 0; i < org.size(); ++i) {
        RTCRayHit rh;
        rh.ray = make_ray(org[i], gather[i], inf);
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(accel.handle(), tc.context(), &rh);
        n += rh.hit.geomID;
      }
      return n;
    });
    time(3, [&] {
      uint64_t n = 0;
      for (size_t i = 0; i < org.size(); i += RayPacket::kLanes) {
        for (size_t l = i; l < i + RayPacket::kLanes; ++l)
          packet.add(org[l], gather[l], inf, RTC_INVALID_GEOMETRY_ID, RTC_INVALID_GEOMETRY_ID);
        packet.intersect(accel.handle());
        for (unsigned l = 0; l < RayPacket::kLanes; ++l) n += packet.rh.hit.geomID[l];
      }
      return n;
    });
  }
  if (counts[0] != counts[1] || counts[2] != counts[3]) state.SkipWithError("packets and single rays disagree");
  const double ns = 1e9 / double(org.size());
  state.counters["shadow_one_ns"] = best[0] * ns;
  state.counters["shadow_packet_ns"] = best[1] * ns;
  state.counters["gather_one_ns"] = best[2] * ns;
  state.counters["gather_packet_ns"] = best[3] * ns;
  state.counters["shadow_speedup"] = best[0] / best[1];
  state.counters["gather_speedup"] = best[2] / best[3];
}
BENCHMARK(BM_TexelRaysOneByOneVersusPackets)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(20);

}  // namespace

BENCHMARK_MAIN();


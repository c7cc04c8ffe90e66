// Speed against error: photons per second and the furnace error they reach.
//   build/bin/photonlm_bench --benchmark_counters_tabular=true
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "demo_scenes.h"

namespace {

void BM_FurnaceBake(benchmark::State& state) {
  const float rho = 0.5f;
  plm_demo::SceneBuilder b;
  plm_demo::build_furnace(b, rho, 1.0f, 16);
  plm_bake_settings s;
  plm_bake_settings_default(&s);
  s.photon_count = uint64_t(state.range(0));
  double rel_error = 0.0;
  for (auto _ : state) {
    plm_result* r = nullptr;
    if (plm_bake(b.scene, &s, nullptr, nullptr, &r) != PLM_OK) {
      state.SkipWithError(plm_last_error());
      return;
    }
    std::vector<float> rgb(48 * 32 * 3), cov(48 * 32);
    plm_result_copy_lightmap(r, 0, rgb.data(), nullptr, nullptr, cov.data());
    double err = 0, n = 0;
    for (size_t t = 0; t < cov.size(); ++t) {
      if (cov[t] < 1.0f) continue;
      const double d = rgb[3 * t] - 1.0 / (1.0 - rho);
      err += d * d;
      n += 1;
    }
    rel_error = std::sqrt(err / n) * (1.0 - rho);
    plm_result_release(r);
  }
  state.counters["photons_per_s"] = benchmark::Counter(double(s.photon_count), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["texel_rmse_rel"] = rel_error;
}
BENCHMARK(BM_FurnaceBake)->Arg(250000)->Arg(1000000)->Arg(4000000)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_CornellBake(benchmark::State& state) {
  plm_demo::SceneBuilder b;
  plm_demo::build_cornell(b, 32);
  plm_bake_settings s;
  plm_bake_settings_default(&s);
  s.photon_count = uint64_t(state.range(0));
  uint64_t rays = 0;
  for (auto _ : state) {
    plm_result* r = nullptr;
    if (plm_bake(b.scene, &s, nullptr, nullptr, &r) != PLM_OK) {
      state.SkipWithError(plm_last_error());
      return;
    }
    plm_bake_stats st{};
    st.struct_size = sizeof st;
    plm_result_stats(r, &st);
    rays = st.rays_traced;
    plm_result_release(r);
  }
  state.counters["photons_per_s"] = benchmark::Counter(double(s.photon_count), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["rays_per_s"] = benchmark::Counter(double(rays), benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_CornellBake)->Arg(1000000)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();

// The C API driven from several threads at once, as a host application does:
// bakes of a small textured scene (an albedo image on the floor, an emission
// image on a panel), cancels from the progress callback at random moments,
// re-bakes of a scene right after its bake was cancelled, EXR writes, and
// scenes and results released in either order, results handed to other
// threads before they are read and released. Every finished bake must give
// finite, non-negative lightmaps; every cancelled one no result and a message.
// Under AddressSanitizer (scripts/test.sh, every check on) this catches heap
// misuse in the bake's set-up and tear-down, including inside the libraries
// the engine calls. About 3 s in Release.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "photonlm/photonlm.h"

namespace {

using Clock = std::chrono::steady_clock;

constexpr int kThreads = 4;
constexpr double kSeconds = 2.5;   // each thread starts new bakes for this long...
constexpr int kMinIterations = 6;  // ...and does at least this many (slow sanitizer builds)

const std::string& temp_dir() {
  static const std::string dir = [] {
    std::string d = testing::TempDir() + "photonlm_api_threads_" + std::to_string(getpid());
    EXPECT_TRUE(::mkdir(d.c_str(), 0700) == 0 || errno == EEXIST) << d;
    return d;
  }();
  return dir;
}

// A w x h binary PPM: a checker of colours a and b with cells x cells squares.
std::string write_checker(const std::string& name, int w, int h, int cells, const unsigned char a[3],
                          const unsigned char b[3]) {
  const std::string path = temp_dir() + "/" + name;
  std::ofstream f(path, std::ios::binary);
  f << "P6\n" << w << " " << h << "\n255\n";
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const unsigned char* c = ((x * cells / w + y * cells / h) % 2) ? b : a;
      f.write(reinterpret_cast<const char*>(c), 3);
    }
  EXPECT_TRUE(f.good()) << path;
  return path;
}

struct Images {
  std::string albedo, emission;
};

const Images& images() {
  static const Images im = [] {
    const unsigned char red[3] = {230, 40, 30}, white[3] = {240, 240, 240};
    const unsigned char warm[3] = {255, 200, 120}, dark[3] = {20, 20, 20};
    return Images{write_checker("albedo.ppm", 32, 24, 4, red, white), write_checker("emission.ppm", 16, 16, 2, warm, dark)};
  }();
  return im;
}

// Two triangles (0, 1, 2), (0, 2, 3) of a quad and their corner UVs, scaled by s.
const uint32_t kQuadIndices[6] = {0, 1, 2, 0, 2, 3};
std::vector<float> quad_uv(float s) { return {0, 0, s, 0, s, s, 0, 0, s, s, 0, s}; }

// A floor with an albedo texture, an emissive panel above it with an emission texture, a plain
// wall, a point light and a grey world. Mesh 0 is the floor.
plm_scene* make_scene() {
  plm_scene* s = nullptr;
  EXPECT_EQ(plm_scene_create(&s), PLM_OK) << plm_last_error();
  const float white[3] = {1, 1, 1}, grey[3] = {0.7f, 0.7f, 0.7f}, none[3] = {0, 0, 0}, glow[3] = {3, 3, 3};
  uint32_t floor_mat = 0, panel_mat = 0, wall_mat = 0;
  EXPECT_EQ(plm_scene_add_material(s, "floor", white, none, &floor_mat), PLM_OK) << plm_last_error();
  EXPECT_EQ(plm_scene_add_material(s, "panel", grey, glow, &panel_mat), PLM_OK) << plm_last_error();
  EXPECT_EQ(plm_scene_add_material(s, "wall", grey, none, &wall_mat), PLM_OK) << plm_last_error();
  EXPECT_EQ(plm_scene_set_material_texture(s, floor_mat, PLM_TEXTURE_ALBEDO, images().albedo.c_str(),
                                           PLM_TEXTURE_COLOR_AUTO), PLM_OK) << plm_last_error();
  EXPECT_EQ(plm_scene_set_material_texture(s, panel_mat, PLM_TEXTURE_EMISSION, images().emission.c_str(),
                                           PLM_TEXTURE_COLOR_LINEAR), PLM_OK) << plm_last_error();
  struct Quad {
    const char* name;
    float p[12];
    uint32_t material, res;
    float texture_scale;  // 0: no texture UVs
  } quads[] = {
      {"floor", {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0}, floor_mat, 16, 3.0f},
      {"panel", {-0.3f, -0.3f, 1.5f, -0.3f, 0.3f, 1.5f, 0.3f, 0.3f, 1.5f, 0.3f, -0.3f, 1.5f}, panel_mat, 8, 1.0f},
      {"wall", {-1, -1, 0, -1, 1, 0, -1, 1, 2, -1, -1, 2}, wall_mat, 8, 0.0f},
  };
  const std::vector<float> lightmap_uv = quad_uv(1.0f);
  for (const Quad& q : quads) {
    const uint32_t mats[2] = {q.material, q.material};
    uint32_t id = 0;
    EXPECT_EQ(plm_scene_add_mesh(s, q.name, q.p, 4, kQuadIndices, 2, lightmap_uv.data(), mats, q.res, q.res, &id),
              PLM_OK) << plm_last_error();
    if (q.texture_scale > 0) {
      EXPECT_EQ(plm_scene_set_mesh_texture_uv(s, id, quad_uv(q.texture_scale).data()), PLM_OK) << plm_last_error();
    }
  }
  plm_light light;
  plm_light_default(&light, PLM_LIGHT_POINT);
  light.power = 60.0f;
  light.matrix[3] = 0.4f;
  light.matrix[7] = 0.2f;
  light.matrix[11] = 1.2f;
  EXPECT_EQ(plm_scene_add_light(s, "lamp", &light, nullptr), PLM_OK) << plm_last_error();
  const float sky[3] = {0.1f, 0.12f, 0.15f};
  EXPECT_EQ(plm_scene_set_world(s, sky), PLM_OK) << plm_last_error();
  return s;
}

// When the progress callback cancels: never, after a number of calls, or once a moment has passed.
struct Cancel {
  int after_calls = -1;                     // -1: not by calls
  Clock::time_point at = Clock::time_point::max();
  int calls = 0;
  bool fired = false;
};

int progress(void* user, double fraction, const char* stage) {
  Cancel& c = *static_cast<Cancel*>(user);
  EXPECT_TRUE(fraction >= 0.0 && fraction <= 1.0) << fraction;
  EXPECT_TRUE(stage != nullptr);
  const bool stop = (c.after_calls >= 0 && c.calls >= c.after_calls) || Clock::now() >= c.at;
  ++c.calls;
  c.fired = c.fired || stop;
  return stop ? 0 : 1;
}

// Results finished by one thread and read and released by another.
struct Pool {
  std::mutex mutex;
  std::vector<plm_result*> results;
  void put(plm_result* r) {
    std::lock_guard<std::mutex> lock(mutex);
    results.push_back(r);
  }
  plm_result* take(std::mt19937& rng) {
    std::lock_guard<std::mutex> lock(mutex);
    if (results.empty()) return nullptr;
    const size_t i = rng() % results.size();
    plm_result* r = results[i];
    results[i] = results.back();
    results.pop_back();
    return r;
  }
};

struct Counts {
  std::atomic<int> bakes{0}, finished{0}, cancelled{0}, handed_over{0}, exrs{0};
};

// Reads a finished result (the floor's lightmap, stats, warnings, maybe an EXR) and releases it.
void check_and_release(plm_result* r, std::mt19937& rng, Counts& counts, int thread) {
  uint32_t w = 0, h = 0;
  ASSERT_EQ(plm_result_lightmap_size(r, 0, &w, &h), PLM_OK) << plm_last_error();
  ASSERT_EQ(w, 16u);
  ASSERT_EQ(h, 16u);
  std::vector<float> rgb(size_t(w) * h * 3), error(size_t(w) * h);
  ASSERT_EQ(plm_result_copy_lightmap(r, 0, rgb.data(), error.data(), nullptr, nullptr), PLM_OK) << plm_last_error();
  double sum = 0;
  for (float v : rgb) {
    ASSERT_TRUE(std::isfinite(v) && v >= 0.0f) << v;
    sum += v;
  }
  for (float e : error) ASSERT_TRUE(std::isfinite(e) && e >= 0.0f) << e;
  EXPECT_GT(sum, 0.0) << "the floor is lit";
  plm_bake_stats st{};
  st.struct_size = sizeof st;
  ASSERT_EQ(plm_result_stats(r, &st), PLM_OK);
  EXPECT_GT(st.photons_emitted, 0u);
  for (uint32_t i = 0; i < plm_result_warning_count(r); ++i) EXPECT_NE(plm_result_warning(r, i), nullptr);
  if (rng() % 4 == 0) {
    const std::string path = temp_dir() + "/floor_" + std::to_string(thread) + ".exr";
    EXPECT_EQ(plm_result_write_exr(r, 0, path.c_str()), PLM_OK) << plm_last_error();
    std::remove(path.c_str());
    counts.exrs++;
  }
  plm_result_release(r);
}

void worker(int thread, Pool& pool, Counts& counts, Clock::time_point end) {
  std::mt19937 rng(1234u + 97u * unsigned(thread));
  plm_scene* scene = nullptr;
  for (int it = 0; it < kMinIterations || Clock::now() < end; ++it) {
    if (!scene) scene = make_scene();
    plm_bake_settings settings;
    plm_bake_settings_default(&settings);
    settings.photon_count = 10000 + rng() % 40000;
    settings.max_bounces = 4 + rng() % 8;
    settings.seed = rng();
    const uint32_t thread_counts[3] = {0, 1, 2};
    settings.thread_count = thread_counts[rng() % 3];
    settings.direct_samples = rng() % 3 == 0 ? 0 : 2;
    settings.dilation = 2;
    if (rng() % 4 == 0) settings.target_error = 0.2;  // stop at an error target, photon_count the cap

    // The first two bakes of each thread finish and cancel at once; then any mix.
    Cancel cancel;
    const int kind = it == 0 ? 0 : it == 1 ? 1 : int(rng() % 5);
    if (kind == 1 || kind == 2) cancel.after_calls = int(rng() % (kind == 1 ? 1 : 8));
    if (kind == 3) cancel.at = Clock::now() + std::chrono::microseconds(rng() % 40000);
    plm_result* result = nullptr;
    const plm_status status = plm_bake(scene, &settings, progress, &cancel, &result);
    counts.bakes++;
    if (status == PLM_ERROR_CANCELLED) {
      EXPECT_TRUE(cancel.fired) << "cancelled without being asked";
      EXPECT_EQ(result, nullptr);
      EXPECT_NE(std::string(plm_last_error()).find("cancelled"), std::string::npos) << plm_last_error();
      counts.cancelled++;
      // Half the time the same scene bakes again right away; else it is released first.
      if (rng() % 2) {
        plm_scene_release(scene);
        scene = nullptr;
      }
    } else {
      ASSERT_EQ(status, PLM_OK) << plm_last_error();
      ASSERT_NE(result, nullptr);
      counts.finished++;
      // The result outlives its scene; it is read here or by another thread.
      if (rng() % 2) {
        plm_scene_release(scene);
        scene = nullptr;
      }
      if (rng() % 2) {
        pool.put(result);
        counts.handed_over++;
      } else {
        check_and_release(result, rng, counts, thread);
      }
    }
    if (plm_result* other = pool.take(rng)) check_and_release(other, rng, counts, thread);
  }
  plm_scene_release(scene);
}

}  // namespace

TEST(ApiThreads, ConcurrentBakesCancelsAndReleases) {
  images();  // written once, before the threads start
  Pool pool;
  Counts counts;
  const Clock::time_point t0 = Clock::now();
  const Clock::time_point end = t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(kSeconds));
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) threads.emplace_back(worker, t, std::ref(pool), std::ref(counts), end);
  for (std::thread& t : threads) t.join();
  std::mt19937 rng(5);
  while (plm_result* r = pool.take(rng)) check_and_release(r, rng, counts, 0);
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  std::printf("%d threads, %.2f s: %d bakes, %d finished, %d cancelled, %d results read by another thread, %d EXRs\n",
              kThreads, seconds, counts.bakes.load(), counts.finished.load(), counts.cancelled.load(),
              counts.handed_over.load(), counts.exrs.load());
  EXPECT_GE(counts.bakes.load(), kThreads * kMinIterations);
  EXPECT_GE(counts.finished.load(), kThreads);
  EXPECT_GE(counts.cancelled.load(), kThreads);
}

// `photonlm bake`: scene file in, lightmaps and a report out (docs/scene-file.md).
// Ctrl-C (or SIGTERM) cancels the bake through the progress callback; files of
// an interrupted run are removed, so a folder holds either a whole bake or none.
#include "bake_command.h"

#include <nlohmann/json.hpp>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <set>
#include <string>
#include <vector>

#include "io/scene_file.h"
#include "photonlm/photonlm.h"

namespace plm_cli {

namespace {

using ordered_json = nlohmann::ordered_json;

constexpr int kOk = 0, kBadInput = 1, kBakeFailed = 2, kInterrupted = 130;

volatile std::sig_atomic_t g_interrupted = 0;

void on_signal(int sig) {
  g_interrupted = 1;
  std::signal(sig, SIG_DFL);  // a second Ctrl-C ends the process at once
}

struct Args {
  std::string scene, out_dir;
  uint32_t shard = 0, shard_count = 0;  // --shard K/N: shard K - 1 of N; 0 = not sharded
  // --direct K/N or --gather K/N: texel range K - 1 of N; 0 = none
  uint32_t range = 0, range_count = 0;
  int stage = -1;  // PLM_TEXELS_DIRECT or PLM_TEXELS_GATHER with a range
  std::vector<std::string> parts;  // --parts: what the gather reads (default: the output folder)
  bool has_target = false, has_budget = false, has_photons = false, has_seed = false, has_threads = false;
  int directional = -1;  // --directional on|off; -1: as the scene file says
  double target_error = 0, time_budget = 0;
  uint64_t photons = 0;
  uint32_t seed = 0, threads = 0;
  plm::SceneFileOptions read;  // --max-file-mb
};

int bad_input(const std::string& message) {
  std::fprintf(stderr, "photonlm bake: %s\n", message.c_str());
  return kBadInput;
}

bool parse_u64(const char* s, uint64_t max, uint64_t& out) {
  if (!*s || *s == '-' || std::isspace((unsigned char)*s)) return false;
  char* end = nullptr;
  errno = 0;
  const unsigned long long v = std::strtoull(s, &end, 10);
  if (*end || errno == ERANGE || v > max) return false;
  out = v;
  return true;
}

bool parse_seconds(const char* s, double& out) {
  char* end = nullptr;
  const double v = std::strtod(s, &end);
  if (!*s || *end || !(v >= 0) || !std::isfinite(v)) return false;
  out = v;
  return true;
}

}  // namespace

std::string parse_max_file_mb(const std::string& value, plm::SceneFileOptions& options) {
  uint64_t mb = 0;
  if (!parse_u64(value.c_str(), uint64_t(1) << 30, mb) || mb == 0)
    return "--max-file-mb: '" + value + "' is not an integer in [1, 2^30]";
  options.limits.max_file_bytes = mb << 20;
  return "";
}

bool read_scene(const std::string& path, const plm::SceneFileOptions& options, plm::SceneFile& scene,
                std::string& error) {
  if (plm::read_scene_file(path, options, scene, error)) return true;
  if (error.find("larger than the limit of") != std::string::npos)
    error += " (" + std::to_string(options.limits.max_file_bytes >> 20) + " MiB; --max-file-mb N raises it)";
  return false;
}

namespace {

// Returns "" or the error.
std::string parse_args(int argc, char** argv, Args& a) {
  for (int i = 0; i < argc; ++i) {
    const std::string opt = argv[i];
    if (opt.empty() || opt[0] != '-') {
      if (!a.scene.empty()) return "more than one scene file (" + a.scene + ", " + opt + ")";
      a.scene = opt;
      continue;
    }
    if (i + 1 >= argc) return "option " + opt + " needs a value";
    const char* v = argv[++i];
    uint64_t u = 0;
    if (opt == "-o" || opt == "--out") {
      a.out_dir = v;
    } else if (opt == "--target-error") {
      if (!parse_seconds(v, a.target_error)) return "--target-error: '" + std::string(v) + "' is not a number >= 0";
      a.has_target = true;
    } else if (opt == "--time-budget") {
      if (!parse_seconds(v, a.time_budget)) return "--time-budget: '" + std::string(v) + "' is not a number >= 0";
      a.has_budget = true;
    } else if (opt == "--photons") {
      if (!parse_u64(v, uint64_t(1) << 40, a.photons)) return "--photons: '" + std::string(v) + "' is not an integer in [0, 2^40]";
      a.has_photons = true;
    } else if (opt == "--seed") {
      if (!parse_u64(v, 0xffffffffu, u)) return "--seed: '" + std::string(v) + "' is not an integer in [0, 2^32)";
      a.seed = uint32_t(u);
      a.has_seed = true;
    } else if (opt == "--shard" || opt == "--direct" || opt == "--gather") {
      const std::string text = v;
      const size_t slash = text.find('/');
      uint64_t k = 0, n = 0;
      if (slash == std::string::npos || !parse_u64(text.substr(0, slash).c_str(), 1u << 20, k) ||
          !parse_u64(text.substr(slash + 1).c_str(), 1u << 20, n) || k < 1 || k > n)
        return opt + ": '" + text + "' is not K/N with 1 <= K <= N <= 1048576";
      if (a.shard_count > 0 || a.range_count > 0) return "only one of --shard, --direct and --gather";
      if (opt == "--shard") {
        a.shard = uint32_t(k - 1);
        a.shard_count = uint32_t(n);
      } else {
        a.range = uint32_t(k - 1);
        a.range_count = uint32_t(n);
        a.stage = opt == "--direct" ? PLM_TEXELS_DIRECT : PLM_TEXELS_GATHER;
      }
    } else if (opt == "--directional") {
      const std::string text = v;
      if (text != "on" && text != "off") return "--directional: '" + text + "' is not on or off";
      a.directional = text == "on" ? 1 : 0;
    } else if (opt == "--parts") {
      a.parts.push_back(v);
    } else if (opt == "--max-file-mb") {
      const std::string e = parse_max_file_mb(v, a.read);
      if (!e.empty()) return e;
    } else if (opt == "--threads") {
      if (!parse_u64(v, 0xffffffffu, u)) return "--threads: '" + std::string(v) + "' is not an integer >= 0";
      a.threads = uint32_t(u);
      a.has_threads = true;
    } else {
      return "unknown option " + opt;
    }
  }
  if (a.scene.empty()) return "no scene file given (usage: photonlm bake SCENE.json -o DIR [options])";
  if (a.out_dir.empty()) return "no output folder given (-o DIR)";
  if (!a.parts.empty() && a.stage != PLM_TEXELS_GATHER) return "--parts is for --gather K/N";
  return "";
}

// Progress: one updating line on a terminal, plain lines (each stage, every 10 %) otherwise.
struct Progress {
  bool tty = false;
  std::string stage;
  int decile = -1;
  std::chrono::steady_clock::time_point last{};
  bool line_open = false;

  void finish_line() {
    if (line_open) std::printf("\n");
    line_open = false;
    std::fflush(stdout);
  }
};

int on_progress(void* user, double fraction, const char* stage) {
  if (g_interrupted) return 0;
  Progress& p = *static_cast<Progress*>(user);
  const std::string s = stage ? stage : "";
  const double pct = 100.0 * (fraction < 0 ? 0 : fraction > 1 ? 1 : fraction);
  const auto now = std::chrono::steady_clock::now();
  if (p.tty) {
    if (s != p.stage || now - p.last > std::chrono::milliseconds(100) || fraction >= 1) {
      std::printf("\r%-32.32s %5.1f%%", s.c_str(), pct);
      std::fflush(stdout);
      p.line_open = true;
      p.last = now;
    }
  } else {
    const int decile = int(pct / 10);
    if (s != p.stage || decile != p.decile) {
      std::printf("%s %.1f%%\n", s.c_str(), pct);
      std::fflush(stdout);
      p.decile = decile;
    }
  }
  p.stage = s;
  return g_interrupted ? 0 : 1;
}

// A file name from an object name: letters, digits, '.', '-', '_' kept, the
// rest '_'; unique in the folder (ignoring case) by numbering duplicates.
std::string file_name(const std::string& name, const char* suffix, std::set<std::string>& used) {
  std::string base;
  for (char c : name) base += (std::isalnum((unsigned char)c) || c == '-' || c == '_' || c == '.') ? c : '_';
  while (!base.empty() && base[0] == '.') base.erase(0, 1);
  if (base.size() > 100) base.resize(100);
  if (base.empty()) base = "unnamed";
  for (int n = 1;; ++n) {
    const std::string f = (n == 1 ? base : base + "_" + std::to_string(n)) + suffix;
    std::string key = f;
    for (char& c : key) c = char(std::tolower((unsigned char)c));
    if (key == "report.json") continue;
    if (used.insert(key).second) return f;
  }
}

// Writes text to path atomically (temporary file in the same folder, then rename).
bool write_atomic(const std::string& path, const std::string& text, std::string& error) {
  const std::string tmp = path + ".tmp-" + std::to_string(getpid());
  FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) {
    error = tmp + ": " + std::strerror(errno);
    return false;
  }
  bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size() && std::fflush(f) == 0 && fsync(fileno(f)) == 0;
  ok = (std::fclose(f) == 0) && ok;
  if (!ok || std::rename(tmp.c_str(), path.c_str()) != 0) {
    error = path + ": " + std::strerror(errno);
    std::remove(tmp.c_str());
    return false;
  }
  return true;
}

ordered_json settings_json(const plm_bake_settings& s) {
  ordered_json j;
  j["photon_count"] = s.photon_count;
  j["max_bounces"] = s.max_bounces;
  j["seed"] = s.seed;
  j["thread_count"] = s.thread_count;
  j["dilation"] = s.dilation;
  j["target_error"] = s.target_error;
  j["time_budget"] = s.time_budget;
  j["direct_samples"] = s.direct_samples;
  j["filter_radius"] = s.filter_radius;
  j["texel_value"] = plm::texel_value_name(s.texel_value);
  j["sampler"] = plm::sampler_name(s.sampler);
  j["directional"] = s.directional != 0;
  return j;
}

struct ResultGuard {
  plm_result* r = nullptr;
  ~ResultGuard() { plm_result_release(r); }
};

}  // namespace

bool make_output_folder(const std::string& dir, std::string& error) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (!ec && std::filesystem::is_directory(dir)) return true;
  error = dir + ": cannot create the output folder" + (ec ? ": " + ec.message() : "");
  return false;
}

int run_with_progress(const std::string& what, const std::function<plm_status(plm_progress_fn, void*)>& call) {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  Progress progress;
  progress.tty = isatty(fileno(stdout)) != 0;
  const plm_status st = call(on_progress, &progress);
  progress.finish_line();
  if (st == PLM_ERROR_CANCELLED || (g_interrupted && st != PLM_OK)) {
    std::fprintf(stderr, "%s: interrupted; nothing written\n", what.c_str());
    return kInterrupted;
  }
  if (st != PLM_OK) {
    std::fprintf(stderr, "%s: failed (%s): %s\n", what.c_str(), plm_status_string(st), plm_last_error());
    return st == PLM_ERROR_INVALID_ARGUMENT || st == PLM_ERROR_INVALID_SCENE ? kBadInput : kBakeFailed;
  }
  return kOk;
}

int bake_command(int argc, char** argv) {
  Args a;
  const std::string arg_error = parse_args(argc, argv, a);
  if (!arg_error.empty()) return bad_input(arg_error);

  plm::SceneFile scene;
  std::string error;
  if (!read_scene(a.scene, a.read, scene, error)) return bad_input(error);
  plm_bake_settings s = scene.settings;
  if (a.has_target) s.target_error = a.target_error;
  if (a.has_budget) s.time_budget = a.time_budget;
  if (a.has_photons) s.photon_count = a.photons;
  if (a.has_seed) s.seed = a.seed;
  if (a.has_threads) s.thread_count = a.threads;
  if (a.directional >= 0) s.directional = uint32_t(a.directional);

  if (!make_output_folder(a.out_dir, error)) return bad_input(error);
  const auto t0 = std::chrono::steady_clock::now();

  std::string scene_path;  // what a part file records
  if (a.shard_count > 0 || a.range_count > 0) {
    scene_path = std::filesystem::absolute(a.scene).lexically_normal().string();
    if (scene_path.size() > 255) {  // the part keeps 255 bytes: the merge then needs --scene
      std::fprintf(stderr, "warning: the scene's path is longer than 255 bytes and is not kept in the part; "
                           "give it to photonlm merge with --scene\n");
      scene_path.clear();
    }
  }
  if (a.range_count > 0) {  // one texel range's direct pass or gather: its part file (docs/farm.md)
    const bool direct = a.stage == PLM_TEXELS_DIRECT;
    const std::string part = a.out_dir + "/" + texel_part_file_name(direct, a.range, a.range_count);
    std::vector<std::string> inputs;
    if (!direct && !find_part_files(a.parts.empty() ? std::vector<std::string>{a.out_dir} : a.parts, inputs, error))
      return bad_input(error);
    std::vector<const char*> paths;
    for (const std::string& p : inputs) paths.push_back(p.c_str());
    const std::string what = "photonlm bake " + a.scene + (direct ? " --direct " : " --gather ") +
                             std::to_string(a.range + 1) + "/" + std::to_string(a.range_count);
    const int code = run_with_progress(what, [&](plm_progress_fn fn, void* user) {
      return plm_bake_texels(scene.scene, &s, uint32_t(a.stage), a.range, a.range_count, paths.data(),
                             uint32_t(paths.size()), scene_path.c_str(), part.c_str(), fn, user);
    });
    if (code == kOk)
      std::printf("%s range %u of %u: %.3f s -> %s\n", direct ? "direct" : "gather", a.range + 1, a.range_count,
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), part.c_str());
    return code;
  }
  if (a.shard_count > 0) {  // one shard of a sharded bake: its part file, nothing else (docs/farm.md)
    const std::string part = a.out_dir + "/" + part_file_name(a.shard, a.shard_count);
    const int code = run_with_progress("photonlm bake " + a.scene + " --shard " + std::to_string(a.shard + 1) + "/" +
                                           std::to_string(a.shard_count),
                                       [&](plm_progress_fn fn, void* user) {
                                         return plm_bake_shard(scene.scene, &s, a.shard, a.shard_count,
                                                               scene_path.c_str(), part.c_str(), fn, user);
                                       });
    if (code == kOk)
      std::printf("shard %u of %u: %.3f s -> %s\n", a.shard + 1, a.shard_count,
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), part.c_str());
    return code;
  }

  ResultGuard result;
  const int code = run_with_progress("photonlm bake: " + a.scene, [&](plm_progress_fn fn, void* user) {
    return plm_bake(scene.scene, &s, fn, user, &result.r);
  });
  if (code != kOk) return code;
  return write_bake_outputs(result.r, scene, s, a.scene, a.out_dir, t0);
}

std::string part_file_name(uint32_t shard, uint32_t count) {
  char name[64];
  std::snprintf(name, sizeof name, "part-%05u-of-%05u.plmpart", shard + 1, count);
  return name;
}

std::string texel_part_file_name(bool direct, uint32_t range, uint32_t count) {
  char name[64];
  std::snprintf(name, sizeof name, "%s-%05u-of-%05u.plmpart", direct ? "direct" : "gather", range + 1, count);
  return name;
}

bool find_part_files(const std::vector<std::string>& inputs, std::vector<std::string>& parts, std::string& error) {
  // Only *.plmpart: temporary files (being written) end otherwise.
  auto is_part = [](const std::filesystem::path& p) {
    return p.extension() == ".plmpart" && std::filesystem::is_regular_file(p);
  };
  for (const std::string& in : inputs) {
    std::error_code ec;
    if (std::filesystem::is_directory(in, ec)) {
      std::vector<std::string> found;
      for (const auto& e : std::filesystem::directory_iterator(in, ec))
        if (is_part(e.path())) found.push_back(e.path().string());
      if (found.empty()) {
        error = in + ": no part files (*.plmpart) in this folder";
        return false;
      }
      std::sort(found.begin(), found.end());
      parts.insert(parts.end(), found.begin(), found.end());
    } else if (std::filesystem::is_regular_file(in, ec)) {
      parts.push_back(in);
    } else {
      error = in + ": no such part file or folder";
      return false;
    }
  }
  return true;
}

int write_bake_outputs(plm_result* r, const plm::SceneFile& scene, const plm_bake_settings& s,
                       const std::string& scene_label, const std::string& out_dir,
                       std::chrono::steady_clock::time_point t0, double check_target) {
  const std::string cmd = "photonlm";
  plm_bake_stats stats{};
  stats.struct_size = sizeof stats;
  if (plm_result_stats(r, &stats) != PLM_OK) {
    std::fprintf(stderr, "%s: %s\n", cmd.c_str(), plm_last_error());
    return kBakeFailed;
  }
  std::string error;
  ordered_json report;
  report["photonlm_version"] = plm_version();
  report["scene"] = scene_label;
  report["settings"] = settings_json(s);
  report["times"] = {{"setup", stats.seconds_setup},
                     {"direct", stats.seconds_direct},
                     {"trace", stats.seconds_trace},
                     {"total", stats.seconds_total}};
  report["photons"] = {{"emitted", stats.photons_emitted},
                       {"hits", stats.photon_hits},
                       {"rays", stats.rays_traced},
                       {"truncated", stats.paths_truncated}};
  report["direct_samples"] = stats.direct_samples;
  report["emitted_power"] = stats.emitted_power;
  report["stats"] = {{"error_estimate", stats.error_estimate},
                     {"error_direct", stats.error_direct},
                     {"median", stats.error_median},
                     {"p95", stats.error_p95},
                     {"above_twice_target", stats.error_above},
                     {"memory_estimate", stats.memory_estimate},
                     {"worst_object_error", stats.error_worst},
                     {"worst_object", ordered_json()}};
  for (const plm::SceneFileMesh& m : scene.meshes)
    if (m.id == stats.error_worst_mesh) report["stats"]["worst_object"] = m.name;
  if (check_target > 0.0)
    report["target"] = {{"error", check_target},
                        {"estimate", stats.error_worst},
                        {"met", stats.error_worst <= check_target}};
  ordered_json warnings = ordered_json::array();
  for (uint32_t i = 0; i < plm_result_warning_count(r); ++i) {
    const char* w = plm_result_warning(r, i);
    std::fprintf(stderr, "warning: %s\n", w);
    warnings.push_back(w);
  }
  report["warnings"] = warnings;

  // Files: written one by one (each atomically); on any failure or interruption all are removed.
  std::vector<std::string> written;
  auto abandon = [&](int code) {
    for (const std::string& f : written) std::remove(f.c_str());
    if (code == kInterrupted) std::fprintf(stderr, "photonlm: interrupted; nothing written\n");
    return code;
  };
  std::set<std::string> used;
  const std::string dir = out_dir + "/";
  // Twice the target error, or twice the RMS error estimate without a target (the heat map's scale).
  const float above_limit = float(2.0 * (s.target_error > 0.0 ? double(s.target_error) : stats.error_estimate));
  ordered_json meshes = ordered_json::array();
  for (const plm::SceneFileMesh& m : scene.meshes) {
    if (m.width == 0) continue;
    if (g_interrupted) return abandon(kInterrupted);
    const std::string name = file_name(m.name, "_lightmap.exr", used);
    if (plm_result_write_exr(r, m.id, (dir + name).c_str()) != PLM_OK) {
      std::fprintf(stderr, "%s: %s\n", cmd.c_str(), plm_last_error());
      return abandon(kBakeFailed);
    }
    written.push_back(dir + name);
    const size_t n = size_t(m.width) * m.height;
    std::vector<float> rgb(3 * n), error(n), coverage(n);
    double sum[3] = {0, 0, 0}, area = 0;
    uint64_t texels = 0, above = 0;
    double value_sum = 0.0, var_sum = 0.0;  // the object's relative RMS error, as the target judges it
    if (plm_result_copy_lightmap(r, m.id, rgb.data(), error.data(), nullptr, coverage.data()) == PLM_OK) {
      for (size_t t = 0; t < n; ++t) {
        if (coverage[t] <= 0) continue;
        for (int c = 0; c < 3; ++c) sum[c] += double(rgb[3 * t + c]) * coverage[t];
        area += coverage[t];
        // The add-on's per-object count (bake.py): relative error = error / mean RGB, in float.
        const float value = (rgb[3 * t] + rgb[3 * t + 1] + rgb[3 * t + 2]) / 3.0f;
        ++texels;
        value_sum += value, var_sum += double(error[t]) * error[t];
        if (value > 0.0f && error[t] / value > above_limit) ++above;
      }
    }
    const double k = area > 0 ? 1.0 / area : 0.0;
    ordered_json jm;
    jm["name"] = m.name;
    jm["file"] = name;
    jm["size"] = {m.width, m.height};
    jm["mean"] = {sum[0] * k, sum[1] * k, sum[2] * k};
    jm["mean_value"] = (sum[0] + sum[1] + sum[2]) * k / 3.0;
    jm["texels"] = texels;
    jm["texels_above_twice_target"] = above;
    jm["error"] = value_sum > 0.0 ? std::sqrt(var_sum / double(texels)) / (value_sum / double(texels)) : 0.0;
    jm["ol_group"] = m.ol_group >= 0 ? ordered_json(scene.ol_groups[size_t(m.ol_group)].name) : ordered_json();
    // Light groups: each layer beside the lightmap, <mesh>_lightmap.<group>.exr.
    if (plm_result_layer_count(r) > 0) {
      ordered_json layers = ordered_json::array();
      const std::string stem = name.substr(0, name.size() - 4);
      for (uint32_t l = 0; l < plm_result_layer_count(r); ++l) {
        const std::string group = plm_result_layer_name(r, l);
        const std::string layer_file = stem + "." + group + ".exr";
        used.insert(layer_file);
        if (plm_result_write_layer_exr(r, m.id, l, (dir + layer_file).c_str()) != PLM_OK) {
          std::fprintf(stderr, "%s: %s\n", cmd.c_str(), plm_last_error());
          return abandon(kBakeFailed);
        }
        written.push_back(dir + layer_file);
        layers.push_back({{"group", group}, {"file", layer_file}});
      }
      jm["layers"] = layers;
    }
    // Directional lightmaps: the SH bands beside the lightmap, <mesh>_lightmap_sh0.exr (L0) .. _sh3.exr.
    if (plm_result_directional(r)) {
      ordered_json sh = ordered_json::array();
      const std::string stem = name.substr(0, name.size() - 4);
      for (uint32_t band = 0; band < 4; ++band) {
        const std::string band_file = stem + "_sh" + std::to_string(band) + ".exr";
        used.insert(band_file);
        if (plm_result_write_sh_exr(r, m.id, band, (dir + band_file).c_str()) != PLM_OK) {
          std::fprintf(stderr, "%s: %s\n", cmd.c_str(), plm_last_error());
          return abandon(kBakeFailed);
        }
        written.push_back(dir + band_file);
        sh.push_back(band_file);
      }
      jm["sh"] = sh;
    }
    meshes.push_back(jm);
    std::printf("%-24s %5ux%-5u mean %.6g -> %s\n", m.name.c_str(), m.width, m.height, (sum[0] + sum[1] + sum[2]) * k / 3.0,
                name.c_str());
  }
  report["meshes"] = meshes;
  ordered_json light_groups = ordered_json::array();
  for (uint32_t l = 0; l < plm_result_layer_count(r); ++l) {
    double error_estimate = 0.0;
    plm_result_layer_error(r, l, &error_estimate);
    light_groups.push_back({{"name", plm_result_layer_name(r, l)}, {"error_estimate", error_estimate}});
  }
  if (!light_groups.empty()) report["light_groups"] = light_groups;
  ordered_json groups = ordered_json::array();
  for (const plm::SceneFileOlGroup& g : scene.ol_groups) {
    if (g_interrupted) return abandon(kInterrupted);
    const std::string name = file_name(g.name, "_ol.exr", used);
    if (plm_result_write_ol_exr(r, g.id, (dir + name).c_str()) != PLM_OK) {
      std::fprintf(stderr, "%s: %s\n", cmd.c_str(), plm_last_error());
      return abandon(kBakeFailed);
    }
    written.push_back(dir + name);
    plm_ol_stats os{};
    os.struct_size = sizeof os;
    plm_result_ol_stats(r, g.id, &os);
    groups.push_back({{"name", g.name},
                      {"file", name},
                      {"resolution", os.resolution},
                      {"meshes", os.mesh_count},
                      {"hits", os.hits},
                      {"area", os.area},
                      {"flux", os.flux}});
    std::printf("%-24s %5ux%-5u OL -> %s\n", g.name.c_str(), os.resolution, os.resolution, name.c_str());
  }
  report["ol_groups"] = groups;
  report["times"]["wall"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (g_interrupted) return abandon(kInterrupted);
  if (!write_atomic(dir + "report.json", report.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n",
                    error)) {
    std::fprintf(stderr, "photonlm: cannot write the report: %s\n", error.c_str());
    return abandon(kBakeFailed);
  }
  std::printf("photons %llu, %.3f s, error estimate %.4f (median %.4f, p95 %.4f, noisiest object %.4f) -> "
              "%sreport.json\n",
              (unsigned long long)stats.photons_emitted, stats.seconds_total, stats.error_estimate, stats.error_median,
              stats.error_p95, stats.error_worst, dir.c_str());
  return kOk;
}

}  // namespace plm_cli

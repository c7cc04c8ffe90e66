// `photonlm merge PART... -o DIR`: adds the part files of a sharded bake
// (`photonlm bake SCENE --shard K/N`, and optionally its texel ranges'
// `--direct K/N` and `--gather K/N`) and writes what `photonlm bake SCENE`
// writes, bit for bit (docs/farm.md). A PART is a part file or a folder of
// them; the scene is the one the parts name unless --scene gives another path
// to it (a farm whose machines mount it elsewhere).
#include "merge_command.h"

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <string>
#include <vector>

#include "bake_command.h"
#include "io/scene_file.h"
#include "photonlm/photonlm.h"

namespace plm_cli {
namespace {

constexpr int kBadInput = 1;

int bad_input(const std::string& message) {
  std::fprintf(stderr, "photonlm merge: %s\n", message.c_str());
  return kBadInput;
}

}  // namespace

int merge_command(int argc, char** argv) {
  std::vector<std::string> inputs;
  std::string out_dir, scene_path;
  uint64_t threads = 0;
  double target = 0.0;
  plm::SceneFileOptions read;  // --max-file-mb
  for (int i = 0; i < argc; ++i) {
    const std::string opt = argv[i];
    if (opt.empty() || opt[0] != '-') {
      inputs.push_back(opt);
      continue;
    }
    if (i + 1 >= argc) return bad_input("option " + opt + " needs a value");
    const std::string v = argv[++i];
    if (opt == "-o" || opt == "--out") {
      out_dir = v;
    } else if (opt == "--scene") {
      scene_path = v;
    } else if (opt == "--target-error") {
      char* end = nullptr;
      target = std::strtod(v.c_str(), &end);
      if (v.empty() || *end || !(target > 0.0) || !std::isfinite(target))
        return bad_input("--target-error: '" + v + "' is not a number > 0");
    } else if (opt == "--max-file-mb") {
      const std::string e = parse_max_file_mb(v, read);
      if (!e.empty()) return bad_input(e);
    } else if (opt == "--threads") {
      char* end = nullptr;
      threads = std::strtoull(v.c_str(), &end, 10);
      if (v.empty() || *end || v[0] == '-' || threads > 0xffffffffu)
        return bad_input("--threads: '" + v + "' is not an integer >= 0");
    } else {
      return bad_input("unknown option " + opt);
    }
  }
  if (inputs.empty()) return bad_input("no part files or folders given (usage: photonlm merge PART... -o DIR)");
  if (out_dir.empty()) return bad_input("no output folder given (-o DIR)");

  std::vector<std::string> parts;
  std::string error;
  if (!find_part_files(inputs, parts, error)) return bad_input(error);

  plm_bake_settings s;
  plm_bake_settings_default(&s);
  char named_scene[256] = {0};
  if (plm_part_info(parts[0].c_str(), &s, nullptr, nullptr, named_scene, sizeof named_scene) != PLM_OK)
    return bad_input(plm_last_error());
  if (scene_path.empty()) scene_path = named_scene;
  if (scene_path.empty()) return bad_input(parts[0] + ": names no scene file; give one with --scene");

  plm::SceneFile scene;
  if (!read_scene(scene_path, read, scene, error)) return bad_input(error);
  if (!make_output_folder(out_dir, error)) return bad_input(error);

  const auto t0 = std::chrono::steady_clock::now();
  std::vector<const char*> paths;
  for (const std::string& p : parts) paths.push_back(p.c_str());
  plm_result* result = nullptr;
  const int code = run_with_progress("photonlm merge", [&](plm_progress_fn fn, void* user) {
    return plm_bake_merge(scene.scene, paths.data(), uint32_t(paths.size()), uint32_t(threads), fn, user, &result);
  });
  if (code != 0) return code;
  s.thread_count = uint32_t(threads);
  const int written = write_bake_outputs(result, scene, s, scene_path, out_dir, t0, target);
  plm_bake_stats stats{};
  stats.struct_size = sizeof stats;
  plm_result_stats(result, &stats);
  plm_result_release(result);
  if (written == 0) std::printf("merged %zu part file(s)\n", parts.size());
  if (written == 0 && target > 0.0)
    std::printf("target error %g %s (estimate %g)\n", target, stats.error_estimate <= target ? "met" : "not met",
                stats.error_estimate);
  return written;
}

}  // namespace plm_cli

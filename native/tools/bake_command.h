// `photonlm bake SCENE.json -o DIR [options]`: bakes a JSON scene file
// (docs/scene-file.md) into one EXR per lightmap and OL group plus a report.
#pragma once

#include <chrono>
#include <functional>
#include <string>
#include <vector>

#include "io/scene_file.h"
#include "photonlm/photonlm.h"

namespace plm_cli {

// Creates the output folder dir (and its parents) if missing. On failure
// returns false and a message naming the folder.
bool make_output_folder(const std::string& dir, std::string& error);

// --max-file-mb N (bake, merge, gltf): the largest scene, OBJ or glTF file
// read, in MiB, into options. Returns "" or the error.
std::string parse_max_file_mb(const std::string& value, plm::SceneFileOptions& options);
// plm::read_scene_file, its message on an oversized file naming --max-file-mb.
bool read_scene(const std::string& path, const plm::SceneFileOptions& options, plm::SceneFile& scene,
                std::string& error);

// argv: the arguments after "bake". Returns the process exit code:
// 0 ok, 1 bad input, 2 bake failure, 130 interrupted (SIGINT / SIGTERM).
// With --shard K/N (1 <= K <= N) it bakes shard K of N: DIR gets only the
// shard's part file, part_file_name(K - 1, N) (docs/farm.md). With --direct
// K/N the direct pass of texel range K of N, with --gather K/N [--parts
// PATH...] its final gather over the photon and direct parts in PATH (default
// DIR): DIR gets texel_part_file_name(...).
int bake_command(int argc, char** argv);

// The part file of shard `shard` (0-based) of `count`: part-0000K-of-0000N.plmpart.
std::string part_file_name(uint32_t shard, uint32_t count);
// The part file of texel range `range` (0-based) of `count`: direct-0000K-of-0000N.plmpart
// (direct pass) or gather-0000K-of-0000N.plmpart (final gather).
std::string texel_part_file_name(bool direct, uint32_t range, uint32_t count);

// The part files among inputs: files named, and every *.plmpart in the
// folders named (sorted). On failure returns false and the message.
bool find_part_files(const std::vector<std::string>& inputs, std::vector<std::string>& parts, std::string& error);

// Runs call(progress, user) with the CLI's progress line and Ctrl-C handling;
// returns 0 or the exit code of its failure, printing "what: failed (...)".
int run_with_progress(const std::string& what, const std::function<plm_status(plm_progress_fn, void*)>& call);

// Writes a bake's EXRs and report.json into out_dir as `photonlm bake` does
// (each file atomically; all removed on failure). Returns the exit code.
// check_target > 0: report.json also says whether the error estimate is at
// or below it ("target": error, estimate, met), for a driver that bakes
// rounds of shards until it is (docs/farm.md).
int write_bake_outputs(plm_result* result, const plm::SceneFile& scene, const plm_bake_settings& settings,
                       const std::string& scene_label, const std::string& out_dir,
                       std::chrono::steady_clock::time_point t0, double check_target = 0.0);

}  // namespace plm_cli

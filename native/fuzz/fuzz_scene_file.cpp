// libFuzzer target for the JSON scene file reader: the input is the
// text of a scene file. It goes through parse -> plm_scene with file access
// disabled (an "obj" reference is an error, no file is opened); a scene that
// parses and is small is baked with a tiny photon count. The reader must never
// crash, hang, leak or trip a sanitizer, and must refuse with a message that
// starts with a JSON path or names the problem.
//
// Build and run: scripts/fuzz.sh [seconds]. Seeds: native/fuzz/corpus/scene_file/.
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include <string>
#include <string_view>

#include "io/scene_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  plm::SceneFileOptions options;
  options.allow_file_access = false;
  // Small limits keep one input fast; they are the same checks as the defaults.
  options.limits.max_file_bytes = 1 << 16;
  options.limits.max_vertices = 4096;
  options.limits.max_triangles = 4096;
  options.limits.max_items = 256;
  plm::SceneFile scene;
  std::string error;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  if (!plm::parse_scene_file_text(text, options, scene, error)) {
    if (error.empty()) {
      fprintf(stderr, "fuzz_scene_file: refused without a message\n");
      abort();
    }
    return 0;
  }
  // A tiny bake of small scenes: the parsed settings reach plm_bake (bounded so one input stays fast).
  uint64_t texels = 0;
  for (const plm::SceneFileMesh& m : scene.meshes) texels += uint64_t(m.width) * m.height;
  uint64_t bins = 0;
  for (const plm::SceneFileOlGroup& g : scene.ol_groups) bins += g.resolution ? uint64_t(g.resolution) * g.resolution : 256;
  if (texels <= 1024 && bins <= 4096 && scene.meshes.size() <= 16) {
    plm_bake_settings s = scene.settings;
    s.photon_count = 2000;
    s.target_error = 0;
    s.time_budget = 0;
    s.thread_count = 1;
    if (s.direct_samples > 4) s.direct_samples = 4;
    if (s.max_bounces > 8) s.max_bounces = 8;
    if (s.dilation > 4) s.dilation = 4;
    if (s.filter_radius > 4) s.filter_radius = 4;
    plm_result* result = nullptr;
    if (plm_bake(scene.scene, &s, nullptr, nullptr, &result) == PLM_OK) plm_result_release(result);
  }
  return 0;
}

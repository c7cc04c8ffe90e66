// photonlm: command-line front end of the engine.
//   photonlm version
//   photonlm furnace [--albedo R] [--emission E] [--photons N] [--res N] [-o DIR]
//   photonlm cornell [--photons N] [--res N] [--seed S] [-o DIR]
//   photonlm bake SCENE.json -o DIR [--target-error X] [--time-budget S] [--photons N] [--seed N] [--threads N]
//                 [--directional on|off] [--shard K/N | --direct K/N | --gather K/N [--parts PATH]...]
//                 [--max-file-mb N]
//   photonlm merge PART... -o DIR [--scene SCENE.json] [--threads N] [--target-error X] [--max-file-mb N]
//   photonlm gltf SCENE.json BAKE_DIR -o FILE.glb [--max-file-mb N]
// furnace/cornell: progress goes to stderr; results (time, photons, error) to stdout.
// bake (bake_command.cpp): see docs/scene-file.md; shards and merge (merge_command.cpp): docs/farm.md.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "bake_command.h"
#include "demo_scenes.h"
#include "gltf_command.h"
#include "merge_command.h"

namespace {

struct Options {
  std::string command, out_dir;
  double albedo = 0.5, emission = 1.0;
  uint64_t photons = 2000000;
  uint32_t res = 32, seed = 0, threads = 0;
};

int usage(const char* error) {
  if (error) std::fprintf(stderr, "photonlm: %s\n\n", error);
  std::fprintf(stderr,
               "usage: photonlm version\n"
               "       photonlm furnace [--albedo R] [--emission E] [--photons N] [--res N] [-o DIR]\n"
               "       photonlm cornell [--photons N] [--res N] [--seed S] [--threads T] [-o DIR]\n"
               "       photonlm bake SCENE.json -o DIR [--target-error X] [--time-budget S] [--photons N]\n"
               "                     [--seed N] [--threads N] [--directional on|off]\n"
               "                     [--shard K/N | --direct K/N | --gather K/N [--parts P]] [--max-file-mb N]\n"
               "       photonlm merge PART... -o DIR [--scene SCENE.json] [--threads N] [--target-error X]\n"
               "                     [--max-file-mb N]\n"
               "       photonlm gltf SCENE.json BAKE_DIR -o FILE.glb [--max-file-mb N]\n"
               "furnace: closed box with uniform emission and albedo; the exact texel value is E/(1-R).\n"
               "cornell: Cornell box with a 200 W area light; writes one EXR per object with -o.\n"
               "bake: bakes a JSON scene file (docs/scene-file.md) into DIR: one EXR per lightmap and\n"
               "      OL group, and report.json. Exit codes: 0 ok, 1 bad input, 2 bake failure, 130 interrupted.\n"
               "      --shard K/N bakes the photons of shard K of N into DIR/part-K-of-N.plmpart (docs/farm.md);\n"
               "      --direct K/N the direct pass of texel range K of N into DIR/direct-K-of-N.plmpart;\n"
               "      --gather K/N the final gather of texel range K of N over the photon and direct parts in\n"
               "      P (default DIR) into DIR/gather-K-of-N.plmpart.\n"
               "merge: adds the part files of all N shards (files or folders; direct and gather parts of\n"
               "      every texel range too, if given) and writes what bake writes.\n"
               "--max-file-mb N: read scene, OBJ and glTF files of up to N MiB (default 256).\n");
  return 2;
}

bool parse(int argc, char** argv, Options& o, std::string& error) {
  if (argc < 2) return false;
  o.command = argv[1];
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) {
      error = "option " + a + " needs a value";
      return false;
    }
    const char* v = argv[++i];
    char* end = nullptr;
    if (a == "-o" || a == "--out") o.out_dir = v;
    else if (a == "--albedo") o.albedo = std::strtod(v, &end);
    else if (a == "--emission") o.emission = std::strtod(v, &end);
    else if (a == "--photons") o.photons = std::strtoull(v, &end, 10);
    else if (a == "--res") o.res = uint32_t(std::strtoul(v, &end, 10));
    else if (a == "--seed") o.seed = uint32_t(std::strtoul(v, &end, 10));
    else if (a == "--threads") o.threads = uint32_t(std::strtoul(v, &end, 10));
    else {
      error = "unknown option " + a;
      return false;
    }
    if (end && *end) {
      error = "option " + a + ": '" + v + "' is not a number";
      return false;
    }
  }
  return true;
}

int progress(void*, double fraction, const char* stage) {
  std::fprintf(stderr, "\r%5.1f%% %-40s", 100.0 * fraction, stage);
  if (fraction >= 1.0) std::fprintf(stderr, "\n");
  return 1;
}

int fail(const char* what) {
  std::fprintf(stderr, "photonlm: %s: %s\n", what, plm_last_error());
  return 1;
}

int run(const Options& o) {
  plm_demo::SceneBuilder b;
  if (o.command == "furnace") plm_demo::build_furnace(b, float(o.albedo), float(o.emission), o.res);
  else plm_demo::build_cornell(b, o.res);
  if (!b.ok()) {
    std::fprintf(stderr, "photonlm: cannot build the scene: %s\n", b.error.c_str());
    return 1;
  }
  std::string error;
  if (!o.out_dir.empty() && !plm_cli::make_output_folder(o.out_dir, error)) {  // before the bake, not after it
    std::fprintf(stderr, "photonlm: %s\n", error.c_str());
    return 1;
  }
  plm_bake_settings s;
  plm_bake_settings_default(&s);
  s.photon_count = o.photons;
  s.seed = o.seed;
  s.thread_count = o.threads;
  plm_result* r = nullptr;
  if (plm_bake(b.scene, &s, progress, nullptr, &r) != PLM_OK) return fail("bake failed");
  plm_bake_stats st{};
  st.struct_size = sizeof st;
  plm_result_stats(r, &st);
  for (uint32_t i = 0; i < plm_result_warning_count(r); ++i) std::fprintf(stderr, "warning: %s\n", plm_result_warning(r, i));
  std::printf("photons %llu, rays %llu, bake %.3f s (trace %.3f s), %.2f M photons/s\n",
              (unsigned long long)st.photons_emitted, (unsigned long long)st.rays_traced, st.seconds_total,
              st.seconds_trace, st.photons_emitted / std::fmax(st.seconds_trace, 1e-9) * 1e-6);
  int status = 0;
  for (uint32_t m = 0; m < b.mesh_names.size(); ++m) {
    uint32_t w = 0, h = 0;
    plm_result_lightmap_size(r, m, &w, &h);
    std::vector<float> rgb(size_t(w) * h * 3), cov(size_t(w) * h), err(size_t(w) * h);
    plm_result_copy_lightmap(r, m, rgb.data(), err.data(), nullptr, cov.data());
    double sum = 0, area = 0, abs_err = 0, rep_err = 0;
    const double exact = o.emission / (1.0 - o.albedo);
    for (size_t t = 0; t < cov.size(); ++t) {
      if (cov[t] <= 0) continue;
      const double v = (rgb[3 * t] + rgb[3 * t + 1] + rgb[3 * t + 2]) / 3.0;
      sum += v * cov[t];
      area += cov[t];
      abs_err += std::fabs(v - exact) * cov[t];
      rep_err += err[t] * cov[t];
    }
    std::printf("%-12s %4ux%-4u mean %.5f", b.mesh_names[m].c_str(), w, h, sum / area);
    if (o.command == "furnace")
      std::printf("  exact %.5f  mean error %.3f%%  texel error %.3f%% (reported %.3f%%)", exact,
                  100.0 * std::fabs(sum / area - exact) / exact, 100.0 * abs_err / area / exact,
                  100.0 * rep_err / area / exact);
    std::printf("\n");
    if (!o.out_dir.empty()) {
      const std::string path = o.out_dir + "/" + b.mesh_names[m] + "_lightmap.exr";
      if (plm_result_write_exr(r, m, path.c_str()) != PLM_OK) status = fail("cannot write the lightmap");
    }
  }
  plm_result_release(r);
  return status;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc >= 2 && std::strcmp(argv[1], "bake") == 0) return plm_cli::bake_command(argc - 2, argv + 2);
  if (argc >= 2 && std::strcmp(argv[1], "merge") == 0) return plm_cli::merge_command(argc - 2, argv + 2);
  if (argc >= 2 && std::strcmp(argv[1], "gltf") == 0) return plm_cli::gltf_command(argc - 2, argv + 2);
  Options o;
  std::string error;
  if (!parse(argc, argv, o, error)) return usage(error.empty() ? nullptr : error.c_str());
  if (o.command == "version") {
    std::printf("photonlm %s\n", plm_version());
    return 0;
  }
  if (o.command != "furnace" && o.command != "cornell") return usage(("unknown command " + o.command).c_str());
  if (o.albedo < 0 || o.albedo >= 1) return usage("--albedo must be in [0, 1)");
  return run(o);
}

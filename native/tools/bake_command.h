// `photonlm bake SCENE.json -o DIR [options]`: bakes a JSON scene file
// (docs/scene-file.md) into one EXR per lightmap and OL group plus a report.
#pragma once

#include <string>

namespace plm_cli {

// Creates the output folder dir (and its parents) if missing. On failure
// returns false and a message naming the folder.
bool make_output_folder(const std::string& dir, std::string& error);

// argv: the arguments after "bake". Returns the process exit code:
// 0 ok, 1 bad input, 2 bake failure, 130 interrupted (SIGINT / SIGTERM).
int bake_command(int argc, char** argv);

}  // namespace plm_cli

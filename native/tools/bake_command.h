// `photonlm bake SCENE.json -o DIR [options]`: bakes a JSON scene file
// (docs/scene-file.md) into one EXR per lightmap and OL group plus a report.
#pragma once

namespace plm_cli {

// argv: the arguments after "bake". Returns the process exit code:
// 0 ok, 1 bad input, 2 bake failure, 130 interrupted (SIGINT / SIGTERM).
int bake_command(int argc, char** argv);

}  // namespace plm_cli

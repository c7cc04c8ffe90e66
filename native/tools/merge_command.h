// `photonlm merge PART... -o DIR [--scene SCENE.json] [--threads N] [--target-error X]`:
// merges the part files of a sharded bake into the bake's EXRs and report.json
// (with --target-error, report.json's "target" says whether the estimate met it).
#pragma once

namespace plm_cli {

// argv: the arguments after "merge". Exit codes as bake_command's.
int merge_command(int argc, char** argv);

}  // namespace plm_cli

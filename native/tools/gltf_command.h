// `photonlm gltf SCENE.json BAKE_DIR -o FILE.glb` (gltf_command.cpp).
#pragma once

namespace plm_cli {

// argv: the arguments after "gltf". Returns the exit code.
int gltf_command(int argc, char** argv);

}  // namespace plm_cli

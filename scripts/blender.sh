#!/usr/bin/env bash
# Runs one of the Blenders photonlm is tested in, with the engine it can load:
#
#     scripts/blender.sh 3.4|4.3|5.2|PATH [BLENDER ARGUMENTS...]
#
#   3.4   this machine's own Blender (Debian 12), with the engine as built (build/lib)
#   4.3   Debian 13's Blender, 5.2: Debian sid's (5.2 LTS), each in a root made once by
#         scripts/blender_root.sh and run by scripts/in_root.sh; the engine is the add-on's
#         self-contained copy (build/addon_stage/.../lib/photonlm), whose libraries travel with it
#   PATH  a Blender executable (a blender.org build, say), with the self-contained engine
#
# PHOTONLM_LIBRARY and PHOTONLM_CLI are set for the chosen Blender unless already set. A root that
# cannot be made fails here with blender_root.sh's message.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
top=$(dirname "$here")
which=${1:?usage: scripts/blender.sh 3.4|4.3|5.2|PATH [BLENDER ARGUMENTS...]}
shift
build=${PHOTONLM_BUILD_DIR:-$top/build}
bundled="$build/addon_stage/photonlm_blender/lib/photonlm"
portable() {
  [ -f "$bundled/libphotonlm.so" ] || { echo "blender.sh: $bundled/libphotonlm.so is missing: run scripts/build.sh" >&2; exit 1; }
  export PHOTONLM_LIBRARY=${PHOTONLM_LIBRARY:-$bundled/libphotonlm.so}
  export PHOTONLM_CLI=${PHOTONLM_CLI:-$build/portable/photonlm}
}
case "$which" in
  3.4)
    export PHOTONLM_LIBRARY=${PHOTONLM_LIBRARY:-$build/lib/libphotonlm.so}
    exec blender "$@" ;;
  4.3|5.2)
    suite=$([ "$which" = 4.3 ] && echo trixie || echo sid)
    root=$("$here/blender_root.sh" "$suite" | tail -n1)
    portable
    exec "$here/in_root.sh" "$root" blender "$@" ;;
  *)
    [ -x "$which" ] || { echo "blender.sh: '$which' is neither 3.4, 4.3, 5.2 nor a Blender executable" >&2; exit 2; }
    portable
    exec "$which" "$@" ;;
esac

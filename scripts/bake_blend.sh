#!/usr/bin/env bash
# Bake a .blend file's PhotonLM lightmaps in headless Blender (no UI):
#   scripts/bake_blend.sh FILE.blend [-o DIR] [--target-error E] [--time-budget S] [--photons N]
#                         [--seed N] [--save [--pack]] [--export-scene SCENE.json]
# Uses this source tree's add-on and build/lib/libphotonlm.so (or $PHOTONLM_LIBRARY; without
# either, the add-on installed in Blender). Prints progress and the reached error; exits non-zero
# with a message on failure. See docs/batch-baking.md.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
if [ $# -lt 1 ] || [ "${1#-}" != "$1" ]; then
  sed -n '2,7p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 1
fi
blend="$1"; shift
if [ ! -f "$blend" ]; then
  echo "bake_blend: error: no such file: $blend" >&2
  exit 1
fi
if [ -z "${PHOTONLM_LIBRARY:-}" ] && [ -f "$here/build/lib/libphotonlm.so" ]; then
  export PHOTONLM_LIBRARY="$here/build/lib/libphotonlm.so"
fi
export PHOTONLM_SOURCE_DIR="${PHOTONLM_SOURCE_DIR:-$here}"
exec "${BLENDER:-blender}" -b "$blend" --python-exit-code 1 --python "$here/scripts/bake_blend.py" -- "$@"

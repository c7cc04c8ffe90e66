#!/usr/bin/env bash
# README command 1: install what is missing, build, bake the demo Cornell box
# through the Blender add-on in headless Blender. Writes out/demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install_deps.sh
scripts/build.sh
export PHOTONLM_LIBRARY="$PWD/build/lib/libphotonlm.so"
blender -b --factory-startup --python-exit-code 1 --python scripts/demo_bake.py -- --out "$PWD/out/demo"

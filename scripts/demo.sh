#!/usr/bin/env bash
# README command 1: install what is missing, build, bake the demo Cornell box
# through the Blender add-on in headless Blender. Writes out/demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install_deps.sh
scripts/build.sh
# The Blender: $BLENDER (a Blender executable, e.g. a blender.org build, or 3.4 / 4.3 / 5.2 for the
# ones scripts/blender.sh knows), else the newest at hand: Debian sid's 5.2 or Debian 13's 4.3 where
# scripts/blender_root.sh has made their root, else this machine's own.
blender=${BLENDER:-}
if [ -z "$blender" ]; then
  roots=${PHOTONLM_ROOTS:-/var/cache/photonlm/roots}
  if [ -f "$roots/sid/.photonlm-root" ]; then blender=5.2
  elif [ -f "$roots/trixie/.photonlm-root" ]; then blender=4.3
  else blender=3.4
  fi
fi
echo "demo: baking in Blender $blender (set BLENDER= to choose)"
scripts/blender.sh "$blender" -b --factory-startup --python-exit-code 1 --python scripts/demo_bake.py -- --out "$PWD/out/demo"

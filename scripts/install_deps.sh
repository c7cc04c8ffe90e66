#!/usr/bin/env bash
# Installs the Debian 12 packages photonlm needs, only if some are missing.
set -euo pipefail
packages=(cmake g++ make libembree-dev libopenexr-dev libstb-dev openimageio-tools libtbb-dev
          libgtest-dev libbenchmark-dev python3-numpy python3-pytest python3-matplotlib blender xvfb
          clang libclang-rt-14-dev nlohmann-json3-dev libosd-dev libtinygltf-dev patchelf
          slurmd slurmctld slurm-client munge chromium python3-pil)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# Node.js and npm build the web viewer (web/); a Node.js from elsewhere (nodesource, with its own npm) is
# kept, Debian's are installed where there is no npm.
command -v npm >/dev/null || missing+=(nodejs npm)
if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#packages[@]} packages and npm present"
  exit 0
fi
echo "install_deps: installing ${missing[*]}"
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"

#!/usr/bin/env bash
# Makes (once) a Debian root file system with a newer Debian's own Blender in it, for the tests and the
# demo to run that Blender without touching this machine's packages:
#
#     scripts/blender_root.sh trixie     # Debian 13: Blender 4.3
#     scripts/blender_root.sh sid        # Debian unstable: the newest Blender (5.2 LTS)
#
# Prints the root's path on its last line. The root is made with debootstrap from Debian's archive
# (the mirror this machine's apt uses), gets blender, xvfb, python3-numpy and what that Blender's
# extension system imports, and is cached in $PHOTONLM_ROOTS (default /var/cache/photonlm/roots):
# a finished root carries a stamp file, a half-made one (an interrupted run) is removed and made
# again. Run Blender in it with scripts/in_root.sh. Needs root (or sudo): debootstrap and chroot do.
set -euo pipefail
suite=${1:?usage: scripts/blender_root.sh trixie|sid}
case "$suite" in trixie|sid) ;; *) echo "blender_root: unknown suite '$suite' (trixie or sid)" >&2; exit 2;; esac
roots=${PHOTONLM_ROOTS:-/var/cache/photonlm/roots}
root="$roots/$suite"
stamp="$root/.photonlm-root"
# xvfb, xauth: windowed tests; libegl1, libegl-mesa0: EEVEE renders headless (-b); x11-apps, netpbm:
# screen grabs for the docs' screenshots where Blender's own read back black (llvmpipe);
# python3-cattr, python3-requests: sid's extension system.
packages="blender xvfb xauth libegl1 libegl-mesa0 x11-apps netpbm python3-numpy python3-cattr python3-requests ca-certificates"
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$packages" ]; then
  echo "$root"; exit 0
fi
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
if ! command -v debootstrap >/dev/null; then
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends debootstrap >&2
fi
# The mirror this machine's apt already reaches (deb822 or one-line sources).
mirror=$(grep -rhoE '^(URIs:\s*|deb\s+)\S+' /etc/apt/sources.list /etc/apt/sources.list.d/ 2>/dev/null \
         | awk '{print $NF}' | grep -E '/debian/?$' | head -n1 || true)
mirror=${mirror:-http://deb.debian.org/debian}
lock="$roots/.$suite.lock"
$sudo mkdir -p "$roots"
exec 9>"$lock"
flock 9
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$packages" ]; then
  echo "$root"; exit 0
fi
if [ -f "$stamp" ]; then  # a finished root made for another package list: install what it lacks
  echo "blender_root: installing $packages into the $suite root" >&2
  if env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin DEBIAN_FRONTEND=noninteractive "$(dirname "$0")/in_root.sh" "$root" \
       sh -c "apt-get update -qq && apt-get install -y -qq --no-install-recommends $packages && apt-get clean" \
       > "$roots/$suite.packages.log" 2>&1; then
    echo "$packages" | $sudo tee "$stamp" >/dev/null
    echo "$root"; exit 0
  fi
  tail -n 20 "$roots/$suite.packages.log" >&2
  echo "blender_root: could not add packages to the $suite root; making it again" >&2
fi
echo "blender_root: making a Debian $suite root in $root from $mirror (once; a few minutes)" >&2
$sudo rm -rf "$root"
t0=$(date +%s)
if ! $sudo debootstrap --variant=minbase "$suite" "$root" "$mirror" > "$roots/$suite.debootstrap.log" 2>&1; then
  tail -n 20 "$roots/$suite.debootstrap.log" >&2
  echo "blender_root: debootstrap of $suite from $mirror failed (log: $roots/$suite.debootstrap.log)" >&2
  exit 1
fi
# sid's Release file can be past its Valid-Until date; apt refuses it unless told not to check.
echo 'Acquire::Check-Valid-Until "false";' | $sudo tee "$root/etc/apt/apt.conf.d/99photonlm" >/dev/null
echo "deb $mirror $suite main" | $sudo tee "$root/etc/apt/sources.list" >/dev/null
if ! env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin DEBIAN_FRONTEND=noninteractive \
     "$(dirname "$0")/in_root.sh" "$root" sh -c "apt-get update -qq && apt-get install -y -qq --no-install-recommends $packages && apt-get clean" \
     > "$roots/$suite.packages.log" 2>&1; then
  tail -n 20 "$roots/$suite.packages.log" >&2
  echo "blender_root: installing $packages into the $suite root failed (log: $roots/$suite.packages.log)" >&2
  exit 1
fi
version=$("$(dirname "$0")/in_root.sh" "$root" blender --version 2>/dev/null | head -n1 || true)
echo "$packages" | $sudo tee "$stamp" >/dev/null
echo "blender_root: $suite root ready in $(( $(date +%s) - t0 )) s: ${version:-blender --version printed nothing}" >&2
echo "$root"

#!/usr/bin/env bash
# Runs a command inside a root made by scripts/blender_root.sh, in a mount namespace of its own:
# /proc, /dev, /sys, /tmp and the checkout (at the same path) are mounted for the command only, so
# nothing stays mounted when it ends or dies.
#
#     scripts/in_root.sh ROOT COMMAND [ARGS...]
#
# The environment passes through, less what would point the root's programs at this machine's
# libraries (LD_LIBRARY_PATH, LD_PRELOAD, PYTHONHOME, PYTHONPATH).
set -euo pipefail
root=${1:?usage: scripts/in_root.sh ROOT COMMAND [ARGS...]}
shift
checkout=$(cd "$(dirname "$0")/.." && pwd)
[ -x "$root/usr/bin/env" ] || { echo "in_root: $root is not a root made by scripts/blender_root.sh" >&2; exit 2; }
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
# The bind targets are made in the root once (they stay empty directories outside the namespace);
# those under /tmp are made inside the namespace, on its fresh /tmp.
for d in proc dev sys tmp; do [ -d "$root/$d" ] || $sudo mkdir -p "$root/$d"; done
[ -z "${PHOTONLM_TEST_OUT:-}" ] || mkdir -p "$PHOTONLM_TEST_OUT"
here=$PWD
case "$here" in "$checkout"*|"${PHOTONLM_TEST_OUT:-/nonexistent}"*) ;; *) here=$checkout;; esac
exec $sudo env -u LD_LIBRARY_PATH -u LD_PRELOAD -u PYTHONHOME -u PYTHONPATH \
  PHOTONLM_IN_ROOT_DIR="$root" PHOTONLM_IN_ROOT_CHECKOUT="$checkout" PHOTONLM_IN_ROOT_CWD="$here" \
  unshare --mount --propagation private -- bash -c '
    set -e
    r=$PHOTONLM_IN_ROOT_DIR; c=$PHOTONLM_IN_ROOT_CHECKOUT
    mount -t proc proc "$r/proc"
    mount --rbind /dev "$r/dev"
    mount --rbind /sys "$r/sys"
    mount -t tmpfs tmpfs "$r/tmp"
    mkdir -p "$r$c"
    mount --bind "$c" "$r$c"
    if [ -n "${PHOTONLM_TEST_OUT:-}" ] && [ "${PHOTONLM_TEST_OUT#$c}" = "$PHOTONLM_TEST_OUT" ]; then
      mkdir -p "$r$PHOTONLM_TEST_OUT"
      mount --bind "$PHOTONLM_TEST_OUT" "$r$PHOTONLM_TEST_OUT"
    fi
    w=$PHOTONLM_IN_ROOT_CWD
    unset PHOTONLM_IN_ROOT_DIR PHOTONLM_IN_ROOT_CHECKOUT PHOTONLM_IN_ROOT_CWD
    exec chroot "$r" /bin/sh -c '"'"'cd "$1"; shift; exec /usr/bin/env \
      PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin HOME=/root "$@"'"'"' sh "$w" "$@"
  ' in_root "$@"

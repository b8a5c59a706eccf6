#!/usr/bin/env bash
# Installs what the OpenXR check needs on a Debian bookworm machine: a Debian
# trixie chroot with the Monado runtime (monado-service, its OpenXR runtime
# library, the OpenXR loader) and Mesa's lavapipe. Monado is packaged only in
# trixie (it needs glibc >= 2.38); dmu's binaries, built on bookworm, run
# inside the chroot unchanged (scripts/xr-check.sh bind-mounts them in).
#
# Idempotent: a finished chroot carries a stamp naming its packages and is
# reused; an interrupted debootstrap (DIR.partial) is started again.
#
#   scripts/xr-setup.sh            # chroot at $DMU_XR_ROOT (default /var/lib/dmu-xr/trixie)
#
# Environment: DMU_XR_ROOT (the chroot), DMU_XR_MIRROR (default
# http://deb.debian.org/debian). Needs root. Prints the chroot's path last.
set -euo pipefail

ROOT="${DMU_XR_ROOT:-/var/lib/dmu-xr/trixie}"
MIRROR="${DMU_XR_MIRROR:-http://deb.debian.org/debian}"
PACKAGES="monado-service libopenxr1-monado libopenxr-loader1 mesa-vulkan-drivers"
STAMP="$ROOT/.dmu-xr-ready"

if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$PACKAGES" ]; then
    echo "$ROOT"
    exit 0
fi
if [ "$(id -u)" != 0 ]; then
    echo "error: xr-setup.sh: building the chroot at $ROOT needs root" >&2
    exit 2
fi

if ! command -v debootstrap >/dev/null 2>&1; then
    apt-get update -qq
    apt-get install -y -qq debootstrap >/dev/null
fi

mkdir -p "$(dirname "$ROOT")"
if [ ! -d "$ROOT" ]; then
    # Built beside its final place and renamed when complete, so a chroot at
    # $ROOT is never half made.
    PARTIAL="$ROOT.partial"
    rm -rf "$PARTIAL"
    echo "xr-setup: debootstrap trixie (minbase) into $PARTIAL from $MIRROR" >&2
    start=$(date +%s)
    debootstrap --variant=minbase trixie "$PARTIAL" "$MIRROR" >"$(dirname "$ROOT")/debootstrap.log" 2>&1 || {
        echo "error: xr-setup.sh: debootstrap failed; see $(dirname "$ROOT")/debootstrap.log" >&2
        exit 2
    }
    mv "$PARTIAL" "$ROOT"
    echo "xr-setup: debootstrap took $(($(date +%s) - start)) s" >&2
fi

# apt inside the chroot wants /proc and /dev; unmounted again on any exit.
mounted=()
cleanup() {
    local i
    for ((i = ${#mounted[@]} - 1; i >= 0; i--)); do umount "${mounted[$i]}" 2>/dev/null || umount -l "${mounted[$i]}" || true; done
}
trap cleanup EXIT
for d in proc dev; do
    if ! mountpoint -q "$ROOT/$d"; then
        mount --bind "/$d" "$ROOT/$d"
        mounted+=("$ROOT/$d")
    fi
done

start=$(date +%s)
echo "xr-setup: installing $PACKAGES in the chroot" >&2
# shellcheck disable=SC2086 # the package list is meant to split
chroot "$ROOT" /usr/bin/env DEBIAN_FRONTEND=noninteractive LC_ALL=C \
    sh -c "apt-get update -qq && apt-get install -y -qq --no-install-recommends $PACKAGES" \
    >"$(dirname "$ROOT")/apt.log" 2>&1 || {
    echo "error: xr-setup.sh: installing $PACKAGES in $ROOT failed; see $(dirname "$ROOT")/apt.log" >&2
    exit 2
}
chroot "$ROOT" apt-get clean
echo "xr-setup: packages took $(($(date +%s) - start)) s" >&2
printf '%s' "$PACKAGES" >"$STAMP.tmp"
sync "$STAMP.tmp"
mv "$STAMP.tmp" "$STAMP"
echo "$ROOT"

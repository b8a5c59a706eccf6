#!/usr/bin/env bash
# The Python module and the Ray example: builds the wheel with its `cad`
# extra (OpenCascade's OCP and IfcOpenShell, which read STEP and IFC) into a
# fresh venv (target/py-venv), installs pytest, ray, bcf-client (IfcOpenShell's BCF
# library, the independent reader and writer of the BCF tests) and embreex
# (Embree, the ray tracer picks are compared with), and runs crates/dmu-py/tests
# against the `dmu` binary of the workspace build (DMU_BIN). Under CI=true a
# missing prerequisite fails; elsewhere it prints SKIPPED and exits 0.
set -euo pipefail
cd "$(dirname "$0")/.."

skip() {
    if [ "${CI:-}" = "true" ]; then
        echo "error: $1" >&2
        exit 1
    fi
    echo "SKIPPED: Python tests: $1"
    exit 0
}

command -v python3 >/dev/null 2>&1 || skip "python3 not found"
python3 -c 'import ensurepip, venv' 2>/dev/null || skip "python3 cannot make a venv (install python3-venv)"
: "${DMU_BIN:=target/debug/dmu}"
[ -x "$DMU_BIN" ] || skip "no dmu binary at $DMU_BIN (cargo build --workspace first)"
export DMU_BIN="$PWD/$DMU_BIN"

venv=target/py-venv
rm -rf "$venv"
python3 -m venv "$venv"
start=$(date +%s)
# The dev profile builds in half the time of release; the tests' models are small.
MATURIN_PEP517_ARGS="--profile dev" "$venv/bin/pip" install --quiet --disable-pip-version-check './crates/dmu-py[cad]' pytest 'ray>=2.9' bcf-client embreex ||
    skip "pip could not install the wheel with its cad extra, pytest, ray, bcf-client or embreex"
echo "wheel and packages installed in $(($(date +%s) - start)) s"
# -s: the Ray test prints its 1- and 2-worker times into the log.
"$venv/bin/python" -m pytest -rs -q -s crates/dmu-py/tests

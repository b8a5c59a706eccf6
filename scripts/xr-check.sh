#!/usr/bin/env bash
# The VR check on a real OpenXR runtime: Monado (null compositor, simulated
# headset) in the trixie chroot that scripts/xr-setup.sh makes, dmu-viewer
# --xr on the built-in 2M plant for 120+ frames with a scripted hand (look
# around, aim at a part, grab it into a clash, release, undo), then checks:
#   - the session reached FOCUSED, >= 120 frames were submitted, it exited
#     cleanly (EXITING after the exit request, exit status 0);
#   - both eye images show the plant (pixels that are not background);
#   - the parallax is right: at the known points the report gives (world
#     points seen from between the eyes, projected analytically into both
#     eyes from the runtime's eye poses and fields of view), a patch of the
#     left image is found in the right image at the analytic disparity
#     within 1 px, sign included;
#   - the grab gave the same part transform and clashes as the same drag in
#     the desktop viewer (run under Xvfb with the equivalent --script).
# Writes OUT/left.png, OUT/right.png, OUT/report.json (the viewer's report),
# OUT/desktop.json, OUT/check.json (what was checked, with the figures) and
# OUT/monado.log. Exit status 0 when every check passes, 1 when one fails,
# 2 when something needed is missing.
#
#   scripts/xr-check.sh OUT
#
# Environment: DMU_VIEWER (the binary; default target/debug/dmu-viewer, built
# when missing), DMU_XR_ROOT (the chroot, as xr-setup.sh), DMU_XR_FRAMES
# (default 120), DMU_XR_EYE_PX (default 640). Needs root (chroot, mounts).
set -euo pipefail
cd "$(dirname "$0")/.."
REPO=$(pwd)

if [ $# -ne 1 ]; then
    echo "usage: scripts/xr-check.sh OUT" >&2
    exit 2
fi
mkdir -p "$1"
OUT=$(cd "$1" && pwd)
FRAMES="${DMU_XR_FRAMES:-120}"
EYE_PX="${DMU_XR_EYE_PX:-640}"
SCRIPT="$REPO/scripts/xr/walkthrough.json"

ROOT=$(scripts/xr-setup.sh | tail -n 1)
VIEWER="${DMU_VIEWER:-$REPO/target/debug/dmu-viewer}"
if [ ! -x "$VIEWER" ]; then
    echo "xr-check: building dmu-viewer" >&2
    cargo build --workspace --locked >&2
    VIEWER="$REPO/target/debug/dmu-viewer"
fi
command -v xvfb-run >/dev/null 2>&1 || {
    echo "error: xr-check.sh: xvfb-run is missing (apt-get install xvfb xauth): the desktop run needs it" >&2
    exit 2
}

# Everything the chroot sees of this run lives under one directory, made and
# removed (with its mounts) here.
RUN="/opt/dmu-xr-check.$$"
HOST_RUN="$ROOT$RUN"
mkdir -p "$HOST_RUN/out" "$HOST_RUN/xdg"
chmod 700 "$HOST_RUN/xdg"
touch "$HOST_RUN/dmu-viewer"
cp "$SCRIPT" "$HOST_RUN/walkthrough.json"
mounted=()
MONADO_PID=
cleanup() {
    local i
    exec 3>&- 2>/dev/null || true
    if [ -n "$MONADO_PID" ]; then
        kill "$MONADO_PID" 2>/dev/null || true
        wait "$MONADO_PID" 2>/dev/null || true
    fi
    for ((i = ${#mounted[@]} - 1; i >= 0; i--)); do umount "${mounted[$i]}" 2>/dev/null || umount -l "${mounted[$i]}" || true; done
    rm -rf "$HOST_RUN"
}
trap cleanup EXIT
bind() { # bind SRC DST [--rbind]
    mount "${3:---bind}" "$1" "$2"
    mounted+=("$2")
}
for d in proc sys dev; do
    mountpoint -q "$ROOT/$d" || bind "/$d" "$ROOT/$d" --rbind
done
bind "$VIEWER" "$HOST_RUN/dmu-viewer"
bind "$OUT" "$HOST_RUN/out"

in_chroot() {
    chroot "$ROOT" /usr/bin/env -i PATH=/usr/bin:/bin HOME=/tmp LC_ALL=C \
        XDG_RUNTIME_DIR="$RUN/xdg" NODEVICE_SELECT=1 \
        VK_ICD_FILENAMES=/usr/share/vulkan/icd.d/lvp_icd.json \
        XR_RUNTIME_JSON=/usr/share/openxr/1/openxr_monado.json \
        "$@"
}

# Monado: the null compositor and the simulated headset. Its standard input
# must be a pipe (with /dev/null it fails on epoll): a FIFO this script holds
# open until it ends.
mkfifo "$HOST_RUN/stdin"
in_chroot XRT_COMPOSITOR_NULL=1 SIMULATED_ENABLE=1 IPC_EXIT_ON_DISCONNECT=0 \
    monado-service <"$HOST_RUN/stdin" >"$OUT/monado.log" 2>&1 &
MONADO_PID=$!
exec 3>"$HOST_RUN/stdin"
for _ in $(seq 200); do
    [ -S "$HOST_RUN/xdg/monado_comp_ipc" ] && break
    kill -0 "$MONADO_PID" 2>/dev/null || break
    sleep 0.1
done
if [ ! -S "$HOST_RUN/xdg/monado_comp_ipc" ]; then
    echo "error: xr-check.sh: monado-service did not start; see $OUT/monado.log" >&2
    exit 2
fi

start_ms=$(($(date +%s%N) / 1000000))
set +e
in_chroot "$RUN/dmu-viewer" --xr --frames "$FRAMES" --eye-px "$EYE_PX" \
    --xr-script "$RUN/walkthrough.json" --save-eyes "$RUN/out" --json \
    >"$OUT/report.json.tmp" 2>"$OUT/viewer.log"
viewer_status=$?
set -e
xr_ms=$(($(date +%s%N) / 1000000 - start_ms))
sync "$OUT/report.json.tmp"
mv "$OUT/report.json.tmp" "$OUT/report.json"
if [ "$viewer_status" != 0 ]; then
    echo "error: xr-check.sh: dmu-viewer --xr exited with $viewer_status: $(tail -n 1 "$OUT/viewer.log")" >&2
    exit 1
fi
# The report names the saved eyes by their path inside the chroot.
sed -i "s#$RUN/out#$OUT#g" "$OUT/report.json"

# The same move in the desktop viewer: select the grabbed part, drag it by
# the grab's offset in as many steps.
python3 - "$OUT/report.json" "$SCRIPT" >"$OUT/desktop-script.json" <<'EOF'
import json, sys
report, script = (json.load(open(p)) for p in sys.argv[1:3])
grab = next(a["grab"] for a in script["actions"] if isinstance(a, dict) and "grab" in a)
if not report.get("grabbed_part"):
    sys.exit("the XR run grabbed no part")
json.dump([{"select": report["grabbed_part"]},
           {"drag": {"by": grab["by"], "steps": grab["frames"]}}], sys.stdout)
EOF
xvfb-run -a -s "-screen 0 1280x800x24" "$VIEWER" --width 640 --height 480 \
    --script "$OUT/desktop-script.json" >"$OUT/desktop.json" 2>"$OUT/desktop.log" || {
    echo "error: xr-check.sh: the desktop viewer failed: $(tail -n 1 "$OUT/desktop.log")" >&2
    exit 1
}

python3 - "$OUT" "$FRAMES" "$xr_ms" <<'EOF'
import json, os, struct, sys, zlib

out, frames_wanted, xr_s = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]) / 1000
report = json.load(open(f"{out}/report.json"))
desktop = json.load(open(f"{out}/desktop.json"))
checks = {}
failures = []

def check(name, ok, **figures):
    checks[name] = {"ok": bool(ok), **figures}
    if not ok:
        failures.append(f"{name}: {figures}")

def read_png(path):
    """RGBA8 or RGB8, non-interlaced PNG -> (width, height, rows of pixel tuples)."""
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path}: not a PNG"
    pos, idat, header = 8, b"", None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    w, h, depth, colour, _, _, interlace = header
    assert depth == 8 and colour in (2, 6) and interlace == 0, f"{path}: unexpected PNG format"
    bpp = 4 if colour == 6 else 3
    raw = zlib.decompress(idat)
    stride = w * bpp
    rows, prev = [], bytearray(stride)
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if f == 1: line[i] = (line[i] + a) & 255
            elif f == 2: line[i] = (line[i] + b) & 255
            elif f == 3: line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append([tuple(line[x * bpp:x * bpp + 3]) for x in range(w)])
        prev = line
    return w, h, rows

# Session: state, frames, exit.
check("focused", report.get("max_session_state") == "FOCUSED", max_session_state=report.get("max_session_state"))
check("frames", report.get("frames_submitted", 0) >= frames_wanted, frames_submitted=report.get("frames_submitted"), wanted=frames_wanted)
check("clean_exit", report.get("exit") == "clean" and report.get("final_state") == "EXITING",
      exit=report.get("exit"), final_state=report.get("final_state"))

# Both eyes show the plant: pixels away from the background colour (the
# renderer's clear colour, linear (0.02, 0.025, 0.035), sRGB-encoded).
def srgb(v):
    return round(255 * (12.92 * v if v <= 0.0031308 else 1.055 * v ** (1 / 2.4) - 0.055))
background = tuple(srgb(v) for v in (0.02, 0.025, 0.035))
images = {}
for eye in ("left", "right"):
    w, h, rows = read_png(f"{out}/{eye}.png")
    gray = [[(30 * p[0] + 59 * p[1] + 11 * p[2]) / 100 for p in row] for row in rows]
    covered = sum(1 for row in rows for p in row if max(abs(p[i] - background[i]) for i in range(3)) > 3)
    images[eye] = gray
    check(f"{eye}_shows_plant", covered >= 0.05 * w * h, covered_pixels=covered, pixels=w * h)

# Parallax at the known points: a patch of the left image around each is
# found in the right image (least squares along the row, sub-pixel) where the
# patch has an edge to match, one clear best match, and a narrow range of
# disparities (at most 1 px between its nearest and farthest content, from the
# report's samples). The measured shift must lie within that range, give or
# take 1 px, for 85 % of the points, and the median error against the point's
# analytic disparity must be under 0.5 px. The same measurement with the eyes
# swapped must fail where the disparity is at least 1 px (a control: the check
# can fail, and the sign is right).
SEARCH = 16
def patch(img, cx, cy, R):
    return [img[y][x] for y in range(cy - R, cy + R + 1) for x in range(cx - R, cx + R + 1)]
def measure(first, second):
    h, w = len(first), len(first[0])
    found = []
    for p in report.get("known_points", []):
        lx, ly = p["left_px"]
        cx, cy, R = int(lx), int(ly), int(p["patch_px"])
        low, high = p["patch_disparity_px"]
        if not (R + SEARCH <= cx < w - R - SEARCH and R <= cy < h - R) or high - low > 1.0:
            continue
        a = patch(first, cx, cy, R)
        # An edge to match (a step of 24 grey levels across the row): the
        # headlight's smooth shading of a face follows the screen, not the
        # scene, and would match at no shift.
        side = 2 * R + 1
        if max(abs(a[k + 1] - a[k]) for k in range(len(a) - 1) if (k + 1) % side) < 24:
            continue
        costs = [sum((u - v) ** 2 for u, v in zip(a, patch(second, cx + s, cy, R)))
                 for s in range(-SEARCH, SEARCH + 1)]
        i = min(range(len(costs)), key=costs.__getitem__)
        # An ambiguous match (repeated texture: another minimum nearly as
        # good, away from this one) measures nothing.
        others = [c for j, c in enumerate(costs) if abs(j - i) > 2
                  and 0 < j < len(costs) - 1 and c <= costs[j - 1] and c <= costs[j + 1]]
        if others and min(others) < 2 * costs[i] + 1e-9:
            continue
        shift = i - SEARCH
        if 0 < i < len(costs) - 1:  # sub-pixel: the parabola through the minimum
            c0, c1, c2 = costs[i - 1], costs[i], costs[i + 1]
            if c0 - 2 * c1 + c2 > 0:
                shift += 0.5 * (c0 - c2) / (c0 - 2 * c1 + c2)
        # What the left eye shows at x the right eye shows at x + shift: the
        # disparity (left x - right x) is -shift.
        found.append({"part": p["part"], "distance": p["distance"], "analytic_px": p["disparity_px"],
                      "range_px": [low, high], "measured_px": -shift,
                      "error_px": -shift - p["disparity_px"],
                      "consistent": low - 1.0 <= -shift <= high + 1.0})
    return found
measured = measure(images["left"], images["right"])
swapped = measure(images["right"], images["left"])
errors = sorted(abs(m["error_px"]) for m in measured)
median_error = errors[len(errors) // 2] if errors else None
consistent = sum(m["consistent"] for m in measured)
signed = [m for m in swapped if m["range_px"][0] >= 1.0]
swapped_consistent = sum(m["consistent"] for m in signed)
check("parallax", len(measured) >= 8 and consistent >= 0.85 * len(measured) and median_error < 0.5
      and len(signed) >= 3 and swapped_consistent <= 0.25 * len(signed),
      points=len(measured), consistent=consistent, median_error_px=median_error,
      swapped_sign_points=len(signed), swapped_consistent=swapped_consistent,
      ipd_m=report.get("ipd_m"), samples=measured)

# The grab against the same drag on the desktop.
grab = report.get("grab") or {}
drag = desktop["steps"][-1] if desktop.get("steps") else {}
def key(c):
    return (min(c["a"], c["b"]), max(c["a"], c["b"]), c["kind"])
same = (grab.get("path") == drag.get("path") and grab.get("translation") == drag.get("translation")
        and grab.get("matrix3") == drag.get("matrix3")
        and sorted(map(key, grab.get("clashes", []))) == sorted(map(key, drag.get("clashes", []))))
check("grab_equals_desktop", same and len(grab.get("clashes", [])) > 0 and grab.get("tree_valid") is True,
      part=grab.get("path"), tree_valid=grab.get("tree_valid"),
      xr_translation=grab.get("translation"), desktop_translation=drag.get("translation"),
      xr_clashes=grab.get("clashes"), desktop_clashes=drag.get("clashes"))
undone = report.get("after", {})
check("undo_restores", undone.get("translation") is not None and undone.get("translation") != grab.get("translation"),
      after_undo=undone.get("translation"))

summary = {"ok": not failures, "runtime": report.get("runtime"), "xr_run_s": xr_s,
           "eye_frame_ms_median": {e: report["eye_frame_ms"][e].get("median") for e in ("left", "right")},
           "checks": checks}
tmp = f"{out}/check.json.tmp"
with open(tmp, "w") as f:
    json.dump(summary, f, indent=2)
    f.flush()
    os.fsync(f.fileno())
os.replace(tmp, f"{out}/check.json")
for name, c in checks.items():
    print(f"{'ok  ' if c['ok'] else 'FAIL'} {name}: " + ", ".join(f"{k}={v}" for k, v in c.items() if k not in ("ok", "samples")))
if failures:
    sys.exit(1)
EOF
echo "xr-check: passed ($OUT/check.json)"

#!/usr/bin/env bash
# The VR check on a real OpenXR runtime: Monado (null compositor, simulated
# headset and two simulated WMR controllers) in the trixie chroot that
# scripts/xr-setup.sh makes, dmu-viewer --xr on the built-in 2M plant for
# 120+ frames with a scripted hand (look around, aim at a part, grab it into
# a clash, release, undo), recording the session, and a second, short session
# (the frame budget, the thumbsticks walking and turning), then checks:
#   - the session reached FOCUSED, >= 120 frames were submitted, it exited
#     cleanly (EXITING after the exit request, exit status 0);
#   - the controllers' actions: bindings suggested for every profile were
#     accepted, the actions were synced on focused frames, the runtime bound
#     an interaction profile and located an aim pose for both hands;
#   - a haptic pulse (xrApplyHapticFeedback, accepted) when the grabbed part
#     entered a hard clash, once per entry, as the replay below finds them;
#   - the recording replays in `dmu collide --record` to the clashes the
#     session saw at every recorded step;
#   - the thumbsticks walked and turned the tracking space as far as their
#     speeds, the dead zone and the runtime's display periods say (second
#     session);
#   - both eye images show the plant (pixels that are not background);
#   - the parallax is right: at the known points the report gives (world
#     points seen from between the eyes, projected analytically into both
#     eyes from the runtime's eye poses and fields of view), a patch of the
#     left image is found in the right image at the analytic disparity
#     within 1 px, sign included;
#   - the grab gave the same part transform and clashes as the same drag in
#     the desktop viewer (run under Xvfb with the equivalent --script), and
#     the hand moved the part by the script's offset;
#   - both eyes culled once and drawn apart, alternate frames of the main
#     session (--xr-stereo compare), timed (their ratio in check.json);
#   - comfort: a second, short session with the frame budget from the
#     display period (--xr-budget display): frames over the period are
#     counted late, and the budget draws coarser after a late frame.
# The main session runs with --culling frustum (occlusion culling's switch is
# timed, so a frame of it may come out of a re-probe with chunks a frame late,
# and the parallax check then finds too few patches) and --xr-budget off
# (exact images, for the parallax
# check; it ends where the walkthrough leaves the view). Writes OUT/left.png, OUT/right.png, OUT/report.json (the viewer's
# report), OUT/comfort.json (the second session's), OUT/session.jsonl (the
# recording), OUT/replay.json, OUT/desktop.json, OUT/check.json (what was
# checked, with the figures) and OUT/monado.log. Exit status 0 when every
# check passes, 1 when one fails, 2 when something needed is missing.
#
#   scripts/xr-check.sh OUT
#
# Environment: DMU_VIEWER (the binary; default target/debug/dmu-viewer, built
# when missing), DMU_BIN (the dmu command line, for the replay; default beside
# DMU_VIEWER), DMU_XR_ROOT (the chroot, as xr-setup.sh), DMU_XR_FRAMES
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
LOCOMOTION="$REPO/scripts/xr/locomotion.json"

ROOT=$(scripts/xr-setup.sh | tail -n 1)
VIEWER="${DMU_VIEWER:-$REPO/target/debug/dmu-viewer}"
if [ ! -x "$VIEWER" ]; then
    echo "xr-check: building dmu-viewer" >&2
    cargo build --workspace --locked >&2
    VIEWER="$REPO/target/debug/dmu-viewer"
fi
DMU="${DMU_BIN:-$(dirname "$VIEWER")/dmu}"
if [ ! -x "$DMU" ]; then
    echo "error: xr-check.sh: the dmu command line is missing at $DMU (set DMU_BIN): the replay needs it" >&2
    exit 2
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
cp "$LOCOMOTION" "$HOST_RUN/locomotion.json"
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

# Monado: the null compositor, the simulated headset and two simulated
# Windows Mixed Reality controllers (static poses, buttons at rest, haptics
# accepted). Its standard input
# must be a pipe (with /dev/null it fails on epoll): a FIFO this script holds
# open until it ends.
mkfifo "$HOST_RUN/stdin"
in_chroot XRT_COMPOSITOR_NULL=1 SIMULATED_ENABLE=1 SIMULATED_LEFT=wmr SIMULATED_RIGHT=wmr \
    IPC_EXIT_ON_DISCONNECT=0 \
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
rm -f "$OUT/session.jsonl"
in_chroot "$RUN/dmu-viewer" --xr --frames "$FRAMES" --eye-px "$EYE_PX" \
    --xr-script "$RUN/walkthrough.json" --save-eyes "$RUN/out" --xr-budget off --xr-stereo compare \
    --culling frustum \
    --record "$RUN/out/session.jsonl" --json \
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
# The report names the saved eyes and the recording by their paths inside the chroot.
sed -i "s#$RUN/out#$OUT#g" "$OUT/report.json"

# Comfort and locomotion: a short session with the budget from the display
# period, the thumbsticks walking and turning (the same Monado, the same
# model; apart from the main session, whose last view the parallax check
# wants where the walkthrough leaves it).
set +e
in_chroot "$RUN/dmu-viewer" --xr --frames "${DMU_XR_COMFORT_FRAMES:-24}" --eye-px "$EYE_PX" \
    --xr-script "$RUN/locomotion.json" --xr-budget display --json \
    >"$OUT/comfort.json.tmp" 2>"$OUT/comfort.log"
comfort_status=$?
set -e
sync "$OUT/comfort.json.tmp"
mv "$OUT/comfort.json.tmp" "$OUT/comfort.json"
if [ "$comfort_status" != 0 ]; then
    echo "error: xr-check.sh: the comfort session exited with $comfort_status: $(tail -n 1 "$OUT/comfort.log")" >&2
    exit 1
fi

# The recording replayed by the command line on the same (built-in) model,
# each step checked where it ends, as the viewer checks it.
set +e
"$DMU" collide --record "$OUT/session.jsonl" --clearance 0 --discrete --json \
    >"$OUT/replay.json" 2>"$OUT/replay.log"
replay_status=$?
set -e
if [ "$replay_status" -gt 1 ]; then
    echo "error: xr-check.sh: dmu collide --record failed ($replay_status): $(tail -n 1 "$OUT/replay.log")" >&2
    exit 1
fi

# The same move in the desktop viewer: select the grabbed part, drag it by
# the offset the hand moved it (the script's offset, carried through the
# tracking space and back) in as many steps.
python3 - "$OUT/report.json" "$SCRIPT" >"$OUT/desktop-script.json" <<'EOF'
import json, sys
report, script = (json.load(open(p)) for p in sys.argv[1:3])
grab = next(a["grab"] for a in script["actions"] if isinstance(a, dict) and "grab" in a)
if not report.get("grabbed_part") or not (report.get("grab") or {}).get("offset"):
    sys.exit("the XR run grabbed no part")
json.dump([{"select": report["grabbed_part"]},
           {"drag": {"by": report["grab"]["offset"], "steps": grab["frames"]}}], sys.stdout)
EOF
xvfb-run -a -s "-screen 0 1280x800x24" "$VIEWER" --width 640 --height 480 \
    --script "$OUT/desktop-script.json" >"$OUT/desktop.json" 2>"$OUT/desktop.log" || {
    echo "error: xr-check.sh: the desktop viewer failed: $(tail -n 1 "$OUT/desktop.log")" >&2
    exit 1
}

python3 - "$OUT" "$FRAMES" "$xr_ms" "$SCRIPT" "$LOCOMOTION" <<'EOF'
import json, math, os, struct, sys, zlib

out, frames_wanted, xr_s = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]) / 1000
script = json.load(open(sys.argv[4]))
locomotion = json.load(open(sys.argv[5]))
report = json.load(open(f"{out}/report.json"))
comfort = json.load(open(f"{out}/comfort.json"))
desktop = json.load(open(f"{out}/desktop.json"))
replay = json.load(open(f"{out}/replay.json"))
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
def key(c, a="a", b="b"):
    return (min(c[a], c[b]), max(c[a], c[b]), c["kind"])
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
by = next(a["grab"]["by"] for a in script["actions"] if isinstance(a, dict) and "grab" in a)
offset = grab.get("offset") or [math.inf] * 3
check("hand_moved_by_the_script", max(abs(a - b) for a, b in zip(offset, by)) < 1e-6, offset=offset, by=by)

# The controllers through OpenXR actions, as Monado's simulated ones give them.
ctl = report.get("controllers", {})
bindings = ctl.get("bindings", [])
check("bindings_accepted", len(bindings) >= 5 and all(b["accepted"] for b in bindings),
      bindings=[(b["profile"], b["error"]) for b in bindings])
check("actions_synced", ctl.get("synced_frames", 0) >= frames_wanted // 2
      and all(ctl.get("profiles", {}).get(h) for h in ("left", "right"))
      and all(ctl.get("first_aim", {}).get(h) for h in ("left", "right")),
      synced_frames=ctl.get("synced_frames"), driven_frames=ctl.get("driven_frames"),
      profiles=ctl.get("profiles"), first_aim=ctl.get("first_aim"))

# The recording replayed: at every recorded step the clashes the session saw.
recorded = (report.get("recording") or {}).get("steps", [])
seen = [sorted(key(c) for c in s["clashes"]) for s in recorded]
replayed = [[] for _ in seen]
for c in replay.get("clashes", []):
    if c["step"] < len(replayed):
        replayed[c["step"]].append(key(c, "a_id", "b_id"))
replayed = [sorted(r) for r in replayed]
grab_frames = next(a["grab"]["frames"] for a in script["actions"] if isinstance(a, dict) and "grab" in a)
check("recording_replays", len(seen) == grab_frames + 1 and replay.get("summary", {}).get("steps") == len(seen)
      and replayed == seen and any(seen),
      recorded_steps=len(seen), replay_steps=replay.get("summary", {}).get("steps"),
      first_difference=next(({"step": i, "session": a, "replay": b} for i, (a, b) in enumerate(zip(seen, replayed)) if a != b), None))

# A haptic pulse each time the grabbed part entered a hard clash, by the
# replay's steps of the grab.
part = grab.get("part_id")
hard = [any(k[2] == "hard" and part in k[:2] for k in r) for r in replayed[:grab_frames]]
entries = sum(1 for i, h in enumerate(hard) if h and (i == 0 or not hard[i - 1]))
pulses = report.get("haptic_pulses", [])
hard_others = {k[0] if k[1] == part else k[1] for r in replayed[:grab_frames] for k in r if k[2] == "hard"}
check("haptic_on_hard_clash", entries >= 1 and len(pulses) == entries
      and all(p["result"] == "ok" for p in pulses) and all(p["other_id"] in hard_others for p in pulses),
      hard_clash_entries=entries, pulses=pulses)

# Locomotion: the left stick walks over the floor along where the head faces
# at MOVE_M_PER_S (2 m/s) times the deflection, the right stick's x turns
# clockwise about the head at TURN_DEG_PER_S (90 deg/s) times the deflection
# (the stick's value past the 0.15 dead zone, scaled to reach 1), each
# frame's time step its predicted display period: each controller action
# against the placement before and after it, in the comfort session.
def deflection(v, dead=0.15):
    return 0.0 if abs(v) <= dead else math.copysign((min(abs(v), 1.0) - dead) / (1 - dead), v)
periods = {f["frame"]: f["display_period_ms"] / 1000 for f in comfort.get("frames", [])}
steps = comfort.get("steps", [])
moves = []
for i, (a, st) in enumerate(zip(locomotion["actions"], steps)):
    if not (isinstance(a, dict) and "controller" in a) or i == 0:
        continue
    c = a["controller"]
    before, after = steps[i - 1]["placement"], st["placement"]
    t = sum(periods.get(st["frame"] - k, math.nan) for k in range(c["frames"]))
    if c.get("hand") == "left":
        got = math.dist(after["origin"][:2], before["origin"][:2])
        want = 2000 * math.hypot(*map(deflection, c["thumbstick"])) * t
    else:
        got = before["heading_deg"] - after["heading_deg"]
        want = 90 * deflection(c["thumbstick"][0]) * t
    moves.append({"hand": c.get("hand"), "got": got, "want": want, "seconds": t})
# A turn is exact; a walk follows the head's forward, which the simulated
# head turns a little frame by frame, so the straight line from start to end
# is at most the path and within 1 % of it.
def moved_right(m):
    if m["hand"] == "left":
        return m["want"] * 0.99 <= m["got"] <= m["want"] + 1e-6
    return abs(m["got"] - m["want"]) <= 1e-6 * max(1, abs(m["want"]))
check("locomotion", len(moves) == 5 and all(map(moved_right, moves))
      and any(m["hand"] == "left" and m["want"] > 0 for m in moves)
      and any(m["hand"] == "right" and m["want"] == 0 for m in moves), moves=moves)

# Comfort: frames over the display period are late; after a late frame the
# budget draws coarser (a higher LOD error or coverage threshold, unless at
# their maximum, or unless the late frame's drawing fits the next frame's
# budget: the runtime lengthens the display period after a missed display),
# never above the maximum.
frames = comfort.get("frames", [])
late = [f for f in frames if f["late"]]
pairs = [(a, b) for a, b in zip(frames, frames[1:]) if a["late"]]
coarser = bool(pairs) and all(b["lod_error_px"] > a["lod_error_px"] or b["min_pixels"] > a["min_pixels"]
                              or (a["lod_error_px"] >= 8.0 and a["min_pixels"] >= 32.0)
                              or a["render_ms"] <= b["display_period_ms"] for a, b in pairs)
check("comfort_budget", len(frames) >= 20 and comfort.get("frames_late") == len(late) and coarser
      and all(f["lod_error_px"] <= 8.0 and f["min_pixels"] <= 32.0 for f in frames),
      frames=len(frames), late=len(late), late_pairs=len(pairs), displays_missed=comfort.get("displays_missed"),
      display_period_ms=[f["display_period_ms"] for f in frames],
      render_ms=[round(f["render_ms"], 1) for f in frames],
      lod_error_px=[f["lod_error_px"] for f in frames], min_pixels=[f["min_pixels"] for f in frames])

# Culling once against drawing each eye apart, alternate frames of the main
# session (exact images both ways: the saved last frame is culled once).
render = report.get("render_ms", {})
once, apart = render.get("culled_once", {}).get("median"), render.get("per_eye", {}).get("median")
tri = report.get("triangles_drawn", {})
check("culled_once_timed", once is not None and apart is not None and report["frames"][-1]["culled_once"],
      culled_once_median_ms=once, per_eye_median_ms=apart, ratio=(once / apart) if once and apart else None,
      triangles_once=tri.get("culled_once", {}).get("median"), triangles_per_eye=tri.get("per_eye", {}).get("median"),
      multiview=report.get("stereo", {}).get("multiview"))

summary = {"ok": not failures, "runtime": report.get("runtime"), "xr_run_s": xr_s,
           "render_ms_median": {m: report["render_ms"][m].get("median") for m in ("culled_once", "per_eye")},
           "checks": checks}
tmp = f"{out}/check.json.tmp"
with open(tmp, "w") as f:
    json.dump(summary, f, indent=2)
    f.flush()
    os.fsync(f.fileno())
os.replace(tmp, f"{out}/check.json")
for name, c in checks.items():
    print(f"{'ok  ' if c['ok'] else 'FAIL'} {name}: " + ", ".join(f"{k}={v}" for k, v in c.items() if k not in ("ok", "samples", "lod_error_px", "min_pixels", "display_period_ms")))
if failures:
    sys.exit(1)
EOF
echo "xr-check: passed ($OUT/check.json)"

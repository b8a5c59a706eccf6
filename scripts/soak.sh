#!/usr/bin/env bash
# The soak of issue 48 ("Nothing lost, nothing stuck"); see --help.
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
here="$root/scripts"

usage() {
    cat <<EOF
Usage: scripts/soak.sh [OPTIONS]

The soak of issue 48. The viewer on a plant store (by default the 500M plant)
under --memory-budget, scripted to walk (camera moves along aisles, a look
round, a view preset), pick, move (a move and a drag, both undone) and
section (a plane, then a box, cleared) in cycles over a few places of the
plant, for SOAK_MINUTES or MAX_FRAMES frames, whichever is fewer; its
resident set sampled from /proc every 10 s. Then \`dmu collide\` over
RECORDS records in one batch, sampled the same way. Prints a JSON summary
on standard output (also in OUT/summary.json) and a few lines for people on
standard error; scripts/soak.py says how each figure is defined.

Options (environment variables in brackets):
  --store FILE        the viewer's store; made (500M plant) if missing
                      [SOAK_STORE, default DATA/p500.dmu]
  --data DIR          where the big files go [SOAK_DATA, default target/soak]
  --out DIR           results [SOAK_OUT, default DATA/run-DATE]
  --minutes N         length of the viewer soak [SOAK_MINUTES, default 30]
  --max-frames N      at most this many scripted frames [SOAK_MAX_FRAMES, 20000]
  --cycles N          cycles of the script, instead of timing two first
  --locations N       walks the cycles go round; a pass is one cycle at each,
                      the first pass the warm-up, and growth compares passes,
                      so give at least three passes [SOAK_LOCATIONS, default 3]
  --budget B          the viewer's --memory-budget [SOAK_BUDGET, default 1GiB]
  --collide-model F   the collide batch's model, a .glb; made (2M plant) if
                      missing [SOAK_COLLIDE_MODEL, default DATA/p2.glb]
  --records N         collide records in the batch [SOAK_RECORDS, 10000]
  --record-steps N    steps of each record, a part sliding 20 mm a step
                      [SOAK_RECORD_STEPS, default 40]
  --interval S        seconds between RSS samples [SOAK_INTERVAL, default 10]
  --skip-viewer       only the collide batch
  --skip-collide      only the viewer
  --no-build          use the binaries as built [CARGO_TARGET_DIR/release]
  -h, --help          this text

Needs: cargo, python3, xvfb-run, lavapipe ($LVP_ICD).
EOF
}

die() {
    echo "soak.sh: $*" >&2
    exit 2
}

LVP_ICD=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json
data=${SOAK_DATA:-$root/target/soak}
store=${SOAK_STORE:-}
out=${SOAK_OUT:-}
minutes=${SOAK_MINUTES:-30}
max_frames=${SOAK_MAX_FRAMES:-20000}
budget=${SOAK_BUDGET:-1GiB}
collide_model=${SOAK_COLLIDE_MODEL:-}
records=${SOAK_RECORDS:-10000}
record_steps=${SOAK_RECORD_STEPS:-40}
interval=${SOAK_INTERVAL:-10}
cycles=
locations=${SOAK_LOCATIONS:-3}
viewer_soak=1
collide_soak=1
build=1
while [ $# -gt 0 ]; do
    case $1 in
        --store) store=${2:?--store needs a file}; shift ;;
        --data) data=${2:?--data needs a folder}; shift ;;
        --out) out=${2:?--out needs a folder}; shift ;;
        --minutes) minutes=${2:?--minutes needs a number}; shift ;;
        --max-frames) max_frames=${2:?--max-frames needs a number}; shift ;;
        --cycles) cycles=${2:?--cycles needs a number}; shift ;;
        --locations) locations=${2:?--locations needs a number}; shift ;;
        --budget) budget=${2:?--budget needs a size}; shift ;;
        --collide-model) collide_model=${2:?--collide-model needs a file}; shift ;;
        --records) records=${2:?--records needs a number}; shift ;;
        --record-steps) record_steps=${2:?--record-steps needs a number}; shift ;;
        --interval) interval=${2:?--interval needs seconds}; shift ;;
        --skip-viewer) viewer_soak= ;;
        --skip-collide) collide_soak= ;;
        --no-build) build= ;;
        -h | --help) usage; exit 0 ;;
        *) usage >&2; die "unknown option $1" ;;
    esac
    shift
done
for n in minutes max_frames records record_steps interval locations ${cycles:+cycles}; do
    [[ ${!n} =~ ^[0-9]+$ && ${!n} -gt 0 ]] || die "--${n//_/-} must be a whole number above 0, not '${!n}'"
done
command -v python3 >/dev/null || die "python3 is missing"
if [ -n "$viewer_soak" ]; then
    command -v xvfb-run >/dev/null || die "xvfb-run is missing (apt-get install xvfb xauth)"
    [ -e "$LVP_ICD" ] || die "lavapipe is missing: $LVP_ICD (apt-get install mesa-vulkan-drivers)"
fi
mkdir -p "$data"
data=$(cd "$data" && pwd)
store=${store:-$data/p500.dmu}
collide_model=${collide_model:-$data/p2.glb}
out=${out:-$data/run-$(date +%Y%m%d-%H%M%S)}
mkdir -p "$out"
target=${CARGO_TARGET_DIR:-$root/target}
dmu=$target/release/dmu
viewer=$target/release/dmu-viewer

if [ -n "$build" ]; then
    echo "soak: building release binaries in $target" >&2
    (cd "$root" && cargo build --release --locked -p dmu -p dmu-viewer) >&2
fi
[ -x "$dmu" ] || die "$dmu is not built (drop --no-build, or set CARGO_TARGET_DIR)"
[ -x "$viewer" ] || die "$viewer is not built"

# Samples the resident set of the process whose id will be in $1 every
# $interval s into $2 (`t_s rss_kib hwm_kib load1`), t from the id's appearing,
# until the process is gone.
sample_rss() {
    local pidfile=$1 file=$2 pid= start now rss hwm load
    : >"$file"
    while [ -z "$pid" ]; do
        [ -s "$pidfile" ] && pid=$(cat "$pidfile")
        sleep 0.05
    done
    start=$(date +%s.%N)
    while [ -r "/proc/$pid/status" ]; do
        rss=$(awk '/^VmRSS:/ {print $2}' "/proc/$pid/status" 2>/dev/null || true)
        hwm=$(awk '/^VmHWM:/ {print $2}' "/proc/$pid/status" 2>/dev/null || true)
        [ -n "$rss" ] || break
        read -r load _ </proc/loadavg
        now=$(date +%s.%N)
        echo "$(echo "$now - $start" | bc) $rss $hwm $load" >>"$file"
        sleep "$interval"
    done
}

# Runs the viewer on $store with script $1, its report to $2, RSS samples to $3.
run_viewer() {
    local script=$1 report=$2 rss=$3 pidfile="$out/viewer.pid" sampler status=0
    rm -f "$pidfile"
    sample_rss "$pidfile" "$rss" &
    sampler=$!
    # The inner shell writes its id, then becomes the viewer.
    WGPU_BACKEND=vulkan VK_ICD_FILENAMES=$LVP_ICD \
        xvfb-run -a -s "-screen 0 1280x800x24" \
        sh -c 'echo $$ >"$0"; exec "$@"' "$pidfile" \
        "$viewer" "$store" --memory-budget "$budget" --no-vsync --script "$script" \
        >"$report" 2>"$report.stderr" || status=$?
    [ -s "$pidfile" ] || echo 0 >"$pidfile" # never started: stop the sampler
    wait "$sampler" || true
    if [ "$status" -ne 0 ]; then
        tail -5 "$report.stderr" >&2
        die "the viewer failed (exit $status); see $report.stderr"
    fi
}

summary_viewer=null
if [ -n "$viewer_soak" ]; then
    if [ ! -f "$store" ]; then
        glb=${store%.dmu}.glb
        echo "soak: making the 500M plant store $store" >&2
        "$dmu" generate plant --triangles 500M -o "$glb"
        "$dmu" import "$glb" -o "$store" --memory-budget 1GiB
        rm -f "$glb"
    fi
    view=680x727
    if [ -z "$cycles" ]; then
        echo "soak: timing two cycles" >&2
        python3 "$here/soak.py" viewer-script --dmu "$dmu" --model "$store" --cycles 2 \
            --locations "$locations" --view "$view" -o "$out/calibrate.json" >/dev/null
        run_viewer "$out/calibrate.json" "$out/calibrate-report.json" "$out/calibrate-rss.txt"
        read -r cycles view < <(python3 - "$out/calibrate-report.json" "$out/calibrate.json.meta.json" \
            "$minutes" "$max_frames" <<'EOF'
import json, math, sys
report, meta = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
minutes, max_frames = float(sys.argv[3]), int(sys.argv[4])
f = report["frames"]
per_cycle_s = (f[-1]["t_s"] - f[0]["t_s"]) / meta["cycles"]
start_s = f[0]["t_s"]
by_time = math.ceil(max(1.0, minutes * 60 - start_s) / per_cycle_s)
by_frames = max_frames // meta["frames_per_cycle"]
v = report["viewport"]
print(max(1, min(by_time, by_frames)), f'{v["width"]}x{v["height"]}')
EOF
        )
        echo "soak: $cycles cycles (3D view $view)" >&2
    fi
    python3 "$here/soak.py" viewer-script --dmu "$dmu" --model "$store" --cycles "$cycles" \
        --locations "$locations" --view "$view" -o "$out/script.json" >/dev/null
    passes=$(( (cycles + locations - 1) / locations ))
    [ "$passes" -ge 3 ] || echo "soak: warning: $cycles cycles make $passes passes over $locations walks; growth needs 3" >&2
    echo "soak: viewer, $cycles cycles, --memory-budget $budget, from $(date +%T)" >&2
    run_viewer "$out/script.json" "$out/report.json" "$out/rss.txt"
    python3 "$here/soak.py" viewer --report "$out/report.json" --meta "$out/script.json.meta.json" \
        --rss "$out/rss.txt" >"$out/viewer-summary.json"
    summary_viewer=$(cat "$out/viewer-summary.json")
fi

summary_collide=null
if [ -n "$collide_soak" ]; then
    if [ ! -f "$collide_model" ]; then
        echo "soak: making the 2M plant $collide_model" >&2
        "$dmu" generate plant --triangles 2M -o "$collide_model"
    fi
    recs="$out/records"
    rm -rf "$recs"
    python3 "$here/soak.py" records --model "$collide_model" --count "$records" \
        --steps "$record_steps" -o "$recs" >/dev/null
    echo "soak: dmu collide over $records records of $record_steps steps, from $(date +%T)" >&2
    pidfile="$out/collide.pid"
    rm -f "$pidfile"
    sample_rss "$pidfile" "$out/collide-rss.txt" &
    sampler=$!
    t0=$(date +%s.%N)
    status=0
    sh -c 'echo $$ >"$0"; exec "$@"' "$pidfile" "$dmu" collide "$collide_model" --record "$recs" \
        >"$out/collide.txt" 2>"$out/collide.stderr" || status=$?
    wall=$(echo "$(date +%s.%N) - $t0" | bc)
    wait "$sampler" || true
    # Exit 1 means clashes were found: the run itself went through.
    [ "$status" -le 1 ] || die "dmu collide failed (exit $status); see $out/collide.stderr"
    python3 "$here/soak.py" collide --output "$out/collide.txt" --rss "$out/collide-rss.txt" \
        --records "$records" --status "$status" --wall "$wall" >"$out/collide-summary.json"
    summary_collide=$(cat "$out/collide-summary.json")
fi

printf '{"out": "%s", "viewer": %s, "collide": %s}\n' "$out" "$summary_viewer" "$summary_collide" |
    tee "$out/summary.json"

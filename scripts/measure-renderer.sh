#!/bin/bash
# The renderer measurements of docs/measurements.md ("Issue 13, first steps"),
# one after another on a release build; results under $OUT (target/measure).
set -euo pipefail
OUT=${OUT:-target/measure}
mkdir -p "$OUT"
B=target/release
cargo build --release --locked -p dmu -p dmu-viewer
P10=$OUT/p10.dmu
[ -f "$P10" ] || $B/dmu generate plant --triangles 10M -o "$P10"
$B/dmu generate grid --n 2 -o "$OUT/g2.glb"
echo '[{"frames": 60}]' > "$OUT/f60.json"
export WGPU_BACKEND=vulkan
echo "== LOD table (walk 300..330, 1280x720, --compare)"
for tau in 0 0.5 1 2 4; do
  $B/dmu walk "$P10" --render --compare --range 300..330 --width 1280 --height 720 --lod-error-px $tau --json > $OUT/m_lod_$tau.json 2>/dev/null
  python3 -c "
import json; r=json.load(open('$OUT/m_lod_$tau.json'))
px = r['size'][0]*r['size'][1]
print('tau $tau frustum/chc', round(r['frustum_over_chc_frame_time'],2), 'late', r['chc_chunks_more_than_one_frame_late'])
for t in r['totals']: print('  ', t['culling'], 'median', round(t['median_frame_ms']), 'mean', round(t['mean_frame_ms']), 'tris', int(t['mean_triangles_drawn']), 'draws', int(t['mean_draw_calls']), 'diff%', round(100*t['mean_differing_pixels']/px,3), 'surface%', round(100*t['mean_surface_differing_pixels']/px,3))
"
done
echo "== target-ms 100 (walk 300..420 chc, whole model resident)"
$B/dmu walk "$P10" --render --culling chc --target-ms 100 --memory-budget 100% --range 300..420 --width 1280 --height 720 --json > $OUT/m_target.json 2>/dev/null
python3 -c "
import json; r=json.load(open('$OUT/m_target.json'))['render']
t=r['totals']; f=r['per_frame']
print(' median', round(t['median_frame_ms']), 'p95', round(t['p95_frame_ms']), 'within110', t['frames_within_110_percent_of_target'], 'mean tau', round(t['mean_lod_error_px'],2))
print(' taus', [round(x['lod_error_px'],2) for x in f][::6])
print(' minpx', [round(x['min_pixels'],1) for x in f][::6])
print(' ms', [round(x['frame_ms']) for x in f][::6])
"
echo "== culling none overview, tau 0 and 1"
for tau in 0 1; do
  $B/dmu render "$P10" --culling none --lod-error-px $tau --eye 4450000,5300000,200000 --target 4633420,5457375,28860 --size 1280x720 --frames 4 -o $OUT/m_none_$tau.png --json > $OUT/m_none_$tau.json
  python3 -c "
import json; r=json.load(open('$OUT/m_none_$tau.json'))
for f in r['frames']: print('  tau $tau', f['triangles_drawn'], f['draw_calls'], round(f['cpu_ms']), round(f['gpu_ms']))
"
done
echo "== viewer drag, 10M, 1280x720"
for cull in chc frustum; do for tau in 0 1; do
  echo "[{\"culling\": \"$cull\"}, {\"frames\": 5}, {\"select\": \"U25-RF-STR-0002\"}, {\"drag\": {\"by\": [0, 0, 2000], \"steps\": 30}}]" > $OUT/drag.json
  xvfb-run -a -s "-screen 0 1600x1000x24" $B/dmu-viewer --plant-triangles 10M --width 1280 --height 720 --lod-error-px $tau --no-vsync --script $OUT/drag.json > $OUT/m_drag_${cull}_$tau.json 2>/dev/null
  python3 -c "
import json; r=json.load(open('$OUT/m_drag_${cull}_$tau.json'))
d=[f for f in r['frames'] if f['action']=='drag']
s=r['drag_frame_ms']; print('  $cull tau $tau drag median', round(s['median']), 'p95', round(s['p95']), 'tris', sorted(f['triangles_drawn'] for f in d)[len(d)//2], 'view', r['viewport'])
"
done; done
echo "== viewer overview, 10M, 1280x720"
echo '[{"frames": 20}]' > $OUT/f20.json
for tau in 0 1; do
  xvfb-run -a -s "-screen 0 1600x1000x24" $B/dmu-viewer --plant-triangles 10M --width 1280 --height 720 --lod-error-px $tau --no-vsync --script $OUT/f20.json > $OUT/m_over_$tau.json 2>/dev/null
  python3 -c "
import json; r=json.load(open('$OUT/m_over_$tau.json'))
f=r['frames'][5:]; ms=sorted(x['frame_ms'] for x in f)
print('  tau $tau overview median', round(ms[len(ms)//2]), 'tris', f[-1]['triangles_drawn'], 'draws', f[-1]['draw_calls'], 'split', {k:(round(v['median'],1) if isinstance(v,dict) else v) for k,v in r['frame_split_ms'].items()})
"
done
echo "== viewer floor, grid n 2, 1280x800"
for mode in "" "--paint-whole"; do
  xvfb-run -a -s "-screen 0 1600x1000x24" $B/dmu-viewer "$OUT/g2.glb" --no-vsync $mode --script $OUT/f60.json > $OUT/m_floor.json 2>/dev/null
  python3 -c "
import json; r=json.load(open('$OUT/m_floor.json')); s=r['frame_split_ms']; print('  $mode', r['window'], {k:(round(v['median'],1) if isinstance(v,dict) else v) for k,v in s.items()})"
done
date

#!/usr/bin/env python3
"""The soak of issue 48 ("Nothing lost, nothing stuck"): the pieces
scripts/soak.sh runs, standard library only.

  soak.py viewer-script  writes the viewer's script: cycles of walking,
                         picking, moving and sectioning over a plant store
  soak.py records        writes collide records (JSON Lines, one small
                         slide of one part each) from a plant .glb
  soak.py viewer         summarises a viewer run: its --script report and
                         the RSS sampled beside it
  soak.py collide        summarises a `dmu collide` batch and its RSS samples

Each summary is printed as one JSON object, then a few lines for people
(on standard error, so the JSON can be piped). `soak.py CMD --help` says more.

Definitions used in the summaries:
- a pass: one cycle at each walk location, in order (`locations` cycles);
  every pass is the same frames. Warm-up: pass 0; "after warm-up" is
  everything later. (A collide batch's passes are tenths of its run.)
- RSS after warm-up: the first sample at or after its end.
- RSS growth after warm-up (`growth_pct`): the highest sample of passes 2
  on over the highest of pass 1, percent (with two passes only, pass 1 over
  pass 0). The resident set swings within a pass by tens of percent (a
  view preset's overview frame holds far more transient memory than a
  walk's), so passes, which repeat the same frames, are compared by their
  highest; pass 1, not the warm-up, is the reference, so that the opening's
  own peak cannot hide growth. The viewer's own per-frame `rss_bytes` gives
  the same figure per frame (`rss_per_frame_growth_pct`). Also the
  least-squares slope of the samples after warm-up, MB per hour.
- a frame's time: the viewer's own `frame_ms` (one redraw, the script's
  action included); a hang is measured as the gap between consecutive
  frames' `t_s` (everything between two frames, the event loop included).
- an eviction wave: consecutive frames in which the residency's eviction
  count rose; "back within budget" is checked on the frame that ends it.
"""

import argparse
import json
import math
import os
import struct
import subprocess
import sys

# The plant of `dmu generate plant`: 48 m plots in rows along X, each with its
# pipe rack 2-10 m from its front edge and its building from 14 m; the aisle
# between them 12 m in (apps/dmu/src/cmd_walk.rs, `plant_path`).
PLOT_MM = 48_000.0
AISLE_MM = 12_000.0
EYE_MM = 1_700.0


def percentile(values, p):
    """The p-th percentile (nearest rank) of values, or None when empty."""
    if not values:
        return None
    s = sorted(values)
    k = max(0, min(len(s) - 1, math.ceil(p / 100.0 * len(s)) - 1))
    return s[k]


def stats(values):
    """Median, p95 and longest of a list of times."""
    return {
        "count": len(values),
        "median": percentile(values, 50),
        "p95": percentile(values, 95),
        "max": max(values) if values else None,
    }


def run_json(cmd):
    out = subprocess.run(cmd, check=True, stdout=subprocess.PIPE, text=True).stdout
    return json.loads(out)


# ---------------------------------------------------------------- the script


# `dmu generate plant`'s default origin (the site's corner), millimetres.
PLANT_ORIGIN = [4_512_000.0, 5_341_000.0, 12_000.0]


def site_corner(bounds):
    """The plant's site corner: its default origin when the model's box holds
    it (foundations reach below the ground, the first rack starts in from the
    edge), else the box's lowest corner."""
    lo, hi = bounds["min"], bounds["max"]
    if all(lo[i] - PLOT_MM <= PLANT_ORIGIN[i] <= hi[i] for i in range(3)):
        return PLANT_ORIGIN
    return lo


def locations(bounds, count):
    """`count` walks along plot aisles spread over the plant: (start eye,
    heading +X). Rows and plots are counted from the site's corner."""
    lo, hi = site_corner(bounds), bounds["max"]
    cols = max(1, int((hi[0] - lo[0]) // PLOT_MM))
    rows = max(1, int((hi[1] - lo[1]) // PLOT_MM))
    out = []
    for i in range(count):
        # Spread over the rows and along them, a different plot each time.
        row = (i * rows) // count if rows >= count else i % rows
        col = ((2 * i + 1) * cols) // (2 * count) if cols > 1 else 0
        col = min(col, cols - 1)
        x = lo[0] + col * PLOT_MM + 4_000.0
        y = lo[1] + row * PLOT_MM + AISLE_MM
        out.append([x, y, lo[2] + EYE_MM])
    return out


def directions():
    """Where a walk's end looks for a part to pick: eight headings, level
    and 10 and 30 degrees down (the plant has no ground to hit)."""
    out = []
    for pitch in (0.0, -10.0, -30.0):
        for heading in range(0, 360, 45):
            h, p = math.radians(heading), math.radians(pitch)
            out.append([math.cos(h) * math.cos(p), math.sin(h) * math.cos(p), math.sin(p)])
    return out


def aim(dmu, model, eyes):
    """For each walk's end, the direction whose ray from the eye hits a part
    nearest, and that part, from `dmu pick` on the loaded model: (forward,
    part id)."""
    dirs = directions()
    path = model + ".soak-rays.jsonl"
    with open(path, "w") as f:
        for eye in eyes:
            for d in dirs:
                f.write(json.dumps({"origin": eye, "direction": d}) + "\n")
    out = subprocess.run(
        [dmu, "pick", model, "--rays", path, "--json"],
        check=True, stdout=subprocess.PIPE, text=True,
    ).stdout
    os.unlink(path)
    hits = [json.loads(line) for line in out.splitlines() if line.strip()]
    aims = []
    for i, eye in enumerate(eyes):
        found = [(h["distance"], d, h["part_id"])
                 for h, d in zip(hits[i * len(dirs):(i + 1) * len(dirs)], dirs) if h.get("hit")]
        if not found:
            sys.exit(f"soak.py: no part seen from walk {i}'s end at {eye}: give another model")
        _, d, part = min(found, key=lambda f: f[0])
        aims.append((d, part))
    return aims


def cycle(k, start, end, fwd, part, view, walk_steps, presets):
    """One cycle's actions at walk `k`: walk, look round, pick, move and drag
    (undone), section by a plane and by a box, a view preset (walk k's own,
    so a pass over the walks is the same frames every time)."""
    a = []
    for k in range(walk_steps):
        t = k / walk_steps
        eye = [start[j] + (end[j] - start[j]) * t for j in range(3)]
        a.append({"camera": {"eye": eye, "forward": [1.0, 0.0, 0.0]}})
    for k in range(8):
        h = 2 * math.pi * (k + 1) / 8
        a.append({"camera": {"eye": end, "forward": [math.cos(h), math.sin(h), 0.0]}})
    a.append({"camera": {"eye": end, "forward": fwd}})
    a.append({"pick": [view[0] // 2, view[1] // 2]})
    # The part the same ray hits in the loaded model (the pick selects it
    # too, unless it only got near it).
    a.append({"select": f"#{part}"})
    a.append({"move": [0.0, 0.0, 300.0]})
    a.append({"frames": 2})
    a.append({"drag": {"by": [300.0, 0.0, 0.0], "steps": 6}})
    a.append({"frames": 2})
    a.append("undo")
    a.append("undo")
    ahead = [end[j] + 6_000.0 * fwd[j] for j in range(3)]
    a.append({"section_plane": {"point": ahead, "normal": [-v for v in fwd]}})
    a.append({"frames": 4})
    a.append("clear_section")
    a.append({"section_box": {
        "min": [end[0] - 15_000.0, end[1] - 15_000.0, end[2] - 3_000.0],
        "max": [end[0] + 15_000.0, end[1] + 15_000.0, end[2] + 10_000.0],
    }})
    a.append({"frames": 4})
    a.append("clear_section")
    a.append({"view": presets[k % len(presets)]})
    a.append({"frames": 2})
    return a


def frames_of(action):
    """Frames the viewer takes for an action (apps/dmu-viewer/src/script.rs)."""
    if isinstance(action, dict):
        if "frames" in action:
            return max(1, action["frames"])
        if "drag" in action:
            return max(1, action["drag"]["steps"])
    return 1


def cmd_viewer_script(args):
    info = run_json([args.dmu, "info", args.model, "--json"])
    eyes = locations(info["bounds"], args.locations)
    ends = [[e[0] + args.walk_mm, e[1], e[2]] for e in eyes]
    aims = aim(args.dmu, args.model, ends)
    view = [int(v) for v in args.view.split("x")]
    actions = []
    per_cycle = None
    for i in range(args.cycles):
        k = i % args.locations
        c = cycle(k, eyes[k], ends[k], aims[k][0], aims[k][1], view, args.walk_steps,
                  ["iso", "top", "front", "side"])
        per_cycle = sum(frames_of(x) for x in c)
        actions.extend(c)
    with open(args.output, "w") as f:
        json.dump(actions, f)
    meta = {
        "model": args.model,
        "cycles": args.cycles,
        "locations": args.locations,
        "frames_per_cycle": per_cycle,
        "frames": per_cycle * args.cycles,
        "bounds": info["bounds"],
        "walks": [{"start": eyes[k], "end": ends[k], "forward": aims[k][0], "part": aims[k][1]}
                  for k in range(args.locations)],
    }
    with open(args.output + ".meta.json", "w") as f:
        json.dump(meta, f, indent=1)
    print(json.dumps(meta))


# ---------------------------------------------------------------- records


def glb_json(path):
    with open(path, "rb") as f:
        magic, _version, _length = struct.unpack("<4sII", f.read(12))
        if magic != b"glTF":
            sys.exit(f"soak.py: {path} is not a .glb")
        size, kind = struct.unpack("<II", f.read(8))
        if kind != 0x4E4F534A:
            sys.exit(f"soak.py: {path}: the first chunk is not JSON")
        return json.loads(f.read(size))


def mat_mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def node_matrix(node):
    if "matrix" in node:
        m = node["matrix"]  # column-major
        return [[m[c * 4 + r] for c in range(4)] for r in range(4)]
    x, y, z, w = node.get("rotation", [0.0, 0.0, 0.0, 1.0])
    sx, sy, sz = node.get("scale", [1.0, 1.0, 1.0])
    tx, ty, tz = node.get("translation", [0.0, 0.0, 0.0])
    r = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    s = [sx, sy, sz]
    return [
        [r[0][0] * s[0], r[0][1] * s[1], r[0][2] * s[2], tx],
        [r[1][0] * s[0], r[1][1] * s[1], r[1][2] * s[2], ty],
        [r[2][0] * s[0], r[2][1] * s[1], r[2][2] * s[2], tz],
        [0.0, 0.0, 0.0, 1.0],
    ]


def quaternion(m):
    """The rotation of a 4x4 matrix's upper 3x3 (scale divided out), [x, y, z, w]."""
    cols = [[m[r][c] for r in range(3)] for c in range(3)]
    n = [math.sqrt(sum(v * v for v in col)) or 1.0 for col in cols]
    r = [[cols[c][row] / n[c] for c in range(3)] for row in range(3)]
    tr = r[0][0] + r[1][1] + r[2][2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = [(r[2][1] - r[1][2]) / s, (r[0][2] - r[2][0]) / s, (r[1][0] - r[0][1]) / s, 0.25 * s]
    elif r[0][0] > r[1][1] and r[0][0] > r[2][2]:
        s = math.sqrt(1.0 + r[0][0] - r[1][1] - r[2][2]) * 2
        q = [0.25 * s, (r[0][1] + r[1][0]) / s, (r[0][2] + r[2][0]) / s, (r[2][1] - r[1][2]) / s]
    elif r[1][1] > r[2][2]:
        s = math.sqrt(1.0 + r[1][1] - r[0][0] - r[2][2]) * 2
        q = [(r[0][1] + r[1][0]) / s, 0.25 * s, (r[1][2] + r[2][1]) / s, (r[0][2] - r[2][0]) / s]
    else:
        s = math.sqrt(1.0 + r[2][2] - r[0][0] - r[1][1]) * 2
        q = [(r[0][2] + r[2][0]) / s, (r[1][2] + r[2][1]) / s, 0.25 * s, (r[1][0] - r[0][1]) / s]
    length = math.sqrt(sum(v * v for v in q))
    return [v / length for v in q]


def parts_of(doc):
    """(path, world matrix) of every node with a mesh, in document order."""
    nodes = doc["nodes"]
    out = []
    scene = doc.get("scenes", [{"nodes": []}])[doc.get("scene", 0)]
    stack = [(n, [[1.0 if i == j else 0.0 for j in range(4)] for i in range(4)], "")
             for n in reversed(scene["nodes"])]
    while stack:
        index, parent, prefix = stack.pop()
        node = nodes[index]
        world = mat_mul(parent, node_matrix(node))
        path = f"{prefix}/{node.get('name', '')}" if prefix else node.get("name", "")
        if "mesh" in node:
            out.append((path, world))
        for child in reversed(node.get("children", [])):
            stack.append((child, world, path))
    return out


def cmd_records(args):
    parts = parts_of(glb_json(args.model))
    if not parts:
        sys.exit(f"soak.py: {args.model} has no parts")
    os.makedirs(args.output, exist_ok=True)
    stride = max(1, len(parts) // args.count)
    for i in range(args.count):
        path, m = parts[(i * stride + i // max(1, len(parts))) % len(parts)]
        q = quaternion(m)
        t0 = [m[0][3], m[1][3], m[2][3]]
        axis = i % 3
        lines = []
        for s in range(args.steps):
            t = list(t0)
            t[axis] += args.step_mm * s
            lines.append(json.dumps(
                {"t": float(s), "part": path, "translation": t, "rotation": q}))
        with open(os.path.join(args.output, f"r{i:05}.jsonl"), "w") as f:
            f.write("\n".join(lines) + "\n")
    print(json.dumps({"records": args.count, "steps": args.steps, "parts_in_model": len(parts)}))


# ---------------------------------------------------------------- summaries


def read_samples(path):
    """RSS samples: lines `t_s rss_kib hwm_kib load1`."""
    out = []
    with open(path) as f:
        for line in f:
            v = line.split()
            if len(v) >= 3:
                out.append({"t_s": float(v[0]), "rss": int(v[1]) * 1024,
                            "hwm": int(v[2]) * 1024,
                            "load": float(v[3]) if len(v) > 3 else None})
    return out


def rss_summary(samples, passes):
    """The RSS samples: at start, after warm-up (the first at or after the
    end of pass 0), at the end; per pass its highest; growth after warm-up
    (see the module's doc) and the slope after warm-up."""
    if not samples:
        return {"samples": 0}
    bounds = [p["from_s"] for p in passes] + [math.inf]
    per_pass = [[s["rss"] for s in samples if bounds[k] <= s["t_s"] < bounds[k + 1]]
                for k in range(len(passes))]
    after = [s for s in samples if s["t_s"] >= bounds[1]] if len(passes) > 1 else []
    ref = after[0] if after else samples[-1]
    out = {
        "samples": len(samples),
        "interval_s": (samples[-1]["t_s"] - samples[0]["t_s"]) / max(1, len(samples) - 1),
        "start_bytes": samples[0]["rss"],
        "start_t_s": samples[0]["t_s"],
        "after_warmup_bytes": ref["rss"],
        "after_warmup_t_s": ref["t_s"],
        "end_bytes": samples[-1]["rss"],
        "end_t_s": samples[-1]["t_s"],
        "max_per_pass_bytes": [max(v) if v else None for v in per_pass],
        "peak_hwm_bytes": max(s["hwm"] for s in samples),
        "load_average": stats([s["load"] for s in samples if s["load"] is not None]),
    }
    growth = pass_growth(out["max_per_pass_bytes"])
    if growth is not None:
        out["growth_pct"] = growth
    if len(after) >= 3:
        xs = [s["t_s"] for s in after]
        ys = [s["rss"] for s in after]
        mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
        den = sum((x - mx) ** 2 for x in xs)
        slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / den if den else 0.0
        out["slope_mb_per_hour"] = slope * 3600 / 1e6
    return out


def pass_growth(highest):
    """Growth after warm-up, percent: the highest of passes 2 on over the
    highest of pass 1 (pass 0 is the warm-up); with two passes only, pass 1
    over pass 0."""
    v = [h for h in highest if h is not None]
    if len(v) < 2:
        return None
    if len(v) == 2:
        return 100.0 * (v[1] / v[0] - 1.0)
    return 100.0 * (max(v[2:]) / v[1] - 1.0)


def cmd_viewer(args):
    with open(args.report) as f:
        report = json.load(f)
    with open(args.meta) as f:
        meta = json.load(f)
    frames = report["frames"]
    if not frames:
        sys.exit("soak.py: the report has no scripted frames")
    samples = read_samples(args.rss)
    per_cycle = meta["frames_per_cycle"]
    per_pass = per_cycle * meta["locations"]
    passes = []
    for k in range(0, len(frames), per_pass):
        p = frames[k:k + per_pass]
        mem = [f["memory"] for f in p if f.get("memory")]
        passes.append({
            "pass": len(passes),
            "frames": len(p),
            "from_s": p[0]["t_s"],
            "rss_max_bytes": max(f["rss_bytes"] for f in p),
            "rss_median_bytes": percentile([f["rss_bytes"] for f in p], 50),
            "frame_ms_max": max(f["frame_ms"] for f in p),
            "evictions": mem[-1]["evictions"] if mem else None,
            "pool_handed_out_max_bytes": max((m["pool_handed_out_bytes"] for m in mem), default=None),
            "pool_resident_max_bytes": max((m["pool_resident_bytes"] for m in mem), default=None),
            "pool_pages_max": max((m["pool_pages"] for m in mem), default=None),
        })
    warm = min(per_pass, len(frames))
    ms = [f["frame_ms"] for f in frames]
    gaps = [b["t_s"] - a["t_s"] for a, b in zip(frames, frames[1:])]
    longest = max(range(len(frames)), key=lambda i: frames[i]["frame_ms"])
    by_action = {}
    for f in frames[warm:]:
        by_action.setdefault(f["action"], []).append(f["frame_ms"])

    # Memory per frame (under --memory-budget): the residency within its
    # budget on every frame once it has one, and each eviction wave's end.
    mem = [f.get("memory") for f in frames]
    budgeted = [i for i, m in enumerate(mem) if m and m["residency_budget_bytes"] > 0]
    over_residency = [i for i in budgeted
                      if mem[i]["resident_bytes"] + mem[i]["reserved_bytes"]
                      > mem[i]["residency_budget_bytes"]]
    wave_ends = [i for i in budgeted
                 if i > 0 and mem[i - 1] and mem[i]["evictions"] > mem[i - 1]["evictions"]
                 and (i + 1 == len(frames) or mem[i + 1]["evictions"] == mem[i]["evictions"])]
    pool_over = [i for i in wave_ends
                 if mem[i]["pool_resident_bytes"] > mem[i]["residency_budget_bytes"]]
    pages_over = [i for i in wave_ends
                  if mem[i]["pool_handed_out_bytes"] > mem[i]["residency_budget_bytes"]]
    memory = None
    if budgeted:
        last = mem[budgeted[-1]]
        memory = {
            "residency_budget_bytes": last["residency_budget_bytes"],
            "frames_over_residency_budget": len(over_residency),
            "evictions": last["evictions"],
            "eviction_waves": len(wave_ends),
            "waves_ending_with_pool_over_budget": len(pool_over),
            "waves_ending_with_pool_pages_over_budget": len(pages_over),
            "resident_bytes_max": max(mem[i]["resident_bytes"] for i in budgeted),
            "pool_resident_bytes_max": max(mem[i]["pool_resident_bytes"] for i in budgeted),
            "pool_handed_out_bytes_end": last["pool_handed_out_bytes"],
            "pool_pages_end": last["pool_pages"],
            "pool_stand_ins_end": last["pool_stand_ins"],
        }
    frame_rss = [{"t_s": f["t_s"], "rss": f["rss_bytes"], "hwm": 0, "load": None}
                 for f in frames if f.get("rss_bytes")]
    report_memory = report.get("memory", {})
    summary = {
        "model": meta["model"],
        "cycles": meta["cycles"],
        "locations": meta["locations"],
        "frames_per_cycle": per_cycle,
        "frames": len(frames),
        "frames_drawn": report.get("frames_drawn"),
        "run_s": frames[-1]["t_s"],
        "first_frame_ms": report.get("first_frame_ms"),
        "warmup": {"frames": warm, "until_s": passes[1]["from_s"] if len(passes) > 1 else None,
                   "definition": "pass 0: the first pass over every walk"},
        "passes": passes,
        "rss": rss_summary(samples, passes),
        "rss_per_frame_growth_pct": pass_growth([p["rss_max_bytes"] for p in passes]),
        "peak_rss_bytes": report.get("peak_rss_bytes"),
        "frame_ms": {"all": stats(ms), "after_warmup": stats(ms[warm:])},
        "frame_ms_by_action_after_warmup": {k: stats(v) for k, v in sorted(by_action.items())},
        "longest_frame": {"frame_ms": ms[longest], "action": frames[longest]["action"],
                          "index": longest, "t_s": frames[longest]["t_s"]},
        "frames_over_2s": {"all": sum(1 for v in ms if v > 2000),
                           "after_warmup": sum(1 for v in ms[warm:] if v > 2000)},
        "gap_s": {"all": stats(gaps), "after_warmup": stats(gaps[warm:])},
        "memory": memory,
        "holes": report_memory.get("holes"),
        "frames_with_hole": report.get("frames_with_hole"),
        "frames_with_standin": report.get("frames_with_standin"),
        "residency": report_memory.get("residency"),
        "tool_geometry": report.get("tool_geometry"),
    }
    print(json.dumps(summary, indent=1))
    human_viewer(summary)


def mb(b):
    return "?" if b is None else f"{b / 1e6:,.1f} MB"


def pct(v):
    return "?" if v is None else f"{v:+.2f} %"


def human_viewer(s):
    r = s["rss"]
    say = lambda *a: print(*a, file=sys.stderr)
    say(f"viewer soak: {s['frames']:,} frames in {s['run_s'] / 60:.1f} min "
        f"({s['cycles']} cycles of {s['frames_per_cycle']} frames, {len(s['passes'])} passes over "
        f"{s['locations']} walks); warm-up (pass 0) {s['warmup']['frames']} frames")
    if r.get("samples"):
        say(f"  RSS every {r['interval_s']:.0f} s: start {mb(r['start_bytes'])}, after warm-up "
            f"{mb(r['after_warmup_bytes'])} (t={r['after_warmup_t_s']:.0f} s), end {mb(r['end_bytes'])}, "
            f"peak (VmHWM) {mb(r['peak_hwm_bytes'])}; growth after warm-up {pct(r.get('growth_pct'))} "
            f"(per frame: {pct(s['rss_per_frame_growth_pct'])}), slope "
            f"{r.get('slope_mb_per_hour', 0):+.1f} MB/h; load average median {r['load_average']['median']}")
    say("  highest RSS per pass: " + ", ".join(mb(p["rss_max_bytes"]) for p in s["passes"]))
    f = s["frame_ms"]
    say(f"  frame ms: median {f['all']['median']:.0f}, p95 {f['all']['p95']:.0f}, longest "
        f"{f['all']['max']:.0f} ({s['longest_frame']['action']}); after warm-up median "
        f"{f['after_warmup']['median']:.0f}, p95 {f['after_warmup']['p95']:.0f}, longest "
        f"{f['after_warmup']['max']:.0f}; over 2 s: {s['frames_over_2s']['all']} "
        f"({s['frames_over_2s']['after_warmup']} after warm-up); longest gap between frames "
        f"{s['gap_s']['all']['max']:.2f} s")
    m = s["memory"]
    if m:
        say(f"  evictions {m['evictions']:,} in {m['eviction_waves']} waves; residency over its budget "
            f"({mb(m['residency_budget_bytes'])}) on {m['frames_over_residency_budget']} frames; waves "
            f"ending with the GPU pool over that budget: {m['waves_ending_with_pool_over_budget']} "
            f"(its pages' bytes: {m['waves_ending_with_pool_pages_over_budget']}); pool pages "
            f"{m['pool_pages_end']}, handed out per pass: "
            + ", ".join(mb(p["pool_handed_out_max_bytes"]) for p in s["passes"]))
    say(f"  holes {s['holes']}, frames with a hole {s['frames_with_hole']}, "
        f"with a stand-in {s['frames_with_standin']}")


def cmd_collide(args):
    samples = read_samples(args.rss)
    with open(args.output) as f:
        lines = f.read().splitlines()
    last = next((line for line in reversed(lines) if " records (" in line), None)
    # Passes: tenths of the run (the first the warm-up).
    span = samples[-1]["t_s"] if samples else 0.0
    passes = [{"from_s": span * k / 10} for k in range(10)]
    summary = {
        "records": args.records,
        "exit_status": args.status,
        "wall_s": args.wall,
        "batch_line": last,
        "rss": rss_summary(samples, passes),
    }
    print(json.dumps(summary, indent=1))
    r = summary["rss"]
    if r.get("samples"):
        print(f"collide soak: {args.records:,} records in {args.wall:.0f} s (exit {args.status}); "
              f"RSS start {mb(r['start_bytes'])}, after warm-up (10 %) {mb(r['after_warmup_bytes'])}, "
              f"end {mb(r['end_bytes'])}, growth after warm-up {pct(r.get('growth_pct'))}, "
              f"peak (VmHWM) {mb(r['peak_hwm_bytes'])}\n  {last}", file=sys.stderr)


def main():
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("viewer-script", help="write the viewer's soak script")
    s.add_argument("--dmu", required=True, help="the dmu binary")
    s.add_argument("--model", required=True, help="the plant store (.dmu)")
    s.add_argument("--cycles", type=int, required=True)
    s.add_argument("--locations", type=int, default=3, help="walks the cycles go round")
    s.add_argument("--walk-steps", type=int, default=24, help="frames of each walk")
    s.add_argument("--walk-mm", type=float, default=40_000.0, help="length of each walk")
    s.add_argument("--view", default="680x727", help="the 3D view's size, WxH pixels")
    s.add_argument("-o", "--output", required=True)
    s.set_defaults(run=cmd_viewer_script)
    s = sub.add_parser("records", help="write collide records from a plant .glb")
    s.add_argument("--model", required=True, help="the plant (.glb)")
    s.add_argument("--count", type=int, default=10_000)
    s.add_argument("--steps", type=int, default=10)
    s.add_argument("--step-mm", type=float, default=20.0)
    s.add_argument("-o", "--output", required=True, help="a folder")
    s.set_defaults(run=cmd_records)
    s = sub.add_parser("viewer", help="summarise a viewer soak")
    s.add_argument("--report", required=True, help="the viewer's JSON report")
    s.add_argument("--meta", required=True, help="the script's .meta.json")
    s.add_argument("--rss", required=True, help="the RSS samples")
    s.set_defaults(run=cmd_viewer)
    s = sub.add_parser("collide", help="summarise a collide soak")
    s.add_argument("--output", required=True, help="dmu collide's text output")
    s.add_argument("--rss", required=True, help="the RSS samples")
    s.add_argument("--records", type=int, required=True)
    s.add_argument("--status", type=int, required=True)
    s.add_argument("--wall", type=float, required=True)
    s.set_defaults(run=cmd_collide)
    args = p.parse_args()
    args.run(args)


if __name__ == "__main__":
    main()

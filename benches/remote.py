#!/usr/bin/env python3
"""A store read from a local file, from S3 on localhost and from S3 over a
simulated slow link (scripts/slowlink.py: 20 ms, 100 Mbit/s), cold (an empty
cache) and warm (the cache the cold run filled): `dmu walk --render` within a
memory budget, its first complete image, stand-ins, bytes fetched and
requests. Starts its own `weed mini` (DMU_WEED or `weed`) and link.

    python3 benches/remote.py /work/measure/p10.dmu --dmu target/release/dmu \\
        --range 0..100 --budget 1GiB --runs 2

Prints a Markdown table and writes the reports as JSON (--out).
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import urllib.request

S3 = "http://127.0.0.1:8333"
SLOW = "http://127.0.0.1:28333"


def wait_for(url, seconds=90):
    start = time.time()
    while time.time() - start < seconds:
        try:
            urllib.request.urlopen(urllib.request.Request(url, data=b"ok", method="PUT"), timeout=5)
            return
        except OSError:
            time.sleep(0.25)
    sys.exit(f"{url} did not answer within {seconds} s")


def walk(dmu, store, endpoint, cache, args):
    env = dict(os.environ, AWS_ENDPOINT_URL=endpoint or "")
    env.pop("AWS_ACCESS_KEY_ID", None)
    cmd = [dmu, "--cache-dir", cache, "walk", store, "--render", "--memory-budget", args.budget,
           "--range", args.range, "--json"]
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
    r = json.loads(out.stdout)
    remote = r["walk"].get("remote") or {}
    return {
        "open_s": r["open_ms"] / 1e3,
        "first_complete_s": (r["first_complete_image_ms"] or float("nan")) / 1e3,
        "frames": r["walk"]["total"]["frames"],
        "frames_with_standin": r["render"]["frames_with_standin"],
        "frames_with_hole": r["render"]["frames_with_hole"],
        "median_frame_ms": r["render"]["totals"]["median_frame_ms"],
        "wall_s": r["walk"]["total"]["wall_ms"] / 1e3,
        "requests": remote.get("requests", 0),
        "fetched_mb": remote.get("bytes_fetched", 0) / 1e6,
        "cache_hit_mb": remote.get("cache_hit_bytes", 0) / 1e6,
        "retries": remote.get("retries", 0),
    }


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("store")
    p.add_argument("--dmu", default="target/release/dmu")
    p.add_argument("--weed", default=os.environ.get("DMU_WEED", "weed"))
    p.add_argument("--range", default="0..100")
    p.add_argument("--budget", default="1GiB")
    p.add_argument("--runs", type=int, default=2)
    p.add_argument("--out", default="remote-bench.json")
    p.add_argument("--only", help="run only the cases whose name contains one of these (comma separated)")
    p.add_argument("--also", action="append", default=[],
                   help="another dmu binary to run the same cases with, alternated (NAME=PATH)")
    args = p.parse_args()
    here = os.path.dirname(os.path.abspath(__file__))
    work = tempfile.mkdtemp(prefix="dmu-remote-bench-")
    procs = []
    try:
        procs.append(subprocess.Popen(
            [args.weed, "mini", "-ip=127.0.0.1", "-ip.bind=127.0.0.1", "-bucket=models",
             f"-dir={work}/weed"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        wait_for(f"{S3}/models/ready")
        procs.append(subprocess.Popen(
            [sys.executable, os.path.join(here, "..", "scripts", "slowlink.py"),
             "--listen", "127.0.0.1:28333", "--to", "127.0.0.1:8333"], stdout=subprocess.PIPE))
        procs[-1].stdout.readline()
        key = os.path.basename(args.store)
        with open(args.store, "rb") as f:
            urllib.request.urlopen(urllib.request.Request(f"{S3}/models/{key}", data=f, method="PUT",
                                   headers={"Content-Length": str(os.path.getsize(args.store))}))
        rows = {}
        for run in range(args.runs):
            cases = [("local file", args.store, None, None),
                     ("S3 on localhost, cold", f"s3://models/{key}", S3, "cold"),
                     ("S3 on localhost, warm", f"s3://models/{key}", S3, "warm"),
                     ("S3 over 20 ms, 100 Mbit/s, cold", f"s3://models/{key}", SLOW, "cold"),
                     ("S3 over 20 ms, 100 Mbit/s, warm", f"s3://models/{key}", SLOW, "warm")]
            binaries = [("", args.dmu)] + [tuple(a.split("=", 1)) for a in args.also]
            for name, store, endpoint, cache_state in cases:
                if args.only and not any(o in name for o in args.only.split(",")):
                    continue
                for label, binary in binaries:
                    cache = os.path.join(work, f"cache-{endpoint is SLOW}-{label}")
                    if cache_state == "cold":
                        shutil.rmtree(cache, ignore_errors=True)
                    r = walk(binary, store, endpoint, cache, args)
                    row = f"{name} ({label})" if label else name
                    rows.setdefault(row, []).append(r)
                    print(run, row, r, file=sys.stderr)
        with open(args.out, "w") as f:
            json.dump(rows, f, indent=1)
        rng = lambda rs, k, fmt: "-".join(sorted({fmt.format(min(x[k] for x in rs)), fmt.format(max(x[k] for x in rs))}, key=float))
        print("| | store opened | first complete image | frames with a stand-in | median frame | MB fetched | requests |")
        print("|---|---|---|---|---|---|---|")
        for name, rs in rows.items():
            print(f"| {name} | {rng(rs, 'open_s', '{:.2f}')} s | {rng(rs, 'first_complete_s', '{:.2f}')} s | "
                  f"{rng(rs, 'frames_with_standin', '{:.0f}')} of {rs[0]['frames']} | {rng(rs, 'median_frame_ms', '{:.0f}')} ms | "
                  f"{rng(rs, 'fetched_mb', '{:.1f}')} | {rng(rs, 'requests', '{:.0f}')} |")
    finally:
        for proc in reversed(procs):
            proc.kill()
            proc.wait()
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Far fields along the plant walk built in one process and on a two-node
local Ray cluster (a head and a second node, one CPU each), both reading the
store from and writing it to SeaweedFS's S3 server: the times, and whether
the far-field segments are byte-identical.

    python3 benches/ray_farfield.py /work/measure/p100.dmu --dmu target/release/dmu

Needs `ray` in this Python and `weed` ($DMU_WEED); the GPU variables as for
any dmu render (WGPU_BACKEND, VK_ICD_FILENAMES). Prints one JSON object.
"""

import argparse
import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time
import urllib.request

HERE = pathlib.Path(__file__).resolve().parent
S3 = "http://127.0.0.1:8333"
sys.path.insert(0, str(HERE.parent / "crates" / "dmu-py" / "tests"))
from test_ray_farfield import far_cells  # noqa: E402


def put(key, path):
    with open(path, "rb") as f:
        urllib.request.urlopen(urllib.request.Request(
            f"{S3}/models/{key}", data=f, method="PUT",
            headers={"Content-Length": str(os.path.getsize(path))}), timeout=600).read()


def get(key):
    return urllib.request.urlopen(f"{S3}/models/{key}", timeout=600).read()


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("store")
    p.add_argument("--dmu", default="target/release/dmu")
    p.add_argument("--weed", default=os.environ.get("DMU_WEED", "weed"))
    p.add_argument("--build", default="--along-walk", help="options of dmu farfield build")
    args = p.parse_args()
    work = pathlib.Path(tempfile.mkdtemp(prefix="dmu-ray-ff-", dir="/tmp"))
    ray_bin = str(pathlib.Path(sys.executable).parent / "ray")
    weed = subprocess.Popen([args.weed, "mini", "-ip=127.0.0.1", "-ip.bind=127.0.0.1", "-bucket=models",
                             f"-dir={work}/weed"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    ray_env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0")
    common = ["--num-cpus=1", "--object-store-memory=200000000", "--disable-usage-stats",
              f"--temp-dir={work}/ray"]
    try:
        for _ in range(360):
            try:
                urllib.request.urlopen(urllib.request.Request(f"{S3}/models/ready", data=b"ok", method="PUT"))
                break
            except OSError:
                time.sleep(0.25)
        subprocess.run([ray_bin, "start", "--head", "--port=6390", "--node-ip-address=127.0.0.2",
                        "--include-dashboard=false", *common], env=ray_env, check=True, capture_output=True)
        subprocess.run([ray_bin, "start", "--address=127.0.0.2:6390", "--node-ip-address=127.0.0.3",
                        *common], env=ray_env, check=True, capture_output=True)
        put("one.dmu", args.store)
        put("two.dmu", args.store)
        env = dict(os.environ, AWS_ENDPOINT_URL=S3, DMU_BIN=str(pathlib.Path(args.dmu).resolve()),
                   DMU_CACHE_DIR=str(work / "cache"))
        env.pop("AWS_ACCESS_KEY_ID", None)
        example = str(HERE.parent / "examples" / "ray_farfield.py")
        runs = {}
        for name, how in [("one process", ["--no-ray", "s3://models/one.dmu"]),
                          ("two workers, two nodes", ["--address", "127.0.0.2:6390", "--workers", "2",
                                                      "s3://models/two.dmu"])]:
            out = subprocess.run([sys.executable, example, "--json", *how, "--", *args.build.split()],
                                 env=env, capture_output=True, text=True, check=True)
            runs[name] = json.loads(out.stdout)
            print(name, runs[name], file=sys.stderr)
        one, two = far_cells(get("one.dmu")), far_cells(get("two.dmu"))
        print(json.dumps({"store": args.store, "build": args.build, "runs": runs, "cells": len(one),
                          "far_field_segments_identical": one == two and len(one) > 0}, indent=1))
    finally:
        subprocess.run([ray_bin, "stop", "--force"], env=ray_env, capture_output=True)
        weed.kill()
        weed.wait()
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()

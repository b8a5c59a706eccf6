#!/usr/bin/env python3
"""Builds a store's far fields over a Ray cluster and writes them into it.

Each of --workers Ray tasks (one CPU each) runs `dmu farfield build STORE
--shard K/N --cells-out DIR` on its node: it reads the store (from object
storage, `s3://…`, through its node's cache, or a path every node sees),
builds every N-th cell from the K-th, and returns the cells' bytes and index
entries. The driver then writes them all into the store with `dmu farfield
build STORE --cells-from DIR` (on object storage: a put conditional on the
version the build read). A cell's bytes depend on the model and the options
alone, so the far-field segments equal a single-process build's, byte for
byte.

    AWS_ENDPOINT_URL=http://127.0.0.1:8333 python examples/ray_farfield.py \\
        --address 127.0.0.2:6379 --workers 2 s3://models/plant.dmu -- --along-walk

Everything after `--` is passed to every `dmu farfield build` (the same
options for the shards and the write). With --no-ray the build runs as one
process (`dmu farfield build STORE ARGS`), for comparison. Prints a JSON
report with --json. Exit status 0, or 2 on error.
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

# What a worker needs of this process's environment: where object storage
# is and who asks, the cache, and the GPU driver.
PASSED = ("AWS_ENDPOINT_URL", "AWS_REGION", "AWS_DEFAULT_REGION", "AWS_ACCESS_KEY_ID",
          "AWS_SECRET_ACCESS_KEY", "DMU_CACHE_DIR", "DMU_CACHE_BUDGET", "WGPU_BACKEND",
          "VK_ICD_FILENAMES", "NODEVICE_SELECT")


def dmu_binary(given):
    found = given or os.environ.get("DMU_BIN") or shutil.which("dmu")
    if not found:
        raise SystemExit("error: no dmu binary: give --dmu or put dmu on the PATH")
    return str(pathlib.Path(found).resolve())


def run(cmd, env):
    out = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd[:4])} …: {out.stderr.strip() or out.returncode}")
    return out.stdout


def shard(dmu, store, k, n, extra, env):
    """One worker's share: its cells' files, read back as bytes."""
    import ray

    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="dmu-farfield-") as out:
        report = json.loads(run([dmu, "farfield", "build", store, *extra, "--shard", f"{k}/{n}",
                                 "--cells-out", out, "--json"], dict(os.environ, **env)))
        files = {p.name: p.read_bytes() for p in pathlib.Path(out).iterdir()}
    return {"shard": k, "node": ray.get_runtime_context().get_node_id(),
            "cells": report["cells"], "files": files, "seconds": time.perf_counter() - start}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("store", help="the store: s3://bucket/key, or a path every node sees")
    p.add_argument("extra", nargs="*", help="after --: options of dmu farfield build")
    p.add_argument("--address", help="the Ray cluster (default: a local one)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--dmu", help="the dmu binary every node runs (default: $DMU_BIN, else PATH)")
    p.add_argument("--no-ray", action="store_true", help="build in one process instead")
    p.add_argument("--json", action="store_true")
    args = p.parse_args()
    if args.workers < 1:
        raise SystemExit("error: --workers must be at least 1")
    dmu = dmu_binary(args.dmu)
    env = {k: os.environ[k] for k in PASSED if k in os.environ}
    start = time.perf_counter()
    if args.no_ray:
        run([dmu, "farfield", "build", args.store, *args.extra, "--json"], dict(os.environ, **env))
        report = {"workers": 0, "nodes": 0, "cells": None, "shards": []}
    else:
        import ray

        ray.init(address=args.address, logging_level="ERROR", log_to_driver=False)
        task = ray.remote(num_cpus=1)(shard)
        try:
            done = ray.get([task.remote(dmu, args.store, k, args.workers, args.extra, env)
                            for k in range(args.workers)])
        finally:
            ray.shutdown()
        built = time.perf_counter()
        with tempfile.TemporaryDirectory(prefix="dmu-farfield-cells-") as cells:
            for d in done:
                for name, data in d["files"].items():
                    (pathlib.Path(cells) / name).write_bytes(data)
            run([dmu, "farfield", "build", args.store, *args.extra, "--cells-from", cells, "--json"],
                dict(os.environ, **env))
        report = {"workers": args.workers, "nodes": len({d["node"] for d in done}),
                  "cells": sum(d["cells"] for d in done),
                  "shards": [{k: d[k] for k in ("shard", "cells", "seconds")} for d in done],
                  "build_seconds": built - start, "write_seconds": time.perf_counter() - built}
    report["seconds"] = time.perf_counter() - start
    if args.json:
        print(json.dumps(report, indent=1))
    else:
        print(f"{args.store}: far fields built in {report['seconds']:.1f} s"
              + (f" by {args.workers} workers on {report['nodes']} nodes" if not args.no_ray else " in one process"))


if __name__ == "__main__":
    try:
        main()
    except (RuntimeError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        sys.exit(2)

#!/usr/bin/env python3
"""Replays clash records over a Ray cluster and gathers one report.

Each worker is a Ray actor that opens the model once, read-only, from a path
every node sees (a shared file system), and replays the records it is handed
with `dmu`'s `Model.collide`, which puts every moved part back afterwards: a
record's clashes are the same whichever worker replays it, and the same as
`dmu collide MODEL --record RECORD --json` prints.

    # on a cluster (see the README): every node sees /shared
    python examples/ray_collide.py --address auto --model /shared/plant.dmu \\
        --records /shared/records --workers 8 --json

Without --address, Ray starts a local cluster of this machine alone; with
--no-ray the records are replayed in this process (the single-process result).
Exit status: 0 when clear, 1 when any record has a clash or impact, 2 on error.
"""

import argparse
import json
import os
import pathlib
import sys
import time

import dmu


def record_paths(args):
    """The records: every *.jsonl of --records (sorted), then the files given."""
    paths = []
    if args.records:
        folder = pathlib.Path(args.records)
        if not folder.is_dir():
            raise SystemExit(f"error: --records {folder}: not a folder")
        paths += sorted(folder.glob("*.jsonl"))
        if not paths:
            raise SystemExit(f"error: --records {folder}: no *.jsonl records in it")
    paths += [pathlib.Path(p) for p in args.files]
    if not paths:
        raise SystemExit("error: no records (give --records DIR or record files)")
    # Absolute, so that every node resolves them the same way.
    return [str(p.resolve()) for p in paths]


def replay(model, record, clearance, continuous):
    """One record's result: its clashes and how long the replay took."""
    start = time.perf_counter()
    clashes = model.collide(record, clearance=clearance, continuous=continuous)
    return {"record": record, "clashes": clashes, "seconds": time.perf_counter() - start}


def run_local(args, records):
    """The single-process result: every record in turn, in this process."""
    model = dmu.open(args.model)
    start = time.perf_counter()
    results = [dict(replay(model, r, args.clearance, args.continuous), node="local") for r in records]
    return results, time.perf_counter() - start


def run_ray(args, records):
    """Distributes the records over `--workers` actors, at most one record in
    flight per actor, and gathers their results in record order, with the
    time from the first record handed out to the last result."""
    import ray
    from ray.util import ActorPool

    ray.init(address=args.address, logging_level="ERROR", log_to_driver=False)

    @ray.remote(num_cpus=1)
    class Worker:
        """Holds the model, opened once from the shared path."""

        def __init__(self, model, clearance, continuous):
            self.model = dmu.open(model)
            self.clearance, self.continuous = clearance, continuous
            self.node = ray.get_runtime_context().get_node_id()

        def ready(self):
            return self.node

        def replay(self, record):
            try:
                result = replay(self.model, record, self.clearance, self.continuous)
            except dmu.DmuError as e:
                return {"record": record, "error": str(e), "node": self.node}
            return dict(result, node=self.node)

    try:
        workers = [Worker.remote(args.model, args.clearance, args.continuous) for _ in range(args.workers)]
        ray.get([w.ready.remote() for w in workers])  # every worker has opened the model
        start = time.perf_counter()
        results = list(ActorPool(workers).map_unordered(lambda w, r: w.replay.remote(r), records))
        replay_seconds = time.perf_counter() - start
    finally:
        ray.shutdown()
    order = {r: i for i, r in enumerate(records)}
    return sorted(results, key=lambda r: order[r["record"]]), replay_seconds


def main():
    parser = argparse.ArgumentParser(
        description="Replay clash records over a Ray cluster (or in this process) and print one report.",
        epilog="Every node must see --model and the records at the same paths (a shared file system).",
    )
    parser.add_argument("files", nargs="*", help="record files (JSON Lines, docs/record-format.md)")
    parser.add_argument("--records", metavar="DIR", help="replay every *.jsonl in DIR, in name order")
    parser.add_argument("--model", required=True, help="the model (.dmu store, .glb or .gltf) on a shared path")
    parser.add_argument("--address", default=None,
                        help="Ray cluster to join: 'auto' (the one this node belongs to) or HOST:PORT of the head; "
                             "default: start a local one")
    parser.add_argument("--workers", type=int, default=max(1, (os.cpu_count() or 1)),
                        help="actors replaying records at once, each holding the model (default: this machine's cores)")
    parser.add_argument("--clearance", type=float, default=5.0,
                        help="soft clash below this distance, model units (default 5)")
    parser.add_argument("--continuous", action="store_true", help="also sweep every move and report impacts")
    parser.add_argument("--no-ray", action="store_true", help="replay in this process, without Ray")
    parser.add_argument("--json", action="store_true", help="print one JSON document")
    args = parser.parse_args()
    if args.workers < 1:
        parser.error("--workers must be at least 1")
    records = record_paths(args)

    start = time.perf_counter()
    try:
        results, replay_seconds = run_local(args, records) if args.no_ray else run_ray(args, records)
    except dmu.DmuError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    seconds = time.perf_counter() - start
    errors = [r for r in results if "error" in r]
    for r in errors:
        print(f"error: {r['error']}", file=sys.stderr)
    if errors:
        return 2

    clashes = sum(len(r["clashes"]) for r in results)
    report = {
        "model": args.model,
        "clearance": args.clearance,
        "continuous": args.continuous,
        "workers": 1 if args.no_ray else args.workers,
        "nodes": len({r["node"] for r in results}),
        "records": results,
        "clashes": clashes,
        "seconds": seconds,
        "replay_seconds": replay_seconds,
    }
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        for r in results:
            print(f"{r['record']}: {len(r['clashes'])} clashes ({r['seconds'] * 1e3:.1f} ms on {r['node'][:8]})")
        print(f"{len(results)} records, {clashes} clashes, {report['workers']} workers on "
              f"{report['nodes']} nodes, {replay_seconds:.2f} s replaying ({seconds:.2f} s in all)")
    return 1 if clashes else 0


if __name__ == "__main__":
    sys.exit(main())

"""examples/ray_collide.py on a real two-node Ray cluster on this machine (a
head and a second node, each with one CPU, started with `ray start`): its
report equals `dmu collide --json` on every record, with one worker and with
two, and the two workers ran on both nodes. The cluster is always stopped."""

import json
import subprocess
import sys

import dmu
from conftest import REPO, cli_collide, make_records

EXAMPLE = REPO / "examples" / "ray_collide.py"


def run_example(*args):
    out = subprocess.run([sys.executable, str(EXAMPLE), *map(str, args), "--json"],
                         capture_output=True, text=True, timeout=600)
    assert out.returncode in (0, 1), f"ray_collide.py failed ({out.returncode}): {out.stderr}"
    return json.loads(out.stdout)


def test_ray_cluster_reproduces_the_command_line(cluster, plant_store, dmu_bin, tmp_path):
    records = make_records(dmu.open(plant_store), tmp_path / "records", count=6, seed=3)
    expected = [cli_collide(dmu_bin, plant_store, r, 5.0) for r in records]
    assert sum(map(len, expected)) > 0, "the records should clash"

    local = run_example("--no-ray", "--model", plant_store, "--records", tmp_path / "records")
    assert [r["clashes"] for r in local["records"]] == expected

    seconds = {}
    for workers in (1, 2):
        report = run_example("--address", cluster, "--workers", workers, "--model", plant_store,
                             "--records", tmp_path / "records")
        assert [r["record"] for r in report["records"]] == [str(r) for r in records]
        assert [r["clashes"] for r in report["records"]] == expected
        assert report["workers"] == workers
        if workers == 2:
            assert report["nodes"] == 2, "two one-CPU actors must run on both nodes"
        seconds[workers] = (report["replay_seconds"], report["seconds"])
    print(f"ray_collide.py on a two-node cluster, {len(records)} records, replay (total) seconds: "
          f"1 worker {seconds[1][0]:.2f} ({seconds[1][1]:.2f}), 2 workers {seconds[2][0]:.2f} ({seconds[2][1]:.2f})")

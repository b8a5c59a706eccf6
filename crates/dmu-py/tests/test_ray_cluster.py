"""examples/ray_collide.py on a real two-node Ray cluster on this machine (a
head and a second node, each with one CPU, started with `ray start`): its
report equals `dmu collide --json` on every record, with one worker and with
two, and the two workers ran on both nodes. The cluster is always stopped."""

import json
import os
import pathlib
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

import dmu
import pytest
from conftest import REPO, cli_collide, make_records, require

EXAMPLE = REPO / "examples" / "ray_collide.py"


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def ray_cli():
    """The `ray` command of this Python's environment, if installed."""
    beside = pathlib.Path(sys.executable).parent / "ray"
    return str(beside) if beside.exists() else shutil.which("ray")


def processes_of(tag):
    """Pids of the processes whose command line contains `tag`, and all their
    descendants (Ray's agents and workers rename themselves)."""
    parents = {}
    roots = set()
    for entry in pathlib.Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ")
            ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        parents[int(entry.name)] = ppid
        if tag.encode() in cmdline and int(entry.name) != os.getpid():
            roots.add(int(entry.name))
    found = set(roots)
    while True:
        more = {pid for pid, ppid in parents.items() if ppid in found} - found
        if not more:
            return found
        found |= more


def stop_cluster(tag):
    """Stops the cluster's processes only (`ray stop` would stop every Ray
    process of the machine): SIGTERM, then SIGKILL what is left after 5 s."""
    for sig in (signal.SIGTERM, signal.SIGKILL):
        pids = processes_of(tag)
        for pid in pids:
            try:
                os.kill(pid, sig)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + 5
        while pids and time.monotonic() < deadline:
            pids = {p for p in pids if pathlib.Path(f"/proc/{p}").exists() and not zombie(p)}
            time.sleep(0.2)
        if not pids:
            return


def zombie(pid):
    try:
        return pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
    except OSError:
        return True


@pytest.fixture
def cluster():
    """A head and a second node, one CPU each, on loopback addresses (Ray
    would otherwise advertise the machine's network address); yields the
    head's address and always stops both nodes."""
    try:
        import ray  # noqa: F401
    except ImportError:
        ray = None
    require(ray is not None and ray_cli(), "ray is not installed (pip install ray)")
    ray_bin = ray_cli()
    port = free_port()
    address = f"127.0.0.2:{port}"
    # Short: Ray's unix sockets live under it.
    temp_dir = tempfile.mkdtemp(prefix="dmu-ray-", dir="/tmp")
    env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0")
    common = ["--num-cpus=1", "--object-store-memory=100000000", "--disable-usage-stats",
              f"--temp-dir={temp_dir}"]

    def start(*args):
        out = subprocess.run([ray_bin, "start", *args, *common], env=env, timeout=180,
                             capture_output=True, text=True)
        assert out.returncode == 0, f"ray start {' '.join(args)} failed:\n{out.stdout}\n{out.stderr}"

    try:
        start("--head", f"--port={port}", "--node-ip-address=127.0.0.2", "--include-dashboard=false")
        start(f"--address={address}", "--node-ip-address=127.0.0.3")
        yield address
    finally:
        stop_cluster(temp_dir)
        shutil.rmtree(temp_dir, ignore_errors=True)


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

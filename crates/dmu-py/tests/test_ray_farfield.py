"""examples/ray_farfield.py on the two-node Ray cluster against a real S3
server (SeaweedFS): the far fields built by two one-CPU workers on both nodes,
read from and written to object storage, equal a single-process build's
byte for byte in every far-field segment."""

import hashlib
import json
import os
import struct
import subprocess
import sys

from conftest import REPO, get_object, put_object

EXAMPLE = REPO / "examples" / "ray_farfield.py"
KIND_FAR_CELL = 4
# Small captures and a small cull box: cells with something beyond them.
BUILD = ["--along-walk", "--range", "0..200", "--resolution", "64", "--triangle-budget", "20k"]


def far_cells(store):
    """The far-field cell segments of a store's bytes, by cell: read from the
    file's own table of contents (format.rs), not through dmu."""
    toc_offset, entries = struct.unpack_from("<QQ", store, 24)
    cells = {}
    for i in range(entries):
        ident, kind, offset, length, _ = struct.unpack_from("<IIQQQ", store, toc_offset + 32 * i)
        if kind == KIND_FAR_CELL:
            cells[ident] = hashlib.sha256(store[offset:offset + length]).hexdigest()
    return cells


def build(*args, env):
    out = subprocess.run([sys.executable, str(EXAMPLE), "--json", *map(str, args)],
                         capture_output=True, text=True, timeout=900, env=env)
    assert out.returncode == 0, f"ray_farfield.py failed ({out.returncode}): {out.stderr}"
    return json.loads(out.stdout)


def test_far_fields_built_on_a_cluster_from_s3_equal_one_process(cluster, weed, dmu_bin, tmp_path):
    plant = tmp_path / "plant.dmu"
    subprocess.run([dmu_bin, "generate", "plant", "--triangles", "300k", "-o", str(plant)],
                   check=True, capture_output=True)
    for key in ("one.dmu", "two.dmu"):
        put_object(weed, key, plant.read_bytes())
    env = dict(os.environ, AWS_ENDPOINT_URL=weed, DMU_BIN=dmu_bin,
               DMU_CACHE_DIR=str(tmp_path / "cache"))
    env.pop("AWS_ACCESS_KEY_ID", None)

    single = build("--no-ray", "s3://models/one.dmu", "--", *BUILD, env=env)
    spread = build("--address", cluster, "--workers", 2, "s3://models/two.dmu", "--", *BUILD, env=env)
    assert spread["workers"] == 2 and spread["nodes"] == 2, spread

    one, two = far_cells(get_object(weed, "one.dmu")), far_cells(get_object(weed, "two.dmu"))
    assert len(one) == spread["cells"] > 1
    assert one == two, "the far-field segments differ"
    assert far_cells(plant.read_bytes()) == {}, "the local original is untouched"
    print(f"ray_farfield.py, {len(one)} cells: one process {single['seconds']:.1f} s, "
          f"two workers on two nodes {spread['seconds']:.1f} s")

"""The `dmu` module against independent oracles: analytic rays on a grid of
boxes, the command line's JSON, a loop of single picks, and bad input."""

import json
import math
import threading

import numpy as np
import pytest

import dmu
from conftest import cli_collide, make_records, run_cli


def test_pick_on_grid_is_analytic(grid_glb):
    m = dmu.open(grid_glb)
    assert len(m) == 64 and m.triangles == 64 * 12
    rng = np.random.default_rng(1)
    for _ in range(50):
        y, z = rng.integers(0, 4, size=2)
        dy, dz = rng.uniform(-1.9, 1.9, size=2)
        origin = (-5.0, 10.0 * y + dy, 10.0 * z + dz)
        # Whatever the direction's length, the distance is in world units.
        hit = m.pick(origin, (rng.uniform(0.1, 10.0), 0.0, 0.0))
        assert hit["part"] == f"box_0_{y}_{z}"
        assert hit["distance"] == pytest.approx(3.0, abs=1e-9)
        assert hit["point"] == pytest.approx([-2.0, origin[1], origin[2]], abs=1e-9)
        assert hit["normal"] == pytest.approx([-1.0, 0.0, 0.0], abs=1e-9)
    # Between the boxes: nothing.
    assert m.pick((-5.0, 5.0, 5.0), (1.0, 0.0, 0.0)) is None


def test_pick_matches_command_line(grid_glb, dmu_bin):
    m = dmu.open(grid_glb)
    for ray in [(-5.0, 0.5, 10.3, 1.0, 0.01, 0.0), (15.0, 15.0, 50.0, 0.0, 0.0, -3.0), (35, 35, 35, 1, 1, 1)]:
        _, out = run_cli(dmu_bin, "pick", grid_glb, "--ray", ",".join(map(str, ray)), "--json")
        cli = json.loads(out)
        ours = m.pick(ray[:3], ray[3:])
        assert (ours or {"hit": False}) == cli


def test_move_then_pick(grid_glb):
    m = dmu.open(grid_glb)
    before = m.world("box_0_1_2")
    assert np.array_equal(before, [[1, 0, 0, 0], [0, 1, 0, 10], [0, 0, 1, 20], [0, 0, 0, 1]])
    moved = before.copy()
    moved[2, 3] += 100.0  # lift it out of the way
    m.move("box_0_1_2", moved)
    assert np.array_equal(m.world("box_0_1_2"), moved)
    hit = m.pick((-5.0, 10.0, 20.0), (1.0, 0.0, 0.0))
    assert hit["part"] == "box_1_1_2" and hit["distance"] == pytest.approx(13.0)
    # Rotated 90° about z and moved back by id: the same box, seen from -x.
    c, s = math.cos(math.pi / 2), math.sin(math.pi / 2)
    rotated = np.array([[c, -s, 0, 0], [s, c, 0, 10], [0, 0, 1, 20], [0, 0, 0, 1]])
    m.move(m.pick((-5.0, 10.0, 120.0), (1.0, 0.0, 0.0))["part_id"], rotated)
    assert m.pick((-5.0, 10.0, 20.0), (1.0, 0.0, 0.0))["part"] == "box_0_1_2"


def test_pick_many_equals_a_loop_of_pick():
    m = dmu.plant(triangles=100_000)
    rng = np.random.default_rng(2)
    bounds = np.array([m.world(p["id"])[:3, 3] for p in m.parts()])
    lo, hi = bounds.min(axis=0), bounds.max(axis=0)
    n = 400
    origins = rng.uniform(lo, hi, size=(n, 3))
    targets = bounds[rng.integers(0, len(bounds), size=n)]
    directions = targets - origins + rng.normal(0, 100.0, size=(n, 3))
    directions[: n // 4] = rng.normal(size=(n // 4, 3))  # some random ones, many misses
    ids, distances, points = m.pick_many(origins, directions)
    assert ids.shape == (n,) and distances.shape == (n,) and points.shape == (n, 3)
    assert ids.dtype == np.int64 and distances.dtype == np.float64
    hits = 0
    for i in range(n):
        one = m.pick(origins[i], directions[i])
        if one is None:
            assert ids[i] == -1 and distances[i] == math.inf and np.isnan(points[i]).all()
        else:
            hits += 1
            assert ids[i] == one["part_id"]
            assert distances[i] == one["distance"]
            assert list(points[i]) == one["point"]
    assert 0 < hits < n
    # Lists and float32 are converted.
    ids32, _, _ = m.pick_many(origins.astype(np.float32).tolist(), directions.astype(np.float32))
    assert ids32.shape == (n,)
    # From several Python threads at once (the GIL is released), the same answers.
    results = [None] * 4

    def work(k):
        results[k] = m.pick_many(origins, directions)[0]

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for r in results:
        assert np.array_equal(r, ids)


# Sweeps are slow in the debug builds CI tests with: fewer, shorter records.
@pytest.mark.parametrize("continuous, count, steps", [(False, 3, 4), (True, 1, 2)])
def test_collide_matches_command_line(plant_store, dmu_bin, tmp_path, continuous, count, steps):
    m = dmu.open(plant_store)
    poses = {p["id"]: m.world(p["id"]) for p in m.parts()}
    records = make_records(m, tmp_path, count=count, steps=steps)
    total = 0
    for record in records:
        ours = m.collide(str(record), clearance=5.0, continuous=continuous)
        assert ours == cli_collide(dmu_bin, plant_store, record, 5.0, continuous)
        total += len(ours)
        # The same steps given as a list of dicts.
        steps = [json.loads(line) for line in record.read_text().splitlines()]
        assert m.collide(steps, clearance=5.0, continuous=continuous) == ours
    assert total > 0, "the records should clash"
    # Every part moved by the records is back where it was.
    for p, world in poses.items():
        assert np.array_equal(m.world(p), world)


def test_collide_fields_and_allow(plant_store, tmp_path):
    m = dmu.open(plant_store)
    (record,) = make_records(m, tmp_path, count=1, seed=11)
    found = m.collide(record, clearance=20.0)
    assert found, "the record should clash"
    for f in found:
        assert set(f) == {"step", "t", "kind", "a", "b", "a_id", "b_id", "distance", "toi", "point", "normal"}
        assert f["kind"] in {"hard", "contact", "soft"}
        assert f["distance"] <= 20.0
    a, b = found[0]["a_id"], found[0]["b_id"]
    allowed = m.collide(record, clearance=20.0, allow=[(a, b)])
    assert all({f["a_id"], f["b_id"]} != {a, b} for f in allowed)
    assert len(allowed) < len(found)


def test_save_and_reopen(grid_glb, tmp_path):
    m = dmu.open(grid_glb)
    moved = m.world("#5")
    moved[0, 3] += 1000.0
    m.move("#5", moved)
    for name in ["copy.dmu", "copy.glb"]:
        m.save(tmp_path / name)
        again = dmu.open(tmp_path / name)
        assert [p["path"] for p in again.parts()] == [p["path"] for p in m.parts()]
        assert np.array_equal(again.world(5), moved)


def test_plant_is_deterministic():
    a, b = dmu.plant(triangles=20_000, seed=3), dmu.plant(triangles=20_000, seed=3)
    assert a.parts() == b.parts() and 0 < a.triangles <= 20_000
    assert "built-in plant" in repr(a)


def test_bad_input_raises_naming_what(tmp_path, grid_glb):
    def raises(fn, *words):
        with pytest.raises(dmu.DmuError) as e:
            fn()
        for w in words:
            assert w in str(e.value), f"{w!r} not in {e.value}"
        assert "\n" not in str(e.value)

    assert issubclass(dmu.DmuError, ValueError)
    missing = tmp_path / "missing.glb"
    raises(lambda: dmu.open(missing), str(missing))
    broken = tmp_path / "broken.glb"
    broken.write_bytes(b"glTF\x02\x00\x00\x00" + b"\x00" * 20)
    raises(lambda: dmu.open(broken), str(broken))
    raises(lambda: dmu.open(tmp_path / "model.obj"), "model.obj", "unknown file type")
    raises(lambda: dmu.plant(triangles=5), "triangles")
    m = dmu.open(grid_glb)
    raises(lambda: m.pick((0, 0, 0), (0, 0, 0)), "direction")
    raises(lambda: m.pick((math.nan, 0, 0), (1, 0, 0)), "finite")
    raises(lambda: m.pick_many(np.zeros((3, 2)), np.ones((3, 2))), "origins", "(N, 3)")
    raises(lambda: m.pick_many(np.zeros((3, 3)), np.ones((4, 3))), "3 origins but 4 directions")
    raises(lambda: m.pick_many(np.zeros((2, 3)), np.array([[1, 0, 0], [0, 0, 0]])), "ray 1")
    raises(lambda: m.move("no_such_part", np.eye(4)), "no_such_part")
    raises(lambda: m.move(999, np.eye(4)), "999")
    raises(lambda: m.move("box_0_0_0", np.eye(3)), "box_0_0_0", "4x4")
    bad = np.eye(4)
    bad[3, 0] = 1.0
    raises(lambda: m.move("box_0_0_0", bad), "box_0_0_0", "last row")
    far = np.eye(4)
    far[0, 3] = 1e300
    raises(lambda: m.move("box_0_0_0", far), "box_0_0_0", "beyond")
    record = tmp_path / "bad.jsonl"
    record.write_text('{"t": 0, "part": "box_0_0_0", "translation": [0, 0, 0], "rotation": [0, 0, 0, 1]}\n'
                      '{"t": 1, "part": "pump_99", "translation": [0, 0, 0], "rotation": [0, 0, 0, 1]}\n')
    raises(lambda: m.collide(record), str(record), "line 2", "pump_99")
    raises(lambda: m.collide(tmp_path / "none.jsonl"), "none.jsonl")
    raises(lambda: m.collide([{"t": 0, "part": "box_0_0_0"}]), "steps", "line 1", "translation")
    raises(lambda: m.collide(record, clearance=-1.0), "clearance")
    raises(lambda: m.collide([], allow=[("box_0_0_0", "box_0_0_0")]), "twice")
    # Nothing was moved by the failed calls.
    assert np.array_equal(m.world("box_0_0_0"), np.eye(4))


def test_issue_48_threads_share_a_model(grid_glb):
    """Two Python threads on one model got `RuntimeError: Already borrowed`
    (a pick holding PyO3's borrow while a move wanted it). Now picks and moves
    from several threads interleave; every pick sees a whole move (the part at
    one of its two poses, never between) and the last move wins."""
    m = dmu.open(grid_glb)
    home = m.world("box_0_1_2")
    lifted = home.copy()
    lifted[2, 3] += 100.0
    origins = np.tile([-5.0, 10.0, 20.0], (200, 1))
    directions = np.tile([1.0, 0.0, 0.0], (200, 1))
    errors = []
    seen = set()

    def picker():
        try:
            for _ in range(100):
                ids, _, _ = m.pick_many(origins, directions)
                seen.update(ids.tolist())
                assert len(set(ids.tolist())) == 1, "one pose for the whole call"
                m.parts()
                len(m)
        except Exception as e:  # noqa: BLE001 - reported below
            errors.append(e)

    def mover():
        try:
            for i in range(200):
                m.move("box_0_1_2", lifted if i % 2 == 0 else home)
        except Exception as e:  # noqa: BLE001 - reported below
            errors.append(e)

    threads = [threading.Thread(target=picker) for _ in range(2)] + [threading.Thread(target=mover)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    names = {p["id"]: p["name"] for p in m.parts()}
    # The ray meets box_0_1_2 at home and box_1_1_2 behind it when lifted.
    assert {names[i] for i in seen} <= {"box_0_1_2", "box_1_1_2"}
    assert np.array_equal(m.world("box_0_1_2"), home)  # 200 moves: the last one home


def test_issue_48_collide_refuses_bytes(grid_glb):
    """`collide(b"...")` iterated the bytes as integers and read them as
    record lines; bytes and a lone dict are refused, naming what to give."""
    m = dmu.open(grid_glb)
    line = b'{"t": 0, "part": "box_0_0_0", "translation": [0, 0, 0], "rotation": [0, 0, 0, 1]}\n'
    for bad in (line, bytearray(line)):
        with pytest.raises(dmu.DmuError, match="not bytes"):
            m.collide(bad)
    with pytest.raises(dmu.DmuError, match="not one dict"):
        m.collide({"t": 0, "part": "box_0_0_0", "translation": [0, 0, 0], "rotation": [0, 0, 0, 1]})


def test_world_triangles_are_the_parts_in_place(grid_glb):
    m = dmu.open(grid_glb)
    tris, ids = m.world_triangles()
    assert tris.shape == (64 * 12, 3, 3) and tris.dtype == np.float64
    assert ids.shape == (64 * 12,) and ids.dtype == np.int64
    for p in m.parts():
        # Each grid box is 4 wide, centred on its part's translation.
        corners = tris[ids == p["id"]].reshape(-1, 3)
        centre = m.world(p["id"])[:3, 3]
        assert len(corners) == 36
        assert np.array_equal(np.unique(np.abs(corners - centre)), [2.0])
    # A pick lands on one of the triangles of the part it names.
    hit = m.pick((-5.0, 10.3, 20.4), (1.0, 0.0, 0.0))
    mine = tris[ids == hit["part_id"]]
    assert np.isclose(mine[:, :, 0], hit["point"][0]).all(axis=1).any()

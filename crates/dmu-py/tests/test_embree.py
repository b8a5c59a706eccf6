"""dmu's picks beside Embree's (PyPI `embreex`, f32) on the same rays, with an
f64 brute force in numpy as the judge wherever the two differ: the check of
benches/pick_embree.py, small enough for every run."""

import sys

import numpy as np

import dmu
from conftest import REPO, require


def test_where_embree_differs_dmu_equals_a_brute_force():
    try:
        sys.path.insert(0, str(REPO / "benches"))
        import pick_embree as bench
    except SystemExit as e:  # the bench exits when embreex is missing
        require(False, str(e))
    finally:
        sys.path.pop(0)
    m = dmu.plant(triangles=100_000)
    tris, _ = m.world_triangles()
    rng = np.random.default_rng(3)
    origins, directions = bench.random_rays(tris, 3000, rng)
    _, dist, _ = m.pick_many(origins, directions)
    assert np.isfinite(dist).all(), "every ray is aimed at a triangle"
    embree = bench.Embree(tris)
    e_dist = embree.distances(*embree.rays32(origins, directions))
    # Embree's f32 (the plant recentred, still 100 m across) differs from
    # dmu's f64 by more than 0.01 mm on some rays: each of those is judged.
    _, disagree = bench.differ(dist, e_dist, 0.01)
    assert len(disagree) < len(dist) // 10
    brute = bench.BruteForce(tris)
    checked = np.union1d(disagree, rng.choice(len(dist), 200, replace=False))
    assert bench.wrong_answers(brute, origins, directions, dist, checked) == []

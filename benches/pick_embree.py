#!/usr/bin/env python3
"""dmu's exact picks beside Embree's (PyPI `embreex`), on the same rays.

Casts the same rays into one model with both ray tracers, on one thread each
(RAYON_NUM_THREADS=1 before dmu loads; embreex's `run` is a loop of
`rtcIntersect1` on the calling thread), and prints per-ray times and how their
answers differ:

- random rays: each aimed at the centroid of a uniformly chosen triangle from
  0.5-20 m away (model units are millimetres), in a random direction;
- camera rays: a pinhole camera's grid of rays over the model.

Embree is given the world triangles (`Model.world_triangles`) recentred on
the model's box and narrowed to f32, as a user of it would; dmu answers in
f64. Every ray where the two disagree by more than `--tolerance`, and a
sample of `--sample` random rays, is checked against an f64 brute force
written here in numpy (Moeller-Trumbore over every triangle in the grid cells
the ray's line crosses, each cell bounded by its triangles' boxes), which
shares no code with dmu.

Usage (in a venv with the dmu wheel, numpy and embreex):
    python benches/pick_embree.py [MODEL.dmu] [--rays 100000] [--json]
Without a model it uses the built-in plant of --triangles (10M).
"""

import argparse
import json
import os
import sys
import time

if __name__ == "__main__":
    # One thread, as Embree's `run`; imported (by the tests), it leaves the pool be.
    os.environ.setdefault("RAYON_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import dmu  # noqa: E402

try:
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh
except ImportError:  # pragma: no cover - reported, not hidden
    sys.exit("error: embreex is not installed (pip install embreex)")


def random_rays(tris, count, rng):
    """Rays aimed at random triangles' centroids from 0.5-20 m away."""
    pick = rng.integers(0, len(tris), count)
    target = tris[pick].mean(axis=1)
    away = rng.normal(size=(count, 3))
    away /= np.linalg.norm(away, axis=1)[:, None]
    origins = target + away * rng.uniform(500.0, 20_000.0, count)[:, None]
    directions = target - origins
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    return origins, directions


def camera_rays(lo, hi, width, height):
    """A pinhole camera's rays: from above one corner of the box, looking at its
    centre with a 60-degree horizontal field of view."""
    centre = (lo + hi) / 2
    extent = hi - lo
    eye = centre + np.array([-0.45, -0.55, 0.35]) * extent
    forward = centre - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    half = np.tan(np.radians(30.0))
    xs = (np.arange(width) + 0.5) / width * 2 - 1
    ys = (np.arange(height) + 0.5) / height * 2 - 1
    gx, gy = np.meshgrid(xs * half, -ys * half * height / width)
    directions = forward + gx.reshape(-1, 1) * right + gy.reshape(-1, 1) * up
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    origins = np.repeat(eye[None, :], len(directions), axis=0)
    return origins, directions


class BruteForce:
    """The nearest hit distance by Moeller-Trumbore in f64 (unit directions)
    over every triangle whose grid cell the ray's line meets: triangles are
    bucketed by centroid into a uniform grid, each cell bounded by the boxes
    of its triangles, so no triangle the line meets is left out."""

    def __init__(self, tris, cells=48):
        lo = tris.reshape(-1, 3).min(axis=0)
        hi = tris.reshape(-1, 3).max(axis=0)
        centroid = tris.mean(axis=1)
        cell = np.clip(((centroid - lo) / np.maximum(hi - lo, 1e-300) * cells).astype(np.int64), 0, cells - 1)
        key = (cell[:, 0] * cells + cell[:, 1]) * cells + cell[:, 2]
        self.order = np.argsort(key, kind="stable")
        key = key[self.order]
        self.starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
        self.ends = np.r_[self.starts[1:], len(key)]
        tmin = tris.min(axis=1)[self.order]
        tmax = tris.max(axis=1)[self.order]
        slack = 1e-9 * np.abs(np.r_[lo, hi]).max()
        self.box_min = np.minimum.reduceat(tmin, self.starts) - slack
        self.box_max = np.maximum.reduceat(tmax, self.starts) + slack
        self.tris = tris

    def candidates(self, o, d):
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / d
            t1 = (self.box_min - o) * inv
            t2 = (self.box_max - o) * inv
        near = np.fmin(t1, t2)
        far = np.fmax(t1, t2)
        # An axis the ray runs parallel to: inside the slab or missed.
        flat = d == 0
        inside = (self.box_min <= o) & (o <= self.box_max)
        near = np.where(flat, np.where(inside, -np.inf, np.inf), near)
        far = np.where(flat, np.where(inside, np.inf, -np.inf), far)
        enter = near.max(axis=1)
        leave = far.min(axis=1)
        hit = np.flatnonzero((enter <= leave) & (leave >= 0))
        if len(hit) == 0:
            return np.zeros(0, np.int64)
        return self.order[np.concatenate([np.arange(self.starts[i], self.ends[i]) for i in hit])]

    def nearest(self, o, d):
        near = self.candidates(o, d)
        if len(near) == 0:
            return np.inf
        tri = self.tris[near]
        a = tri[:, 0]
        e1 = tri[:, 1] - a
        e2 = tri[:, 2] - a
        p = np.cross(d, e2)
        det = (e1 * p).sum(axis=1)
        ok = det != 0
        inv = np.where(ok, 1 / np.where(ok, det, 1), 0)
        s = o - a
        u = (s * p).sum(axis=1) * inv
        q = np.cross(s, e1)
        v = (q @ d) * inv
        t = (e2 * q).sum(axis=1) * inv
        slack = 1e-9
        hit = ok & (u >= -slack) & (v >= -slack) & (u + v <= 1 + slack) & (t >= 0)
        return t[hit].min() if hit.any() else np.inf


def timed(f):
    start = time.perf_counter()
    out = f()
    return out, time.perf_counter() - start


class Embree:
    """Embree's scene of the world triangles, recentred on their box and
    narrowed to f32, as a user of it would give them."""

    def __init__(self, tris):
        lo, hi = tris.reshape(-1, 3).min(axis=0), tris.reshape(-1, 3).max(axis=0)
        self.centre = (lo + hi) / 2
        self.scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self.scene, (tris - self.centre).astype(np.float32))
        # Embree commits its scene on the first query: pay for it here.
        self.scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))

    def rays32(self, origins, directions):
        return (origins - self.centre).astype(np.float32), directions.astype(np.float32)

    def distances(self, o32, d32):
        """Nearest hit distances (unit directions), inf for a miss."""
        res = self.scene.run(o32, d32, output=1)
        return np.where(res["geomID"] != -1, res["tfar"].astype(np.float64), np.inf)


def differ(a, b, tolerance):
    """Rays whose distances differ by more than `tolerance` (a hit against a miss too)."""
    both = np.isfinite(a) & np.isfinite(b)
    gap = np.full(len(a), np.inf)
    gap[both] = np.abs(a[both] - b[both])
    gap[~np.isfinite(a) & ~np.isfinite(b)] = 0.0
    return gap, np.flatnonzero(gap > tolerance)


def wrong_answers(brute, origins, directions, dist, rays):
    """The rays among `rays` where `dist` is not the brute force's distance."""
    wrong = []
    for i in rays:
        truth = brute.nearest(origins[i], directions[i])
        ok = (np.isinf(truth) and np.isinf(dist[i])) or abs(truth - dist[i]) <= 1e-6 * max(1.0, truth)
        if not ok:
            wrong.append({"ray": int(i), "dmu": float(dist[i]), "brute_force": float(truth)})
    return wrong


def compare(name, origins, directions, model, embree, brute, args, rng):
    # Cold: the first pick of a freshly opened model pays for chunk BVHs.
    _, cold_s = timed(lambda: model.pick_many(origins, directions))
    o32, d32 = embree.rays32(origins, directions)
    dmu_s, embree_s = [], []
    for _ in range(args.repeat):
        (_, dist, _), s = timed(lambda: model.pick_many(origins, directions))
        dmu_s.append(s)
        e_dist, s = timed(lambda: embree.distances(o32, d32))
        embree_s.append(s)
    gap, disagree = differ(dist, e_dist, args.tolerance)
    sample = rng.choice(len(origins), min(args.sample, len(origins)), replace=False)
    checked = np.union1d(sample, disagree)
    print(
        f"{name}: dmu {min(dmu_s) / len(origins) * 1e6:.2f} us/ray, embree "
        f"{min(embree_s) / len(origins) * 1e6:.2f} us/ray; checking {len(checked)} rays by brute force",
        file=sys.stderr,
    )
    wrong = wrong_answers(brute, origins, directions, dist, checked)
    rays = len(origins)
    dmu_us = min(dmu_s) / rays * 1e6
    embree_us = min(embree_s) / rays * 1e6
    return {
        "rays": rays,
        "hits": int(np.isfinite(dist).sum()),
        "dmu_us_per_ray": dmu_us,
        "dmu_cold_us_per_ray": cold_s / rays * 1e6,
        "cold_over_warm": cold_s / min(dmu_s),
        "embree_us_per_ray": embree_us,
        "dmu_over_embree": dmu_us / embree_us,
        "embree_off_by_more_than_tolerance": int(len(disagree)),
        "embree_off_most": float(gap[np.isfinite(gap)].max(initial=0.0)),
        "embree_hit_or_miss_differs": int(np.isinf(gap).sum()),
        "checked_against_brute_force": int(len(checked)),
        "dmu_wrong": wrong,
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("model", nargs="?", help="a .dmu store or glTF; the built-in plant when omitted")
    parser.add_argument("--triangles", type=int, default=10_000_000)
    parser.add_argument("--rays", type=int, default=100_000)
    parser.add_argument("--sample", type=int, default=1000, help="random rays checked by brute force")
    parser.add_argument("--tolerance", type=float, default=0.01, help="model units (mm)")
    parser.add_argument("--repeat", type=int, default=3, help="warm runs; the fastest counts")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()

    def open_model():
        return dmu.open(args.model) if args.model else dmu.plant(triangles=args.triangles)

    model, load_s = timed(open_model)
    tris, _ = model.world_triangles()
    embree, embree_build_s = timed(lambda: Embree(tris))
    brute = BruteForce(tris)
    rng = np.random.default_rng(args.seed)
    side = int(round(np.sqrt(args.rays)))
    lo, hi = tris.reshape(-1, 3).min(axis=0), tris.reshape(-1, 3).max(axis=0)
    results = {
        "model": args.model or f"built-in plant {args.triangles}",
        "triangles": len(tris),
        "threads": 1,
        "load_s": load_s,
        "embree_build_s": embree_build_s,
        "random": compare("random", *random_rays(tris, args.rays, rng), model, embree, brute, args, rng),
    }
    # A fresh model, so the camera rays' cold time is cold too.
    model = open_model()
    results["camera"] = compare("camera", *camera_rays(lo, hi, side, side), model, embree, brute, args, rng)
    if args.json:
        print(json.dumps(results, indent=2))
    else:
        for kind in ("random", "camera"):
            r = results[kind]
            print(
                f"{kind}: {r['rays']} rays, {r['hits']} hit; dmu {r['dmu_us_per_ray']:.2f} us/ray "
                f"(cold {r['dmu_cold_us_per_ray']:.2f}), embree {r['embree_us_per_ray']:.2f} us/ray, "
                f"ratio {r['dmu_over_embree']:.2f}; embree off by > {args.tolerance} on "
                f"{r['embree_off_by_more_than_tolerance']} (most {r['embree_off_most']:.3g}); "
                f"{len(r['dmu_wrong'])} of {r['checked_against_brute_force']} dmu answers differ from brute force"
            )
    if results["random"]["dmu_wrong"] or results["camera"]["dmu_wrong"]:
        sys.exit(1)


if __name__ == "__main__":
    main()

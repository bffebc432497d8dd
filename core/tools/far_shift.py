"""Far and shifted scenes: what a ray costs when the scene lies far from the
origin, or the rays start far from the scene (the table in
docs/algorithms.md#far-scenes).

    python core/tools/far_shift.py [--scene sibenik] [--rays 1000] [--rounds 3]

Two tables, per method (kd, bvh, bsp_wn+kd by default):

* shift: one scene and one set of rays (ray_families.shifted: identical
  geometry, rounded at the shift and moved back exactly) at the origin and at
  +S on every axis, S = 1e3 ... 1e7 (ray_families.SHIFTS); steps and triangle
  tests per ray, the hits-only time over Embree's on the same scene (paired
  rounds), and the rays whose hit differs from the origin copy's.
* distance: the scene at the origin, rays from D scene sizes away towards
  its surface (ray_families.from_distance), D = 2 ... 1e7; steps and tests
  per ray, and the time over Embree's.

Plus the sweep builder's SAH cost (bsp_random) at the origin and at each
shift: its robust_epsilon fattens every clipped cell where the bound follows
the coordinates rather than the scene."""

from __future__ import annotations

import argparse

import numpy as np

import bsplab
from bsplab import oracle, ray_families
from bsplab.lab.timing import Tracer, paired_rounds
from bsplab.scenes import load

METHODS = ("kd", "bvh", "bsp_wn+kd")
DISTANCES = (2, 10, 100, 500, 1e3, 1e4, 1e5, 1e6, 1e7)


def cost(tree, tris, o, d, tmax, rounds: int) -> dict:
    """Steps and tests per ray (counting path), the hits-only time over
    Embree's, and the hits."""
    h = tree.intersect(o, d, tmax=tmax, threads=1)
    embree = oracle.EmbreeTracer(tris)
    etmax = None if np.isinf(tmax).all() else tmax
    times = paired_rounds({
        "ours": Tracer(lambda: tree.intersect(o, d, tmax=tmax, threads=1, counters=False)),
        "embree": Tracer(lambda: embree.intersect(o, d, tmax=etmax),
                         lambda: embree.last_seconds)}, rounds)
    return {"steps": float(h["steps"].mean()), "tests": float(h["tests"].mean()),
            "x_embree": times.ratio("ours", "embree"), "hits": h}


def shift_table(tris, methods, count: int, rounds: int, families) -> None:
    print(f"\nshift: the scene and its rays at the origin and at +S ({count} rays per family)")
    print(f"{'method':<11}{'family':<16}{'S':>7}{'steps':>9}{'tests':>8}{'x Embree':>9}"
          f"{'  at origin: steps':>19}{'tests':>8}{'x Embree':>9}{'differ':>8}")
    for family in families:
        for shift in ray_families.SHIFTS:
            (base, o0), (moved, o_moved), d, tmax = ray_families.shifted(
                family, tris, count, shift, seed=5)
            for method in methods:
                at0 = cost(bsplab.build(base, method=method), base, o0, d, tmax, rounds)
                far = cost(bsplab.build(moved, method=method), moved, o_moved, d, tmax, rounds)
                differ = int(((at0["hits"]["prim"] != far["hits"]["prim"]) |
                              (at0["hits"]["t"] != far["hits"]["t"])).sum())
                print(f"{method:<11}{family:<16}{shift:>7.0e}{far['steps']:>9.1f}"
                      f"{far['tests']:>8.1f}{far['x_embree']:>9.2f}{'':>11}{at0['steps']:>8.1f}"
                      f"{at0['tests']:>8.1f}{at0['x_embree']:>9.2f}{differ:>8}", flush=True)


def distance_table(tris, methods, count: int, rounds: int) -> None:
    print(f"\ndistance: rays from D scene sizes away ({count} rays)")
    print(f"{'method':<11}{'D':>7}{'steps':>9}{'tests':>8}{'x Embree':>9}")
    for method in methods:
        tree = bsplab.build(tris, method=method)
        for dist in DISTANCES:
            rng = np.random.default_rng([3, int(np.log10(dist) * 100)])
            o, d = ray_families.from_distance(tris, count, rng, dist)
            tmax = np.full(len(o), np.inf, np.float32)
            c = cost(tree, tris, o, d, tmax, rounds)
            print(f"{method:<11}{dist:>7.0e}{c['steps']:>9.1f}{c['tests']:>8.1f}"
                  f"{c['x_embree']:>9.2f}", flush=True)


def sweep_sah(tris) -> None:
    print("\nthe sweep builder's SAH cost (bsp_random) at the origin and at +S")
    for shift in (0.0,) + ray_families.SHIFTS:
        base = tris if shift == 0 else ray_families.representable_at(tris, shift)
        moved = (base.astype(np.float64) + shift).astype(np.float32)
        at0 = bsplab.build(base, method="bsp_random").stats["sah_cost"]
        far = bsplab.build(moved, method="bsp_random").stats["sah_cost"]
        print(f"  S {shift:>7.0e}: origin {at0:10.2f}   shifted {far:10.2f}", flush=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default="sibenik", help="a scene name or mesh file")
    p.add_argument("--rays", type=int, default=1000, help="rays per family and distance")
    p.add_argument("--rounds", type=int, default=3, help="paired timing rounds")
    p.add_argument("--methods", nargs="+", default=list(METHODS))
    p.add_argument("--families", nargs="+", default=["outside_in", "inside_camera"])
    p.add_argument("--skip", nargs="*", default=[], choices=["shift", "distance", "sah"])
    args = p.parse_args()
    tris = load(args.scene)
    print(f"{args.scene}: {len(tris):,} triangles")
    if "shift" not in args.skip:
        shift_table(tris, args.methods, args.rays, args.rounds, args.families)
    if "distance" not in args.skip:
        distance_table(tris, args.methods, args.rays, args.rounds)
    if "sah" not in args.skip:
        sweep_sah(tris)


if __name__ == "__main__":
    main()

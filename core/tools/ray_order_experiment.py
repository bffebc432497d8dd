"""What tracing incoherent rays in spatial order buys, and what it would buy Embree.

Per scene, random rays (workloads.random_rays, seed 1) traced on one thread,
hits only, in rounds of four: the tree with the rays kept in the given order
(`ray_order="given"`), the tree sorting them itself (`ray_order="spatial"`,
core/src/trace/ray_order.hpp), Embree on the given rays and Embree on the
same rays in the sort's order (the key recomputed here in numpy, outside the
timed calls). Prints one Markdown row per scene: the medians over the rounds
of each round's ratios (docs/performance.md, "Incoherent rays in spatial
order"), and whether both of the tree's orders gave the same hits.

With --worlds, the same for instanced scenes (bsplab.instanced_scenes.WORLDS,
random rays in the instances' box): the two levels in the given order and
sorted, and whether both gave the same hits and instances (no Embree: most
worlds are too large to flatten).

    python core/tools/ray_order_experiment.py --scenes bunny sibenik [--method kd]
    python core/tools/ray_order_experiment.py --scenes --worlds grid25 city --method bvh
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import bsplab
from bsplab import instanced_scenes, oracle, scenes, workloads


def spatial_order(o: np.ndarray, d: np.ndarray) -> np.ndarray:
    """The core's order (ray_order.cpp): a 30-bit Morton code of the origin's
    and the direction's cells, 32 per axis each, sorted stably."""
    lo, hi = o.min(0), o.max(0)
    span = np.where(hi > lo, hi - lo, 1.0)
    scale = np.where(hi > lo, 32.0 / span, 0.0).astype(np.float32)
    oc = np.clip((o - lo) * scale, 0, 31).astype(np.int64)
    m = np.abs(d).max(1, keepdims=True)
    dc = np.clip(d * (16.0 / m) + 16.0, 0, 31).astype(np.int64)
    key = np.zeros(len(o), np.int64)
    for bit in range(4, -1, -1):
        for cells in (oc, dc):
            for k in range(3):
                key = (key << 1) | ((cells[:, k] >> bit) & 1)
    return np.argsort(key, kind="stable")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="*", default=["bunny", "sibenik"])
    p.add_argument("--worlds", nargs="*", default=[])
    p.add_argument("--method", default="kd")
    p.add_argument("--rays", type=int, default=250_000)
    p.add_argument("--rounds", type=int, default=7)
    a = p.parse_args()
    print("| scene | method | given ÷ Embree | sorted ÷ Embree | sorted ÷ given | "
          "Embree sorted ÷ given | sorted ÷ Embree sorted | same hits |")
    print("|---|---|---:|---:|---:|---:|---:|---|")
    for name in a.scenes:
        tris = scenes.load(name)
        tree = bsplab.build(tris, a.method, threads=2)
        embree = oracle.EmbreeTracer(tris)
        o, d = workloads.random_rays(tris, a.rays, seed=1)
        order = spatial_order(o, d)
        so, sd = o[order], d[order]
        times = {k: [] for k in ("given", "sorted", "embree", "embree_sorted")}
        runs = {
            "given": lambda: tree.intersect(o, d, threads=1, counters=False, ray_order="given"),
            "sorted": lambda: tree.intersect(o, d, threads=1, counters=False,
                                             ray_order="spatial"),
            "embree": lambda: embree.intersect(o, d),
            "embree_sorted": lambda: embree.intersect(so, sd),
        }
        hits = {}
        for _ in range(a.rounds):
            for key, run in runs.items():
                start = time.perf_counter()
                hits[key] = run()
                times[key].append(time.perf_counter() - start)
        g, s, e, es = (np.array(times[k]) for k in runs)
        same = all(np.array_equal(hits["given"][c], hits["sorted"][c])
                   for c in ("t", "prim", "u", "v"))
        print(f"| {name} | {a.method} | {np.median(g / e):.2f} | {np.median(s / e):.2f} | "
              f"{np.median(s / g):.3f} | {np.median(es / e):.3f} | {np.median(s / es):.2f} | "
              f"{same} |", flush=True)
    if a.worlds:
        print("\n| world | method | sorted ÷ given | same hits |\n|---|---|---:|---|")
    for world in a.worlds:
        instanced_world(world, a.method, a.rays, a.rounds)


def instanced_world(world: str, method: str, rays: int, rounds: int) -> None:
    meshes, idx, mats = instanced_scenes.WORLDS[world]()
    scene = bsplab.build_instanced(meshes, idx, mats, method)
    # The instances' box: the top level's root.
    root = scene.top_boxes(max_depth=0)
    rng = np.random.default_rng(1)
    o = rng.uniform(root["lo"][0], root["hi"][0], (rays, 3)).astype(np.float32)
    d = rng.normal(size=(rays, 3))
    d = (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
    times = {"given": [], "sorted": []}
    hits = {}
    for _ in range(rounds):
        for key in times:
            start = time.perf_counter()
            hits[key] = scene.intersect(o, d, threads=1, counters=False,
                                        ray_order="given" if key == "given" else "spatial")
            times[key].append(time.perf_counter() - start)
    g, s = np.array(times["given"]), np.array(times["sorted"])
    same = all(np.array_equal(hits["given"][c], hits["sorted"][c])
               for c in ("t", "prim", "u", "v", "instance"))
    print(f"| {world} | {method} | {np.median(s / g):.3f} | {same} |", flush=True)


if __name__ == "__main__":
    main()

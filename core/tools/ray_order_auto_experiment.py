"""Where the spatial order pays: random rays from boxes of growing size.

The sort's cost does not depend on the walk, so rays that mostly miss the
scene trace slower sorted; `ray_order="auto"` (the default) sorts a batch
only when a probe of it walks at least 8 nodes a ray in a tree, 16 in an
instanced scene, half of each on one thread (core/src/trace/ray_order.hpp).
Per scene or world and per `--scales` factor, random rays (origins uniform in a box that many times the
scene's, or the instances', box about its centre; directions on the sphere)
traced hits only: the mean steps of the probe's 128 rays (counting path; an
instanced scene's top level and mesh trees), whether "auto" sorts the batch
on one thread and on all,
and the times sorted ("spatial") and under "auto" over the given order's,
best of `--rounds`, on one thread and on all of them. Prints one Markdown
row per case (docs/performance.md, "Sorted only where the walks pay").

    python core/tools/ray_order_auto_experiment.py --scenes bunny conference sibenik \\
        --worlds grid25 city --scales 1 1.5 2 2.5 10
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import bsplab
from bsplab import instanced_scenes, scenes, workloads

ORDERS = ("given", "spatial", "auto")
PROBE_RAYS = 128  # ray_order.hpp's kProbeRays


def box_rays(lo, hi, scale: float, n: int, seed: int = 1):
    c, r = (lo + hi) / 2, (hi - lo) / 2
    rng = np.random.default_rng(seed)
    o = rng.uniform(c - scale * r, c + scale * r, (n, 3)).astype(np.float32)
    d = rng.normal(size=(n, 3))
    return o, (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)


def best_ratios(tracer, o, d, threads: int, rounds: int) -> dict:
    """Each order's best time over the given order's best."""
    times = {k: [] for k in ORDERS}
    for _ in range(rounds):
        for order in ORDERS:
            start = time.perf_counter()
            tracer.intersect(o, d, threads=threads, counters=False, ray_order=order)
            times[order].append(time.perf_counter() - start)
    given = min(times["given"])
    return {k: min(v) / given for k, v in times.items()}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="*", default=["bunny", "conference"])
    p.add_argument("--worlds", nargs="*", default=[])
    p.add_argument("--method", default="kd")
    p.add_argument("--scales", nargs="+", type=float, default=[1.0, 2.0, 10.0])
    p.add_argument("--rays", type=int, default=250_000)
    p.add_argument("--rounds", type=int, default=5)
    a = p.parse_args()
    print("| scene | box | probe steps a ray | auto sorts, 1 / all threads | 1 thread: spatial / auto ÷ given "
          "| all threads: spatial / auto ÷ given |\n|---|---:|---:|---|---|---|")
    cases = [(name, False) for name in a.scenes] + [(name, True) for name in a.worlds]
    for name, instanced in cases:
        if instanced:
            make = {**instanced_scenes.TEST_SCENES, **instanced_scenes.WORLDS}[name]
            meshes, idx, mats = make()
            tracer = bsplab.build_instanced(meshes, idx, mats, a.method)
            root = tracer.top_boxes(max_depth=0)
            lo, hi = root["lo"][0], root["hi"][0]
        else:
            tris = scenes.load(name)
            tracer = bsplab.build(tris, a.method)
            lo, hi = workloads.bounds(tris)
        for scale in a.scales:
            o, d = box_rays(lo, hi, scale, a.rays)
            probe = (np.arange(PROBE_RAYS) * (len(o) - 1)) // (PROBE_RAYS - 1)
            counted = tracer.intersect(o[probe], d[probe], threads=1)
            steps = counted["steps"] + (counted["top_steps"] if instanced else 0)
            sorts = [bsplab._core.orders_instanced_rays(tracer._scene, o, d, threads=t)
                     if instanced else bsplab._core.orders_rays(o, d, tracer._tree, threads=t)
                     for t in (1, 0)]
            one = best_ratios(tracer, o, d, 1, a.rounds)
            every = best_ratios(tracer, o, d, 0, a.rounds)
            print(f"| {name} | {scale:g} | {float(np.mean(steps)):.1f} | {sorts[0]} / {sorts[1]} | "
                  f"{one['spatial']:.3f} / {one['auto']:.3f} | "
                  f"{every['spatial']:.3f} / {every['auto']:.3f} |", flush=True)


if __name__ == "__main__":
    main()

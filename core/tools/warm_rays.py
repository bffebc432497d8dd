"""How much of the kernel's gap to Embree a cache layout could close.

Traces the same 200k rays three ways, each paired with Embree in one
process: all distinct (the benchmark's case); the first 2,000 repeated 100
times (their nodes stay in the L2 cache, but their branches are too many for
the predictor to learn); the first 200 repeated 1,000 times (the predictor
learns each ray's whole path). A layout that removed every cache miss could
at most reach the second rate; the third shows what the branches and the
chain of dependent node fetches cost.

    python core/tools/warm_rays.py bunny random [--method kd]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import bsplab
from bsplab import io, oracle, workloads
from bsplab.lab.timing import Tracer, paired_rounds

SCENES = Path(__file__).resolve().parents[2].parent / "shared" / "scenes"
RAYS = 200_000


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scene")
    p.add_argument("workload", choices=["random", "primary"])
    p.add_argument("--method", default="kd")
    args = p.parse_args()
    tris = io.load_mesh(SCENES / f"{args.scene}.ply")
    tree = bsplab.build(tris, args.method)
    embree = oracle.EmbreeTracer(tris)
    if args.workload == "random":
        origins, directions = workloads.random_rays(tris, RAYS)
    else:  # a sample of the camera's rays in random order (the first tiles are sky)
        o, d = workloads.primary_rays(tris, 512, 512)
        pick = np.random.default_rng(3).choice(len(o), RAYS, replace=False)
        origins, directions = o[pick], d[pick]
    for distinct in (RAYS, 2_000, 200):
        o = np.ascontiguousarray(np.tile(origins[:distinct], (RAYS // distinct, 1)))
        d = np.ascontiguousarray(np.tile(directions[:distinct], (RAYS // distinct, 1)))
        tracers = {"ours": Tracer(lambda: tree.intersect(o, d, threads=1, counters=False)),
                   "embree": Tracer(lambda: embree.intersect(o, d), lambda: embree.last_seconds)}
        rounds = paired_rounds(tracers, 5)
        print(f"{args.scene} {args.workload} {distinct:>7} distinct rays: "
              f"ours {RAYS / rounds.median('ours') / 1e6:5.1f} Mray/s, "
              f"Embree {RAYS / rounds.median('embree') / 1e6:5.1f} Mray/s, "
              f"ratio {1 / rounds.ratio('ours', 'embree'):.2f}", flush=True)


if __name__ == "__main__":
    main()

"""How well does a build use the threads it is given? For each scene and
quality, builds one method on 1 and on N threads in paired rounds
(bsplab.lab.timing: one after the other, the order rotating) with Embree's
build beside them, and prints the medians, the speed-up (1-thread time over
N-thread time, a median of per-round ratios), the N-thread build over
Embree's, and the process's CPU seconds per wall second during the N-thread
builds (N when every thread is busy all the way).

    .venv/bin/python core/tools/build_scaling.py --scenes conference bunny \\
        --method kd --threads 2 --rounds 3

The experiment behind BuilderBase::spawns (core/src/builders/build_tree.hpp):
conference's kd build ran 1.30x faster on 2 threads than on 1 while tasks
were spawned by depth, 1.77x once they were spawned by size.
"""

from __future__ import annotations

import argparse
import resource
import time

import bsplab
from bsplab import oracle, scenes
from bsplab.lab.timing import Tracer, paired_rounds


def cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenes", nargs="+", default=["conference", "bunny"])
    ap.add_argument("--method", default="kd")
    ap.add_argument("--k", type=int, help="K for a sweep method")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--qualities", nargs="+", default=["exact", "fast"])
    args = ap.parse_args()
    options = {"k": args.k} if args.k else {}
    n = args.threads
    for name in args.scenes:
        tris = scenes.load(name)
        busy = {q: [0.0, 0.0] for q in args.qualities}  # CPU and wall seconds at n threads

        def build(quality, threads):
            def run():
                c0, t0 = cpu_seconds(), time.perf_counter()
                tree = bsplab.build(tris, args.method, threads=threads, build_quality=quality,
                                    **options)
                if threads == n:
                    busy[quality][0] += cpu_seconds() - c0
                    busy[quality][1] += time.perf_counter() - t0
                return tree
            return Tracer(run)

        tracers = {f"{q}{t}": build(q, t) for q in args.qualities for t in (1, n)}
        tracers["embree"] = Tracer(lambda: oracle.EmbreeTracer(tris))
        r = paired_rounds(tracers, args.rounds)
        for q in args.qualities:
            print(f"{name} {args.method} {q}: 1 thread {r.median(f'{q}1'):.3f} s, {n} threads "
                  f"{r.median(f'{q}{n}'):.3f} s, speed-up {r.ratio(f'{q}1', f'{q}{n}'):.2f}, "
                  f"÷ Embree {r.ratio(f'{q}{n}', 'embree'):.2f} (Embree "
                  f"{r.median('embree'):.3f} s), CPU use {busy[q][0] / busy[q][1]:.2f}",
                  flush=True)


if __name__ == "__main__":
    main()

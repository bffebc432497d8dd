"""Per-ray instruction, branch and mispredict counts of the single-ray kernel
on one shared scene, under callgrind (exact, unlike times on a shared
machine). Used for the profiles in docs/performance.md and docs/benchmark.md.

    python core/tools/profile_trace.py bunny random [--method kd] [--isa avx2]

runs itself under `valgrind --tool=callgrind --branch-sim=yes --cache-sim=yes`
with instrumentation on only around the trace, then prints
the totals per ray. `--annotate` also prints callgrind_annotate's lines
(needs a build with debug info for source lines: RelWithDebInfo)."""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

SCENES = Path(__file__).resolve().parents[2].parent / "shared" / "scenes"
EVENTS = ("Ir", "Bc", "Bcm", "D1mr", "DLmr")


def trace(scene: str, workload: str, method: str) -> int:
    """The traced part (run under valgrind): returns the number of rays."""
    import bsplab
    from bsplab import io, workloads
    tris = io.load_mesh(SCENES / f"{scene}.ply")
    tree = bsplab.build(tris, method, threads=1)
    if workload == "random":
        o, d = workloads.random_rays(tris, 20000)
    else:
        o, d = workloads.primary_rays(tris, 160, 125, tiles=True)
    # Nanobind strips Release modules, so there is no kernel symbol to
    # toggle on: the traced process switches collection on around the trace.
    _callgrind("on")
    tree.intersect(o, d, threads=1, counters=False)
    _callgrind("off")
    return len(o)


def _callgrind(state: str) -> None:
    subprocess.run(["callgrind_control", "-i", state, str(os.getpid())], check=True,
                   capture_output=True)


def profile(args) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "callgrind.out"
        cmd = ["valgrind", "--tool=callgrind", "--branch-sim=yes", "--cache-sim=yes",
               "--dump-instr=yes", "--instr-atstart=no",
               f"--callgrind-out-file={out}", sys.executable, __file__, args.scene,
               args.workload, "--method", args.method, "--inside"]
        env = dict(os.environ, BSPLAB_ISA=args.isa)
        run = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
        rays = int(re.search(r"^rays (\d+)$", run.stdout, re.M).group(1))
        text = out.read_text()
        names = re.search(r"^events: (.*)$", text, re.M).group(1).split()
        totals = [int(x) for x in re.search(r"^totals: (.*)$", text, re.M).group(1).split()]
        per_ray = {n: v / rays for n, v in zip(names, totals)}
        print(f"{args.scene} {args.workload} {args.method} ({args.isa}, {rays} rays), per ray: "
              + ", ".join(f"{n} {per_ray[n]:.1f}" for n in EVENTS if n in per_ray))
        if args.annotate:
            print(subprocess.run(["callgrind_annotate", "--auto=yes", str(out)],
                                 capture_output=True, text=True).stdout)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scene")
    p.add_argument("workload", choices=["random", "primary"])
    p.add_argument("--method", default="kd")
    p.add_argument("--isa", default="avx2", help="BSPLAB_ISA under valgrind (no AVX-512 there)")
    p.add_argument("--annotate", action="store_true")
    p.add_argument("--inside", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.inside:
        print("rays", trace(args.scene, args.workload, args.method))
    else:
        profile(args)


if __name__ == "__main__":
    main()

"""The sweep builder's build quality on the shared meshes (issue 25): the
build times of bsp_wn+kd (K = 8) and bsp_ize+kd, exact and fast, as
multiples of the exact kd build in paired rounds (timing.paired_rounds: the
builds one after the other, the order rotating, each figure the median of
the per-round ratios), their SAH costs fast against exact, and optionally
the fast trees' trace time over the exact ones' (hits only, primary and
random rays, paired rounds too).

    .venv/bin/python core/tools/sweep_fast_bench.py --scenes bunny sponza_dabrovic \\
        --repeats 2 --threads 2 [--trace] [--fast-min-refs N] [--fast-bins B]
"""

from __future__ import annotations

import argparse

import bsplab
from bsplab import scenes, workloads
from bsplab.lab.timing import Tracer, paired_rounds

METHODS = {"wn8": ("bsp_wn+kd", {"k": 8}), "ize": ("bsp_ize+kd", {})}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenes", nargs="+", default=["bunny", "sponza_dabrovic"])
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--methods", nargs="+", default=list(METHODS))
    ap.add_argument("--fast-min-refs", type=int)
    ap.add_argument("--fast-bins", type=int)
    ap.add_argument("--no-exact", action="store_true", help="time the fast builds only")
    ap.add_argument("--trace", action="store_true", help="also time tracing, fast / exact")
    ap.add_argument("--side", type=int, default=256)
    ap.add_argument("--rays", type=int, default=100_000)
    args = ap.parse_args()
    fast = {"build_quality": "fast"}
    if args.fast_min_refs:
        fast["fast_min_refs"] = args.fast_min_refs
    if args.fast_bins:
        fast["fast_bins"] = args.fast_bins
    for name in args.scenes:
        tris = scenes.load(name)
        t = args.threads
        tracers = {"kd": Tracer(lambda: bsplab.build(tris, "kd", threads=t))}
        for key in args.methods:
            method, opts = METHODS[key]
            if not args.no_exact:
                tracers[key] = Tracer(lambda m=method, o=opts: bsplab.build(tris, m, threads=t, **o))
            tracers[key + "_fast"] = Tracer(
                lambda m=method, o=opts: bsplab.build(tris, m, threads=t, **o, **fast))
        times = paired_rounds(tracers, args.repeats)
        line = [f"{name} ({len(tris)} tris): kd {times.median('kd'):.3f} s"]
        for key in tracers:
            if key == "kd":
                continue
            st = times.results[key].stats
            line.append(f"{key} {times.median(key):.3f} s = {times.ratio(key, 'kd'):.2f}x kd, "
                        f"SAH {st['sah_cost']:.3f}")
        for key in args.methods:
            if args.no_exact:
                continue
            a = times.results[key].stats["sah_cost"]
            b = times.results[key + "_fast"].stats["sah_cost"]
            line.append(f"{key} SAH fast/exact {b / a:.4f}")
        print("; ".join(line), flush=True)
        if args.trace and not args.no_exact:
            prim = workloads.primary_rays(tris, args.side, args.side, tiles=True)
            rand = workloads.random_rays(tris, args.rays)
            for key in args.methods:
                for label, (o, d) in (("primary", prim), ("random", rand)):
                    ex, fa = times.results[key], times.results[key + "_fast"]
                    tr = {"exact": Tracer(lambda: ex.intersect(o, d, threads=1)),
                          "fast": Tracer(lambda: fa.intersect(o, d, threads=1))}
                    tt = paired_rounds(tr, 5)
                    print(f"  {name} {key} trace {label}: fast/exact {tt.ratio('fast', 'exact'):.3f} "
                          f"(exact {tt.median('exact'):.3f} s)", flush=True)


if __name__ == "__main__":
    main()

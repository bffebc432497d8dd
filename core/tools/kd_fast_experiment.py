"""How fast, and how good, are the kd builder's fast trees? Builds each scene
with kd exact, kd fast under each option set, and Embree's BVH, in paired
rounds (bsplab.lab.timing: one after the other, the order rotating), and
prints per scene the medians of the per-round build-time ratios to
Embree's build and each tree's SAH cost (stats["sah_cost"]) against the
exact tree's. The experiment behind kFastBins and kFastMinRefs (tree.hpp).

Run: .venv/bin/python core/tools/kd_fast_experiment.py --scenes bunny sibenik \\
        --rounds 3 --threads 2 -- default fast_bins=16,fast_min_refs=1024

Option sets are `default` (the registry's fast defaults) or comma-separated
name=value pairs added to build_quality="fast" (e.g. fast_bins=32,
fast_min_gain=0.1).

With --trace, times tracing instead: the exact tree and each fast tree trace
the same rays (256 x 256 primary rays in tiles, 65,536 random rays; one
thread, hits only) in paired rounds, and the medians of the per-round
ratios fast / exact are printed with the mean steps and tests per ray."""
import argparse

import bsplab
from bsplab import oracle, scenes, workloads
from bsplab.lab.timing import Tracer, paired_rounds

SHARED = ["bunny", "conference", "dragon_res2", "lost_empire", "sibenik",
          "sponza_dabrovic", "sportscar"]


def option_set(text: str) -> dict:
    if text == "default":
        return {}
    def number(value: str):
        return int(value) if value.lstrip("-").isdigit() else float(value)
    return {name: number(value) for name, value in (p.split("=") for p in text.split(","))}


def trace_rows(name: str, tris, sets: list[str], rounds: int) -> None:
    trees = {"exact": bsplab.build(tris, "kd")}
    for s in sets:
        trees[s] = bsplab.build(tris, "kd", build_quality="fast", **option_set(s))
    workloads_ = {"primary": workloads.primary_rays(tris, 256, 256, tiles=True),
                  "random": workloads.random_rays(tris, 65536)}
    for wname, (o, d) in workloads_.items():
        tracers = {k: Tracer(lambda t=t: t.intersect(o, d, threads=1, counters=False))
                   for k, t in trees.items()}
        times = paired_rounds(tracers, rounds)
        for s in sets:
            h = trees[s].intersect(o, d, threads=1)
            he = trees["exact"].intersect(o, d, threads=1)
            print(f"{name} {wname:7s} fast {s}: time / exact {times.ratio(s, 'exact'):.3f} "
                  f"(exact {times.median('exact'):.3f} s); steps {h['steps'].mean():.1f} vs "
                  f"{he['steps'].mean():.1f}, tests {h['tests'].mean():.2f} vs "
                  f"{he['tests'].mean():.2f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenes", nargs="+", default=SHARED)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--trace", action="store_true", help="time tracing, not building")
    ap.add_argument("sets", nargs="*", default=["default"])
    args = ap.parse_args()
    for name in args.scenes:
        tris = scenes.load(name)
        if args.trace:
            trace_rows(name, tris, args.sets, args.rounds)
            continue
        tracers = {
            "exact": Tracer(lambda: bsplab.build(tris, "kd", threads=args.threads)),
            "embree": Tracer(lambda: oracle.EmbreeTracer(tris)),
        }
        for s in args.sets:
            opts = option_set(s)
            tracers[s] = Tracer(lambda o=opts: bsplab.build(
                tris, "kd", threads=args.threads, build_quality="fast", **o))
        times = paired_rounds(tracers, args.rounds)
        exact_sah = times.results["exact"].stats["sah_cost"]
        print(f"{name} ({len(tris)} triangles, {args.threads} threads, {args.rounds} rounds): "
              f"embree {times.median('embree'):.3f} s, exact {times.median('exact'):.3f} s "
              f"= {times.ratio('exact', 'embree'):.2f}x embree, SAH {exact_sah:.2f}")
        for s in args.sets:
            sah = times.results[s].stats["sah_cost"]
            print(f"  fast {s:40s} {times.median(s):.3f} s = {times.ratio(s, 'embree'):.2f}x "
                  f"embree, {times.ratio(s, 'exact'):.2f}x exact; SAH {sah:.2f} "
                  f"({100 * (sah / exact_sah - 1):+.1f} %)", flush=True)


if __name__ == "__main__":
    main()

"""Which BVH build options trace fastest against Embree? Builds the BVH of
each scene under each option set and traces one workload's rays in paired
rounds with Embree (bsplab.lab.timing, one thread, hits only). Prints, per
scene, workload and option set: the median of the per-round time ratios to
Embree's, steps, wide nodes and triangle tests per ray, the SAH cost and the
bytes per triangle.

Run: .venv/bin/python core/tools/bvh_options_experiment.py \\
        sponza_dabrovic:primary bunny:random -- default bins=16,intersect_cost=1.5

Cases are scene:workload (primary: 256 x 256 camera rays in tile order;
random: 65,536 rays from the scene box in all directions); option sets are
`default` or comma-separated name=value pairs. The experiment behind the
BVH's defaults in docs/performance.md ("8 wide"); its table there was
measured before bins_for (bvh_build.cpp), when `bins` was the count of
every node."""
import sys

import numpy as np

import bsplab
from bsplab import io, oracle, workloads
from bsplab.lab.timing import Tracer, paired_rounds

ROUNDS = 7
SIDE = 256
RANDOM_RAYS = 65536
INT_OPTIONS = ("bins", "leaf_size", "max_depth")


def option_set(text: str) -> dict:
    if text == "default":
        return {}
    out = {}
    for pair in text.split(","):
        name, value = pair.split("=")
        out[name] = int(value) if name in INT_OPTIONS else float(value)
    return out


def main(argv: list[str]) -> None:
    if "--" not in argv:
        raise SystemExit(__doc__)
    cut = argv.index("--")
    cases, sets = argv[:cut], argv[cut + 1:] or ["default"]
    paths = {p.stem: p for p in workloads.shared_scene_paths()}
    for case in cases:
        scene, workload = case.split(":")
        tris = io.load_mesh(paths[scene])
        if workload == "random":
            o, d = workloads.random_rays(tris, RANDOM_RAYS)
        else:
            o, d = workloads.primary_rays(tris, SIDE, SIDE, tiles=True)
        embree = oracle.EmbreeTracer(tris)
        tracers = {"embree": Tracer(lambda: embree.intersect(o, d), lambda: embree.last_seconds)}
        counts = {}
        for name in sets:
            tree = bsplab.build(tris, "bvh", **option_set(name))
            h = tree.intersect(o, d, threads=1)
            width = tree.stats["wide_width"]
            counts[name] = (h["steps"].mean(), (h["box_tests"].mean() - 1) / width,
                            h["tests"].mean(), tree.stats["sah_cost"],
                            tree.stats["bytes"] / len(tris))
            tracers[name] = Tracer(lambda tree=tree: tree.intersect(o, d, threads=1,
                                                                    counters=False))
        times = paired_rounds(tracers, ROUNDS)
        reference = np.array(times.seconds["embree"])
        for name in sets:
            ratio = float(np.median(np.array(times.seconds[name]) / reference))
            steps, wide, tests, sah, per_tri = counts[name]
            print(f"{scene:16s} {workload:7s} {name:30s} time / Embree {ratio:.3f}  "
                  f"steps {steps:5.1f}  wide nodes {wide:5.1f}  tests {tests:5.2f}  "
                  f"SAH {sah:.1f}  B/tri {per_tri:.0f}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])

"""Does the fitted cost model (K_i 1.4, general 1.4) make ^Kd trees faster
than the defaults (K_i 1.5, general 2)? Builds kd and bsp_wn+kd / bsp_cn+kd at
K = 8 under each cost set and traces primary and AO rays in paired rounds
against the default kd tree (bsplab.lab.timing). Prints, per scene, tree and
workload: the median of the per-round time ratios to kd, and steps, general
steps and tests per ray.
Run: .venv/bin/python core/tools/cost_defaults_experiment.py [scene ...]
(the experiment behind the refitted defaults in docs/algorithms.md)."""
import sys
import time

import numpy as np

import bsplab
from bsplab import io, workloads
from bsplab.lab.timing import Tracer, paired_rounds

COSTS = {"default": {}, "gen1.4": {"general_cost": 1.4},
         "fit": {"intersect_cost": 1.4, "general_cost": 1.4}}
ROUNDS = 9
SIDE = 200
names = sys.argv[1:] or ["bunny", "sponza_dabrovic", "conference", "dragon_res2"]
paths = {p.stem: p for p in workloads.shared_scene_paths()}
for scene in names:
    tris = io.load_mesh(paths[scene])
    trees = {"kd": bsplab.build(tris, "kd"),
             "kd fit": bsplab.build(tris, "kd", intersect_cost=1.4)}
    for method in ("bsp_wn+kd", "bsp_cn+kd"):
        for label, opts in COSTS.items():
            start = time.perf_counter()
            trees[f"{method} {label}"] = bsplab.build(tris, method, k=8, **opts)
            print(f"# {scene} {method} {label} built in {time.perf_counter() - start:.1f} s",
                  file=sys.stderr, flush=True)
    o, d = workloads.primary_rays(tris, SIDE, SIDE)
    hits = trees["kd"].intersect(o, d, counters=False)
    ao = workloads.ambient_occlusion_rays(tris, o, d, hits)
    for family, (ro, rd) in {"primary": (o, d), "ao": ao}.items():
        tracers = {name: Tracer(lambda t=t: t.intersect(ro, rd, counters=False, threads=1))
                   for name, t in trees.items()}
        times = paired_rounds(tracers, ROUNDS)
        for name, t in trees.items():
            c = t.intersect(ro, rd)
            print(f"{scene}\t{family}\t{name}\t{times.ratio(name, 'kd'):.3f}\t"
                  f"{c['steps'].mean():.2f}\t{c['general_steps'].mean():.2f}\t"
                  f"{c['tests'].mean():.2f}\t{t.stats['sah_cost']:.2f}", flush=True)

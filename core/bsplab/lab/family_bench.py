"""`python -m bsplab bench-families`: per method and ray family, what a ray
costs (steps and tests per ray, the hits-only time against Embree's in
paired rounds) and whether every path gives Embree's answer: leaks (a miss
or a farther hit where Embree hits, oracle.leaks), unexplained disagreements
(oracle.compare), and rays whose t or prim differ between the paths (leaf
culling on and off, counters on and off, packets, one and two threads).

Cheap by design (a few thousand rays per family, three rounds): it is the
robustness issue's check that no family falls off a cliff - rays in split
planes and from a million scene sizes away cost about what camera rays
cost - not a speed report."""

from __future__ import annotations

import numpy as np

from .. import oracle, ray_families
from .timing import Tracer, paired_rounds

# The paths every family is traced on, beside the counting path with
# culling (the one whose steps and tests the table shows).
PATHS = {
    "no cull": dict(cull=False),
    "hits only": dict(counters=False),
    "hits only, no cull": dict(counters=False, cull=False),
    "packets": dict(counters=False, cull=False, packets=True),
    "2 threads": dict(threads=2),
}


def path_differences(tree, o, d, tmax, reference: dict) -> dict[str, int]:
    """Per path of PATHS: how many rays' t or prim differ from `reference`
    (the counting path with culling, one thread)."""
    out = {}
    for name, opts in PATHS.items():
        h = tree.intersect(o, d, tmax=tmax, **{"threads": 1, **opts})
        same = (h["prim"] == reference["prim"]) & (
            (h["t"] == reference["t"]) | (np.isinf(h["t"]) & np.isinf(reference["t"])))
        out[name] = int((~same).sum())
    return out


def family_rows(tree, embree, tris, families: dict, rounds: int) -> list[dict]:
    """One row per family: counts per ray, Embree's answers checked, the
    paths compared, the hits-only time over Embree's."""
    rows = []
    for name, (o, d, tmax) in families.items():
        ref = embree.intersect(o, d, tmax=tmax)
        h = tree.intersect(o, d, tmax=tmax, threads=1)
        etmax = None if np.isinf(tmax).all() else tmax
        times = paired_rounds({
            "ours": Tracer(lambda: tree.intersect(o, d, tmax=tmax, threads=1, counters=False)),
            "embree": Tracer(lambda: embree.intersect(o, d, tmax=etmax),
                             lambda: embree.last_seconds)}, rounds)
        c = oracle.compare(h, ref, triangles=tris, origins=o, directions=d, tmax=tmax)
        rows.append({
            "family": name, "rays": len(o),
            "steps": float(h["steps"].mean()), "tests": float(h["tests"].mean()),
            "leaks": len(oracle.leaks(h, ref, triangles=tris, origins=o, directions=d,
                                      tmax=tmax)),
            "unexplained": len(c["unexplained"]),
            "paths": path_differences(tree, o, d, tmax, h),
            "vs_embree": times.ratio("ours", "embree"),
        })
    return rows


def run(scenes: list[str], methods: list[str], count: int, k: int | None = None,
        rounds: int = 3, seed: int = 0, out=print) -> list[dict]:
    """Prints one line per scene, method and family; returns the rows."""
    import bsplab
    from ..scenes import load

    table = bsplab.methods()
    rows = []
    for scene in scenes:
        tris = load(scene)
        embree = oracle.EmbreeTracer(tris)
        families = {n: ray_families.family(n, tris, count, seed) for n in ray_families.FAMILIES}
        out(f"\n{scene}: {len(tris):,} triangles, {count:,} rays per family")
        out(f"{'method':<14}{'family':<24}{'steps':>9}{'tests':>9}{'leaks':>7}"
            f"{'unexpl':>8}{'paths!=':>8}{'x Embree':>10}")
        for method in methods:
            opts = {}
            if k is not None and "k" in table[method]["params"]:
                opts["k"] = max(k, table[method]["min_k"])
            tree = bsplab.build(tris, method=method, **opts)
            for r in family_rows(tree, embree, tris, families, rounds):
                r.update(scene=scene, method=method)
                rows.append(r)
                out(f"{method:<14}{r['family']:<24}{r['steps']:>9.1f}{r['tests']:>9.1f}"
                    f"{r['leaks']:>7}{r['unexplained']:>8}{sum(r['paths'].values()):>8}"
                    f"{r['vs_embree']:>10.2f}")
    return rows

"""`python -m bsplab bench-families`: per method and ray family, what a ray
costs (steps and tests per ray, the hits-only time against Embree's in
paired rounds) and whether every path gives Embree's answer: leaks (a miss
or a farther hit where Embree hits, oracle.leaks), unexplained disagreements
(oracle.compare), and rays whose t or prim differ between the paths (leaf
culling on and off, counters on and off, packets, one and two threads).

Cheap by design (a few thousand rays per family, three rounds): it is the
robustness issue's check that no family falls off a cliff - rays in split
planes and from a million scene sizes away cost about what camera rays
cost - not a speed report. Beside the camera rays, each family's steps are
compared with those of the same rays moved off by MOVE (of the scene's
size) across their direction ("x moved"): what lying exactly in a plane,
on an edge or on a vertex costs over passing next to it, which is the
cliff; a family aimed into the densest part of a scene costs more than
camera rays whether or not it lies in a plane.

Beside the families of ray_families.FAMILIES: rays from FAR_SIZES scene
sizes away ("far 1e+07": ray_families.from_distance), and the scene itself
moved far from the origin ("shifted 1e+06": ray_families.shifted, the
camera rays from outside on the moved copy, its tree built there), whose
steps should be the origin copy's (the trees' local frame)."""

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


# How far "x moved" moves each ray off its line, in scene sizes: far below
# any feature of the generated scenes, far above the crossing tolerances.
MOVE = 1e-4


def moved_rays(o: np.ndarray, d: np.ndarray, size: float, seed: int = 0) -> np.ndarray:
    """The origins moved by MOVE * size in a random direction across each
    ray (perpendicular to it): the same rays, off every plane, edge and
    vertex they lay in or passed through."""
    rng = np.random.default_rng(seed)
    r = rng.normal(size=o.shape)
    d64 = d.astype(np.float64)
    r -= (np.einsum("ij,ij->i", r, d64) / np.einsum("ij,ij->i", d64, d64))[:, None] * d64
    r /= np.maximum(np.linalg.norm(r, axis=1, keepdims=True), 1e-300)
    return (o.astype(np.float64) + MOVE * size * r).astype(np.float32)


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


# The extra far families' distances, in scene sizes (far_away is 1e6), and
# the shifts of the shifted rows, in the scene's units.
FAR_SIZES = (1e3, 1e7)
SHIFTS = (1e3, 1e6, 1e7)
SHIFTED_FAMILY = "outside_camera"


def far_families(tris, count: int, seed: int) -> dict:
    """The rays from FAR_SIZES scene sizes away, as family name -> rays."""
    out = {}
    for sizes in FAR_SIZES:
        rng = np.random.default_rng([seed, int(np.log10(sizes))])
        o, d = ray_families.from_distance(tris, count, rng, sizes)
        out[f"far {sizes:.0e}"] = (o, d, np.full(len(o), np.inf, np.float32))
    return out


def shifted_rows(build, tris, count: int, rounds: int, seed: int) -> list[dict]:
    """family_rows of SHIFTED_FAMILY on the scene moved by each of SHIFTS,
    with a tree `build(triangles)` of the moved scene."""
    rows = []
    for shift in SHIFTS:
        _, (moved, o), d, tmax = ray_families.shifted(SHIFTED_FAMILY, tris, count, shift, seed)
        rows += family_rows(build(moved), oracle.EmbreeTracer(moved), moved,
                            {f"shifted {shift:.0e}": (o, d, tmax)}, rounds)
    return rows


def family_rows(tree, embree, tris, families: dict, rounds: int) -> list[dict]:
    """One row per family: counts per ray, Embree's answers checked, the
    paths compared, the hits-only time over Embree's."""
    rows = []
    size = float(np.linalg.norm(tris.reshape(-1, 3).max(0) - tris.reshape(-1, 3).min(0)))
    for name, (o, d, tmax) in families.items():
        ref = embree.intersect(o, d, tmax=tmax)
        h = tree.intersect(o, d, tmax=tmax, threads=1)
        moved = tree.intersect(moved_rays(o, d, size), d, tmax=tmax, threads=1)
        etmax = None if np.isinf(tmax).all() else tmax
        times = paired_rounds({
            "ours": Tracer(lambda: tree.intersect(o, d, tmax=tmax, threads=1, counters=False)),
            "embree": Tracer(lambda: embree.intersect(o, d, tmax=etmax),
                             lambda: embree.last_seconds)}, rounds)
        c = oracle.compare(h, ref, triangles=tris, origins=o, directions=d, tmax=tmax)
        rows.append({
            "family": name, "rays": len(o),
            "steps": float(h["steps"].mean()), "tests": float(h["tests"].mean()),
            "x_moved": float(h["steps"].mean() / max(moved["steps"].mean(), 1e-9)),
            "leaks": len(oracle.leaks(h, ref, triangles=tris, origins=o, directions=d,
                                      tmax=tmax)),
            "unexplained": len(c["failing"]),
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
        families.update(far_families(tris, count, seed))
        out(f"\n{scene}: {len(tris):,} triangles, {count:,} rays per family")
        out(f"{'method':<14}{'family':<24}{'steps':>9}{'x moved':>9}{'tests':>9}{'leaks':>7}"
            f"{'unexpl':>8}{'paths!=':>8}{'x Embree':>10}")
        for method in methods:
            opts = {}
            if k is not None and "k" in table[method]["params"]:
                opts["k"] = max(k, table[method]["min_k"])
            tree = bsplab.build(tris, method=method, **opts)
            for r in family_rows(tree, embree, tris, families, rounds) + shifted_rows(
                    lambda t: bsplab.build(t, method=method, **opts), tris, count, rounds, seed):
                r.update(scene=scene, method=method)
                rows.append(r)
                out(f"{method:<14}{r['family']:<24}{r['steps']:>9.1f}{r['x_moved']:>9.2f}"
                    f"{r['tests']:>9.1f}"
                    f"{r['leaks']:>7}{r['unexplained']:>8}{sum(r['paths'].values()):>8}"
                    f"{r['vs_embree']:>10.2f}")
    return rows

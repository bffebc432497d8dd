"""Calibrates the SAH costs to this machine: traces the same rays through
trees of different shapes and fits the time per ray as

    seconds = a + K_kd * kd_steps + K_gen * general_steps + K_i * tests

by least squares (kd_steps counts leaves too: both are cheap fetches). The
ratios K_i / K_kd and K_gen / K_kd are what the builders' costs mean."""

from __future__ import annotations

import time

import numpy as np

from . import build, workloads
from .bench import load


def measure(tree, o, d, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        tree.intersect(o, d, threads=1)
        best = min(best, time.perf_counter() - start)
    return best


def run(scene_names=("spheres", "room"), repeats: int = 3, log=print) -> dict:
    rows, times = [], []
    configs = [("kd", {}), ("kd", {"intersect_cost": 0.5}), ("kd", {"intersect_cost": 6.0}),
               ("kd", {"leaf_size": 16, "intersect_cost": 0.3}), ("rbsp", {"k": 7}),
               ("bsp_random", {"k": 4}), ("bsp_wn+", {"k": 6})]
    for name in scene_names:
        tris = load(name)
        o, d = workloads.random_rays(tris, 60_000, seed=5)
        po, pd = workloads.primary_rays(tris, 200, 200)
        for method, opts in configs:
            tree = build(tris, method=method, **opts)
            for oo, dd in ((o, d), (po, pd)):
                h = tree.intersect(oo, dd, threads=1)
                n = len(oo)
                gen = h["general_steps"].sum() / n
                kd = h["steps"].sum() / n - gen
                tests = h["tests"].sum() / n
                rows.append([1.0, kd, gen, tests])
                times.append(measure(tree, oo, dd, repeats) / n)
            log(f"  {name:8} {method:11} {opts}: done")
    A, y = np.array(rows), np.array(times)
    # Relative least squares: cheap and expensive workloads count alike.
    coef, *_ = np.linalg.lstsq(A / y[:, None], np.ones_like(y), rcond=None)
    fit = A @ coef
    r2 = 1 - ((y - fit) ** 2).sum() / ((y - y.mean()) ** 2).sum()
    base, k_kd, k_gen, k_i = coef
    return {"ns_per_ray": base * 1e9, "ns_kd_step": k_kd * 1e9, "ns_general_step": k_gen * 1e9,
            "ns_test": k_i * 1e9, "intersect_per_kd": k_i / k_kd,
            "general_per_kd": k_gen / k_kd, "r2": r2, "samples": len(y)}

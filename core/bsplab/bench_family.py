"""The BSP-family benchmark: every method at K = 3..10 against our kd-tree
and Embree on the same rays in the same run (primary rays and incoherent
ambient-occlusion rays), with build times and the machine-independent
counters. Times are the best of the repetitions; kd and Embree are measured
before and after each scene's methods and the best is used."""

from __future__ import annotations

import csv
import platform
import time
from pathlib import Path

import numpy as np

from . import build, oracle, workloads
from .bench import load
from .method_table import METHODS


def best_trace(tree, o, d, repeats):
    best, hits = np.inf, None
    for _ in range(repeats):
        start = time.perf_counter()
        hits = tree.intersect(o, d, threads=1)
        best = min(best, time.perf_counter() - start)
    return best, hits


def method_ks(method: str, ks: list[int]) -> list[int | None]:
    m = METHODS[method]
    if "k" not in m.params:
        return [None]
    out = [k for k in ks if k >= m.min_k]
    if method in ("rbsp", "rbsp+kd"):
        out = [k for k in out]  # auto: k-DOP sets at 3, 7, 9; golden spiral otherwise
    return out


def run(scene_names, methods, ks, repeats=2, side=384, ao_samples=1, log=print) -> list[dict]:
    rows = []
    for name in scene_names:
        tris = load(name)
        emb = oracle.EmbreeTracer(tris)
        po, pd = workloads.primary_rays(tris, side, side)
        kd = build(tris, method="kd")
        _, ph = best_trace(kd, po, pd, 1)
        ao, ad = workloads.ambient_occlusion_rays(tris, po, pd, ph, samples=ao_samples)
        loads = {"primary": (po, pd), "ao": (ao, ad)}
        refs = {w: emb.intersect(*loads[w]) for w in loads}

        def baseline():
            t = {}
            for w, (o, d) in loads.items():
                t[("kd", w)], _ = best_trace(kd, o, d, repeats)
                e = np.inf
                for _ in range(repeats):
                    emb.intersect(o, d)
                    e = min(e, emb.last_seconds)
                t[("embree", w)] = e
            return t

        base = baseline()
        kd_counts = {}
        for w, (o, d) in loads.items():
            h = kd.intersect(o, d, threads=1)
            kd_counts[w] = (float(h["steps"].mean()), float(h["tests"].mean()))
        kd_build = min(build(tris, method="kd").stats["build_seconds"] for _ in range(2))
        scene_rows = []
        for method in methods:
            for k in method_ks(method, ks):
                opts = {} if k is None else {"k": k}
                tree = build(tris, method=method, **opts)
                s = tree.stats
                row = {"scene": name, "triangles": len(tris), "method": method,
                       "k": "" if k is None else k, "build_s": s["build_seconds"],
                       "kd_nodes": s["kd_nodes"], "general_nodes": s["general_nodes"],
                       "leaves": s["leaves"], "refs_per_tri": s["duplication"],
                       "bytes": s["bytes"], "sah": s["sah_cost"]}
                for w, (o, d) in loads.items():
                    sec, hits = best_trace(tree, o, d, repeats)
                    c = oracle.compare(hits, refs[w], triangles=tris, origins=o, directions=d)
                    row[f"{w}_s"] = sec
                    row[f"{w}_steps"] = float(hits["steps"].mean())
                    row[f"{w}_general_steps"] = float(hits["general_steps"].mean())
                    row[f"{w}_tests"] = float(hits["tests"].mean())
                    row[f"{w}_unexplained"] = len(c["unexplained"])
                scene_rows.append(row)
                log(f"{name:>16} {method:>14} k={row['k']!s:>2}: build {row['build_s']:6.2f}s "
                    f"primary {row['primary_s'] * 1e3:7.1f} ms  ao {row['ao_s'] * 1e3:7.1f} ms")
                del tree
        after = baseline()
        for key in base:
            base[key] = min(base[key], after[key])
        for row in scene_rows:
            row["rays_primary"], row["rays_ao"] = len(po), len(ao)
            row["kd_build_s"] = kd_build
            row["build_vs_kd"] = row["build_s"] / kd_build
            for w in loads:
                row[f"kd_{w}_s"] = base[("kd", w)]
                row[f"embree_{w}_s"] = base[("embree", w)]
                row[f"{w}_vs_kd"] = row[f"{w}_s"] / base[("kd", w)]
                row[f"{w}_vs_embree"] = row[f"{w}_s"] / base[("embree", w)]
                row[f"kd_{w}_steps"], row[f"kd_{w}_tests"] = kd_counts[w]
        rows += scene_rows
    return rows


def write_csv(rows: list[dict], path: Path) -> None:
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def markdown(rows: list[dict], command: str) -> str:
    out = [
        "# Benchmark: the BSP family against kd and Embree",
        "",
        f"Command: `{command}`",
        "",
        f"Machine: {platform.machine()}, Python {platform.python_version()}; one thread for "
        "every trace (Embree through embreex is single-threaded). Times are ratios measured "
        "in the same run: `x kd` is the method's time over our kd-tree's (below 1 is faster), "
        "`x Embree` over Embree's. Build `x kd` is build time over the kd build. Steps and "
        "tests are per ray (exact, machine-independent); `gen` are the general-node steps "
        "among them. AO rays: one cosine-weighted ray from every primary hit.",
        "",
    ]
    for scene in dict.fromkeys(r["scene"] for r in rows):
        rs = [r for r in rows if r["scene"] == scene]
        r0 = rs[0]
        out += [
            f"## {scene} ({r0['triangles']:,} triangles)",
            "",
            f"kd build {r0['kd_build_s']:.2f} s; kd primary {r0['kd_primary_s'] * 1e3:.1f} ms "
            f"and AO {r0['kd_ao_s'] * 1e3:.1f} ms for {r0['rays_primary']:,} / "
            f"{r0['rays_ao']:,} rays; Embree {r0['embree_primary_s'] * 1e3:.1f} / "
            f"{r0['embree_ao_s'] * 1e3:.1f} ms. kd steps / tests per ray: primary "
            f"{r0['kd_primary_steps']:.1f} / {r0['kd_primary_tests']:.2f}, AO "
            f"{r0['kd_ao_steps']:.1f} / {r0['kd_ao_tests']:.2f}.",
            "",
            "| method | K | build s | build x kd | kd / general nodes | primary x kd | "
            "primary x Embree | steps (gen) | tests | AO x kd | AO x Embree | steps (gen) | "
            "tests | wrong hits |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        ]
        for r in rs:
            out.append(
                f"| {r['method']} | {r['k']} | {r['build_s']:.2f} | {r['build_vs_kd']:.1f} | "
                f"{r['kd_nodes']:,} / {r['general_nodes']:,} | **{r['primary_vs_kd']:.2f}** | "
                f"{r['primary_vs_embree']:.2f} | {r['primary_steps']:.1f} "
                f"({r['primary_general_steps']:.1f}) | {r['primary_tests']:.2f} | "
                f"**{r['ao_vs_kd']:.2f}** | {r['ao_vs_embree']:.2f} | {r['ao_steps']:.1f} "
                f"({r['ao_general_steps']:.1f}) | {r['ao_tests']:.2f} | "
                f"{r['primary_unexplained'] + r['ao_unexplained']} |")
        out.append("")
    return "\n".join(out)

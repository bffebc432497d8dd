"""The leaf-culling benchmark: per scene and method, the share of triangle
tests the segment-box check removes and the trace time with culling on
against off, on the same tree and rays in the same run (one thread), for
both box kinds. A kd-tree with large leaves (intersect_cost 0.3, the kind of
tree the source thesis culled in) shows where culling pays most."""

from __future__ import annotations

import time

import numpy as np

from . import build, workloads
from .bench import load

from .method_table import METHODS

# kd twice (our SAH defaults, and large leaves like the source's trees), then
# every other method at its default K.
CONFIGS = [("kd", {}), ("kd", {"intersect_cost": 0.3})] + [(m, {}) for m in METHODS if m != "kd"]


def trace_time(tree, o, d, cull, repeats):
    best, hits = np.inf, None
    for _ in range(repeats):
        start = time.perf_counter()
        hits = tree.intersect(o, d, threads=1, cull=cull)
        best = min(best, time.perf_counter() - start)
    return best, hits


def run(scene_names, repeats=3, side=384, log=print, boxes_kinds=("triangle", "clipped")) -> list[dict]:
    rows = []
    for name in scene_names:
        tris = load(name)
        po, pd = workloads.primary_rays(tris, side, side)
        kd = build(tris)
        ao, ad = workloads.ambient_occlusion_rays(tris, po, pd, kd.intersect(po, pd))
        for method, opts in CONFIGS:
            for boxes in boxes_kinds:
                tree = build(tris, method=method, leaf_boxes=boxes, **opts)
                row = {"scene": name, "method": method, "options": opts, "boxes": boxes,
                       "box_bytes": tree.stats["box_bytes"], "bytes": tree.stats["bytes"]}
                for w, (o, d) in (("primary", (po, pd)), ("ao", (ao, ad))):
                    t_off = t_on = np.inf
                    for _ in range(repeats):  # interleaved against drift
                        s, off = trace_time(tree, o, d, False, 1)
                        t_off = min(t_off, s)
                        s, on = trace_time(tree, o, d, True, 1)
                        t_on = min(t_on, s)
                    assert np.array_equal(on["t"], off["t"])
                    tests_off = float(off["tests"].mean())
                    row[w] = {"tests_off": tests_off, "tests_on": float(on["tests"].mean()),
                              "culled": float(on["culled"].mean()),
                              "fewer_tests": 1 - on["tests"].sum() / max(off["tests"].sum(), 1),
                              "time_on_vs_off": t_on / t_off}
                rows.append(row)
                p, a = row["primary"], row["ao"]
                log(f"{name:>16} {method:>10} {opts!s:>24} {boxes:>8}: primary "
                    f"{p['fewer_tests'] * 100:5.1f}% fewer tests, time x{p['time_on_vs_off']:.2f}; "
                    f"AO {a['fewer_tests'] * 100:5.1f}%, x{a['time_on_vs_off']:.2f}")
    return rows


def markdown(rows: list[dict], command: str) -> str:
    out = [
        "# Benchmark: leaf culling with the ray segment's box",
        "",
        f"Command: `{command}`",
        "",
        "Same tree, same rays, one thread, culling off and on interleaved (best of the "
        "repetitions). `fewer tests` is the share of ray-triangle tests culling removes; "
        "`time on/off` below 1 means culling pays. The source thesis (seed 002) reports "
        "80–90 % fewer tests and up to 2x faster tracing on kd-trees whose leaves hold many "
        "triangles; our default SAH trees hold 2–5 per leaf and a mailbox already skips "
        "repeats, so the `intersect_cost 0.3` rows (larger leaves) are the comparable ones.",
        "",
        "| scene | method | options | boxes | box MiB | primary: tests off → on | fewer "
        "tests | time on/off | AO: tests off → on | fewer tests | time on/off |",
        "|---|---|---|---|---:|---|---:|---:|---|---:|---:|",
    ]
    for r in rows:
        p, a = r["primary"], r["ao"]
        opts = ", ".join(f"{k} {v}" for k, v in r["options"].items()) or "defaults"
        out.append(
            f"| {r['scene']} | {r['method']} | {opts} | {r['boxes']} | "
            f"{r['box_bytes'] / 2**20:.1f} | {p['tests_off']:.2f} → {p['tests_on']:.2f} | "
            f"{p['fewer_tests'] * 100:.0f} % | **{p['time_on_vs_off']:.2f}** | "
            f"{a['tests_off']:.2f} → {a['tests_on']:.2f} | {a['fewer_tests'] * 100:.0f} % | "
            f"**{a['time_on_vs_off']:.2f}** |")
    return "\n".join(out) + "\n"

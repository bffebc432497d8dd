"""The benchmark: build time and ray throughput of each method against
Embree (embreex) on the same rays in the same process run.

Timings on a shared machine drift, so every figure is a ratio to Embree
measured right next to it, and each is the best of a few interleaved
repetitions. Counters (steps, tests) are exact and machine-independent."""

from __future__ import annotations

import platform
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import build, io, oracle, scenes, workloads


@dataclass
class Workload:
    name: str
    origins: np.ndarray
    directions: np.ndarray


@dataclass
class Row:
    scene: str
    triangles: int
    method: str
    build_seconds: float
    embree_build_seconds: float
    stats: dict
    results: dict = field(default_factory=dict)  # workload -> figures


def load(name: str) -> np.ndarray:
    if name in scenes.NAMES + scenes.PROBE_NAMES:
        return scenes.generate(name)
    path = Path(name)
    if not path.exists():
        d = workloads.shared_scenes_dir()
        if d is None or not (d / f"{name}.ply").exists():
            raise FileNotFoundError(f"no scene {name!r}: not a generated scene "
                                    f"({', '.join(scenes.NAMES)}), a file, or a shared mesh")
        path = d / f"{name}.ply"
    return io.load_mesh(path)


def make_workloads(tris: np.ndarray, primary_side: int, random_count: int) -> list[Workload]:
    o, d = workloads.primary_rays(tris, primary_side, primary_side)
    ro, rd = workloads.random_rays(tris, random_count, seed=1)
    return [Workload("primary", o, d), Workload("random", ro, rd)]


def best_time(fn, repeats: int) -> tuple[float, object]:
    best, out = np.inf, None
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - start)
    return best, out


def measure(tris: np.ndarray, tree, embree: oracle.EmbreeTracer, w: Workload,
            repeats: int) -> dict:
    """Interleaves Embree and our runs so drift hits both alike."""
    t_e, t_1, t_2 = np.inf, np.inf, np.inf
    ref = ours = None
    for _ in range(repeats):
        ref = embree.intersect(w.origins, w.directions)
        t_e = min(t_e, embree.last_seconds)
        s, ours = best_time(lambda: tree.intersect(w.origins, w.directions, threads=1), 1)
        t_1 = min(t_1, s)
        s, _ = best_time(lambda: tree.intersect(w.origins, w.directions, threads=2), 1)
        t_2 = min(t_2, s)
    c = oracle.compare(ours, ref, triangles=tris, origins=w.origins, directions=w.directions)
    n = len(w.origins)
    return {
        "rays": n,
        "embree_mrays": n / t_e / 1e6,
        "mrays_1t": n / t_1 / 1e6,
        "mrays_2t": n / t_2 / 1e6,
        "speed_1t": t_e / t_1,  # > 1: faster than Embree
        "speed_2t": t_e / t_2,
        "mean_steps": float(ours["steps"].mean()),
        "mean_tests": float(ours["tests"].mean()),
        "agreement": c["agreement"],
        "grazing": c["grazing"],
        "unexplained": len(c["unexplained"]),
    }


def run(scene_names: list[str], method_names: list[str], primary_side: int = 512,
        random_count: int = 250_000, repeats: int = 3, log=print) -> list[Row]:
    rows = []
    for name in scene_names:
        tris = load(name)
        embree_build, embree = best_time(lambda: oracle.EmbreeTracer(tris), 1)
        loads = make_workloads(tris, primary_side, random_count)
        for method in method_names:
            build_s = np.inf
            tree = None
            for _ in range(repeats):
                tree = build(tris, method=method)
                build_s = min(build_s, tree.stats["build_seconds"])
            row = Row(name, len(tris), method, build_s, embree.build_seconds, tree.stats)
            for w in loads:
                row.results[w.name] = measure(tris, tree, embree, w, repeats)
            rows.append(row)
            log(summary_line(row))
            del tree
    return rows


def summary_line(r: Row) -> str:
    p, q = r.results["primary"], r.results["random"]
    line = (f"{r.scene:>16} {r.method:>6}: build {r.build_seconds:6.2f}s  "
            f"primary {p['speed_1t']:.2f}x Embree (1 thread), {p['speed_2t']:.2f}x (2)  "
            f"random {q['speed_1t']:.2f}x / {q['speed_2t']:.2f}x  "
            f"agree {min(p['agreement'], q['agreement']) * 100:.4f}%")
    return "\n".join([line] + [f"{'':>16} WARNING: {w}" for w in r.stats.get("warnings", ())])


def markdown(rows: list[Row], command: str) -> str:
    import embreex  # noqa: F401  (version for the record)
    lines = [
        "# Benchmark: BSP Lab trees vs Embree",
        "",
        f"Command: `{command}`",
        "",
        f"Machine: {platform.machine()}, {platform.processor() or 'cpu'}, "
        f"Python {platform.python_version()}, numpy {np.__version__}, "
        f"embreex {getattr(__import__('embreex'), '__version__', '?')}.",
        "",
        "Speed is Embree's time divided by ours on the same rays in the same run "
        "(> 1 means faster than Embree); best of the repetitions, interleaved. "
        "`embreex` traces one ray at a time on one thread, so the 2-thread column is "
        "our 2-thread time against Embree's single thread. Mray/s are absolute and drift "
        "with the machine's load; the ratios are what to compare.",
        "",
        "## Build",
        "",
        "| scene | triangles | method | build s | Embree build s | nodes | leaves | "
        "depth | refs/tri | tris/leaf | MiB | SAH |",
        "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        s = r.stats
        lines.append(
            f"| {r.scene} | {r.triangles:,} | {r.method} | {r.build_seconds:.2f} | "
            f"{r.embree_build_seconds:.2f} | {s['nodes']:,} | {s['leaves']:,} | "
            f"{s['max_depth']} | {s['duplication']:.2f} | {s['mean_leaf_size']:.2f} | "
            f"{s['bytes'] / 2**20:.1f} | {s['sah_cost']:.1f} |")
    warned = [(r, w) for r in rows for w in r.stats.get("warnings", ())]
    if warned:
        lines.append("")
        lines += [f"**Warning** ({r.scene}, {r.method}): {w}." for r, w in warned]
    for wname in ("primary", "random"):
        lines += [
            "",
            f"## {wname.capitalize()} rays",
            "",
            "| scene | method | rays | Embree Mray/s | ours 1t Mray/s | speed 1t | "
            "ours 2t Mray/s | speed 2t | steps/ray | tests/ray | agreement | grazing |",
            "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        ]
        for r in rows:
            x = r.results[wname]
            lines.append(
                f"| {r.scene} | {r.method} | {x['rays']:,} | {x['embree_mrays']:.2f} | "
                f"{x['mrays_1t']:.2f} | **{x['speed_1t']:.2f}** | {x['mrays_2t']:.2f} | "
                f"{x['speed_2t']:.2f} | {x['mean_steps']:.1f} | {x['mean_tests']:.2f} | "
                f"{x['agreement'] * 100:.4f}% | {x['grazing']} |")
    return "\n".join(lines) + "\n"


def default_scenes() -> list[str]:
    shared = [p.stem for p in workloads.shared_scene_paths()]
    return list(scenes.NAMES) + shared


def default_methods() -> list[str]:
    """kd against Embree; bench-family compares the rest of the family."""
    return ["kd"]

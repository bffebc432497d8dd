"""The build-time benchmark, `python -m bsplab bench-build`: the kd build on
one thread and on all of them against Embree's BVH build of the same
triangles, in paired rounds (`timing.paired_rounds`: the three builds one
after the other in a rotating order, so a drifting machine slows all three
alike), each figure the median over the rounds. Every time is the wall time
of the whole call: `bsplab.build` with its input checks, and the
`EmbreeTracer` constructor, which builds Embree's BVH."""

from __future__ import annotations

import os

import bsplab

from .. import oracle, scenes
from .timing import Tracer, paired_rounds

# The shared meshes the target names (docs/benchmark.md's scenes).
DEFAULT_SCENES = ["bunny", "conference", "dragon_res2", "lost_empire", "sibenik",
                  "sponza_dabrovic", "sportscar"]


def build_row(name: str, triangles, rounds: int, threads: int) -> dict:
    """One scene's paired build times (seconds, medians), their ratios to
    Embree's (medians of the per-round ratios) and the kd-tree's SAH cost."""
    many = f"kd_{threads}"
    tracers = {
        "kd_1": Tracer(lambda: bsplab.build(triangles, "kd", threads=1)),
        many: Tracer(lambda: bsplab.build(triangles, "kd", threads=threads)),
        "embree": Tracer(lambda: oracle.EmbreeTracer(triangles)),
    }
    times = paired_rounds(tracers, rounds)
    stats = times.results["kd_1"].stats
    return {
        "scene": name,
        "triangles": len(triangles),
        "threads": threads,
        "kd_1_s": times.median("kd_1"),
        "kd_n_s": times.median(many),
        "embree_s": times.median("embree"),
        "kd_1_per_embree": times.ratio("kd_1", "embree"),
        "kd_n_per_embree": times.ratio(many, "embree"),
        "sah_cost": stats["sah_cost"],
        "rounds": rounds,
    }


def build_markdown(rows: list[dict], command: str) -> str:
    threads = rows[0]["threads"] if rows else 0
    lines = [
        f"Build times (median of {rows[0]['rounds'] if rows else 0} paired rounds; "
        f"`{command}`):",
        "",
        f"| scene | triangles | kd, 1 thread | kd, {threads} threads | Embree | "
        f"kd 1 / Embree | kd {threads} / Embree | kd SAH cost |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['triangles']:,} | {r['kd_1_s']:.3f} s | "
                     f"{r['kd_n_s']:.3f} s | {r['embree_s']:.3f} s | "
                     f"{r['kd_1_per_embree']:.2f}× | {r['kd_n_per_embree']:.2f}× | "
                     f"{r['sah_cost']:.2f} |")
    return "\n".join(lines) + "\n"


def bench_build(scene_names: list[str] | None = None, rounds: int = 3, threads: int = 0,
                log=print) -> list[dict]:
    """The rows of every scene here (shared meshes absent here are skipped,
    and said so); `threads` 0 means all cores."""
    threads = threads or os.cpu_count() or 1
    rows = []
    for name in scene_names or DEFAULT_SCENES:
        try:
            triangles = scenes.load(name)
        except FileNotFoundError as e:
            log(f"skipped scene {name}: {e}")
            continue
        rows.append(build_row(name, triangles, rounds, threads))
        r = rows[-1]
        log(f"{name}: kd {r['kd_1_s']:.3f} s (1 thread), {r['kd_n_s']:.3f} s ({threads}), "
            f"Embree {r['embree_s']:.3f} s: {r['kd_n_per_embree']:.2f}x")
    return rows

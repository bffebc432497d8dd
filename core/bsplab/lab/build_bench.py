"""The build-time benchmark, `python -m bsplab bench-build`: the kd build on
one thread and on all of them against Embree's BVH build of the same
triangles, in paired rounds (`timing.paired_rounds`: the three builds one
after the other in a rotating order, so a drifting machine slows all three
alike), each figure the median over the rounds. Every time is the wall time
of the whole call: `bsplab.build` with its input checks, and the
`EmbreeTracer` constructor, which builds Embree's BVH.

With `sweeps`, the same rounds also build the two BSP trees whose build
time the issue bounds as a multiple of kd's: the ^Kd sweep at K = 8
(bsp_wn+kd) and BSP_IZE^Kd (bsp_ize+kd), both on `threads` threads and
reported over the kd build on as many.

Every run also builds our BVH (method "bvh", issue 23) on `threads` threads,
reported over Embree's build (the issue's target: at most 1.0x)."""

from __future__ import annotations

import os

import bsplab

from .. import oracle, scenes
from .timing import Tracer, paired_rounds

# The shared meshes the target names (docs/benchmark.md's scenes).
DEFAULT_SCENES = ["bunny", "conference", "dragon_res2", "lost_empire", "sibenik",
                  "sponza_dabrovic", "sportscar"]


# The BSP builds `sweeps` adds: row key -> (method, its options).
SWEEP_BUILDS = {"wn8": ("bsp_wn+kd", {"k": 8}), "ize": ("bsp_ize+kd", {})}


def build_row(name: str, triangles, rounds: int, threads: int, sweeps: bool = False) -> dict:
    """One scene's paired build times (seconds, medians), their ratios to
    Embree's (medians of the per-round ratios) and the kd-tree's SAH cost;
    with `sweeps` also the BSP builds' times and ratios to kd's."""
    many = f"kd_{threads}"
    tracers = {
        "kd_1": Tracer(lambda: bsplab.build(triangles, "kd", threads=1)),
        many: Tracer(lambda: bsplab.build(triangles, "kd", threads=threads)),
        "embree": Tracer(lambda: oracle.EmbreeTracer(triangles)),
        "bvh": Tracer(lambda: bsplab.build(triangles, "bvh", threads=threads)),
    }
    if sweeps:
        for key, (method, options) in SWEEP_BUILDS.items():
            tracers[key] = Tracer(lambda m=method, o=options:
                                  bsplab.build(triangles, m, threads=threads, **o))
    times = paired_rounds(tracers, rounds)
    stats = times.results["kd_1"].stats
    row = {
        "scene": name,
        "triangles": len(triangles),
        "threads": threads,
        "kd_1_s": times.median("kd_1"),
        "kd_n_s": times.median(many),
        "embree_s": times.median("embree"),
        "kd_1_per_embree": times.ratio("kd_1", "embree"),
        "kd_n_per_embree": times.ratio(many, "embree"),
        "sah_cost": stats["sah_cost"],
        "bvh_s": times.median("bvh"),
        "bvh_per_embree": times.ratio("bvh", "embree"),
        "bvh_sah_cost": times.results["bvh"].stats["sah_cost"],
        "rounds": rounds,
    }
    if sweeps:
        for key in SWEEP_BUILDS:
            row[f"{key}_s"] = times.median(key)
            row[f"{key}_per_kd"] = times.ratio(key, many)
    return row


def shared_folder() -> str:
    """The shared scenes folder, for messages."""
    from ..workloads import shared_scenes_dir
    return str(shared_scenes_dir() or "not found")


def build_markdown(rows: list[dict], command: str) -> str:
    threads = rows[0]["threads"] if rows else 0
    # The BSP columns when every row has them (rows of one run all do).
    sweeps = bool(rows) and all("wn8_s" in r for r in rows)
    extra_head = (f" bsp_wn+kd K=8, {threads} | / kd {threads} | "
                  f"bsp_ize+kd, {threads} | / kd {threads} |") if sweeps else ""
    lines = [
        f"Build times (median of {rows[0]['rounds'] if rows else 0} paired rounds; "
        f"`{command}`):",
        "",
        f"| scene | triangles | kd, 1 thread | kd, {threads} threads | Embree | "
        f"kd 1 / Embree | kd {threads} / Embree | kd SAH cost | BVH, {threads} | "
        f"BVH / Embree | BVH SAH cost |" + extra_head,
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|" + ("---:|" * 4 if sweeps else ""),
    ]
    for r in rows:
        extra = (f" {r['wn8_s']:.3f} s | {r['wn8_per_kd']:.2f}× | {r['ize_s']:.3f} s | "
                 f"{r['ize_per_kd']:.2f}× |") if sweeps else ""
        lines.append(f"| {r['scene']} | {r['triangles']:,} | {r['kd_1_s']:.3f} s | "
                     f"{r['kd_n_s']:.3f} s | {r['embree_s']:.3f} s | "
                     f"{r['kd_1_per_embree']:.2f}× | {r['kd_n_per_embree']:.2f}× | "
                     f"{r['sah_cost']:.2f} | {r['bvh_s']:.3f} s | {r['bvh_per_embree']:.2f}× | "
                     f"{r['bvh_sah_cost']:.2f} |" + extra)
    return "\n".join(lines) + "\n"


def bench_build(scene_names: list[str] | None = None, rounds: int = 3, threads: int = 0,
                log=print, sweeps: bool = False) -> list[dict]:
    """The rows of every scene named, or without names of DEFAULT_SCENES: a
    default shared mesh absent here is skipped (and said so), any other name
    that is no scene is an error naming the scenes there are; `threads` 0
    means all cores; `sweeps` adds the BSP builds."""
    from .spec import check_scene
    threads = threads or os.cpu_count() or 1
    for name in scene_names or []:  # before the first build: a typo is said at once
        if name not in DEFAULT_SCENES:
            check_scene(name)
    rows = []
    for name in scene_names or DEFAULT_SCENES:
        try:
            triangles = scenes.load(name)
        except FileNotFoundError as e:
            log(f"skipped scene {name}: {e}")
            continue
        rows.append(build_row(name, triangles, rounds, threads, sweeps))
        r = rows[-1]
        log(f"{name}: kd {r['kd_1_s']:.3f} s (1 thread), {r['kd_n_s']:.3f} s ({threads}), "
            f"Embree {r['embree_s']:.3f} s: {r['kd_n_per_embree']:.2f}x; "
            f"bvh {r['bvh_s']:.3f} s: {r['bvh_per_embree']:.2f}x Embree" +
            (f"; bsp_wn+kd K=8 {r['wn8_per_kd']:.2f}x kd, bsp_ize+kd {r['ize_per_kd']:.2f}x kd"
             if sweeps else ""))
    return rows

"""The build-time benchmark, `python -m bsplab bench-build`: the kd build on
one thread and on all of them, at both build qualities, against Embree's BVH
build of the same triangles, in paired rounds (`timing.paired_rounds`: the
builds one after the other in a rotating order, so a drifting machine slows
all of them alike), each figure the median over the rounds. Every time is
the wall time of the whole call: `bsplab.build` with its input checks, and
the `EmbreeTracer` constructor, which builds Embree's BVH.

With `sweeps`, the same rounds also build the two BSP trees whose build
time issue 25 bounds as a multiple of kd's: the ^Kd sweep at K = 8
(bsp_wn+kd) and BSP_IZE^Kd (bsp_ize+kd), both on `threads` threads, at both
qualities, each reported over the exact kd build on as many threads.

Every run also builds our BVH (method "bvh") on `threads` threads, reported
over Embree's build.

Then what a fast build costs in the tree (`quality_rows`): for every method
built, the fast tree beside the exact one - its SAH cost, its steps and
triangle tests per ray (the counting path), and its hits-only trace time
over the exact tree's on the same rays in paired rounds, for primary rays
(tile order) and ambient-occlusion rays cast from their hits."""

from __future__ import annotations

import os

import numpy as np

import bsplab

from .. import oracle, scenes, workloads
from .timing import Tracer, paired_rounds

# The shared meshes the target names (docs/benchmark.md's scenes).
DEFAULT_SCENES = ["bunny", "conference", "dragon_res2", "lost_empire", "sibenik",
                  "sponza_dabrovic", "sportscar"]

# The build qualities compared (the registry's build_quality choices).
QUALITIES = ("exact", "fast")

# The BSP builds `sweeps` adds: row key -> (method, its options).
SWEEP_BUILDS = {"wn8": ("bsp_wn+kd", {"k": 8}), "ize": ("bsp_ize+kd", {})}

# Every method the quality table compares, by row key: kd, and the sweeps'.
QUALITY_METHODS = {"kd": ("kd", {}), **SWEEP_BUILDS}

# The quality table's primary rays: a side x side image from the framing
# camera, and one ambient-occlusion ray from each of their hits.
DEFAULT_SIDE = 256


def _key(method_key: str, quality: str) -> str:
    """A build's tracer key: "kd" (exact on `threads`), "kd_fast", "wn8_fast"..."""
    return method_key if quality == "exact" else f"{method_key}_{quality}"


def build_row(name: str, triangles, rounds: int, threads: int, sweeps: bool = False,
              side: int = DEFAULT_SIDE) -> dict:
    """One scene's paired build times (seconds, medians), their ratios to
    Embree's (medians of the per-round ratios) and the kd-tree's SAH cost at
    both qualities; with `sweeps` also the BSP builds' times and ratios to
    the exact kd build's; and `quality`, the quality table's rows (`side` 0:
    none)."""
    def builder(method, options, quality, n_threads):
        return Tracer(lambda: bsplab.build(triangles, method, threads=n_threads,
                                           build_quality=quality, **options))

    methods = {"kd": QUALITY_METHODS["kd"]}
    if sweeps:
        methods.update(SWEEP_BUILDS)
    tracers = {"kd_1": builder("kd", {}, "exact", 1)}
    for key, (method, options) in methods.items():
        for quality in QUALITIES:
            tracers[_key(key, quality)] = builder(method, options, quality, threads)
    tracers["embree"] = Tracer(lambda: oracle.EmbreeTracer(triangles))
    tracers["bvh"] = Tracer(lambda: bsplab.build(triangles, "bvh", threads=threads))
    times = paired_rounds(tracers, rounds)
    row = {
        "scene": name,
        "triangles": len(triangles),
        "threads": threads,
        "kd_1_s": times.median("kd_1"),
        "kd_n_s": times.median("kd"),
        "kd_fast_s": times.median("kd_fast"),
        "embree_s": times.median("embree"),
        "kd_1_per_embree": times.ratio("kd_1", "embree"),
        "kd_n_per_embree": times.ratio("kd", "embree"),
        "kd_fast_per_embree": times.ratio("kd_fast", "embree"),
        "sah_cost": times.results["kd_1"].stats["sah_cost"],
        "kd_fast_sah_cost": times.results["kd_fast"].stats["sah_cost"],
        "bvh_s": times.median("bvh"),
        "bvh_per_embree": times.ratio("bvh", "embree"),
        "bvh_sah_cost": times.results["bvh"].stats["sah_cost"],
        "rounds": rounds,
    }
    if sweeps:
        for key in SWEEP_BUILDS:
            for quality in QUALITIES:
                k = _key(key, quality)
                row[f"{k}_s"] = times.median(k)
                row[f"{k}_per_kd"] = times.ratio(k, "kd")
    row["quality"] = quality_rows(triangles, times, methods, rounds, side) if side else []
    return row


def _rays(triangles, side: int):
    """The quality table's workloads: primary rays in tile order and one
    ambient-occlusion ray from each primary hit (Embree's hits, so that both
    trees trace the very same secondary rays)."""
    o, d = workloads.primary_rays(triangles, side, side, tiles=True)
    hits = oracle.EmbreeTracer(triangles).intersect(o, d)
    ao_o, ao_d = workloads.ambient_occlusion_rays(triangles, o, d, hits)
    return {"primary": (o, d), "ao": (ao_o, ao_d)}


# The quality table's trace times take at least this many paired rounds: a
# round of 256² rays is 15-30 ms, and two of them could not tell a 5 %
# difference (the bound) from the machine's noise.
TRACE_ROUNDS = 7


def quality_rows(triangles, times, methods: dict, rounds: int, side: int) -> list[dict]:
    """Per method and quality: build time over Embree's, SAH cost (and over
    the exact tree's), steps and tests per ray on each workload, and the
    hits-only trace time over the exact tree's (paired rounds, one thread)."""
    rays = _rays(triangles, side)
    rows = []
    for key, (method, options) in methods.items():
        label = " ".join([method] + [f"{name.upper()}={v}" for name, v in options.items()])
        trees = {q: times.results[_key(key, q)] for q in QUALITIES}
        tracers = {}
        for workload, (o, d) in rays.items():
            for q, tree in trees.items():
                tracers[f"{workload}/{q}"] = Tracer(
                    lambda t=tree, o=o, d=d: t.intersect(o, d, threads=1, counters=False))
        traced = paired_rounds(tracers, max(rounds, TRACE_ROUNDS))
        exact_sah = trees["exact"].stats["sah_cost"]
        for q, tree in trees.items():
            r = {"method": label, "quality": q,
                 "build_per_embree": times.ratio(_key(key, q), "embree"),
                 "sah_cost": tree.stats["sah_cost"],
                 "sah_per_exact": tree.stats["sah_cost"] / exact_sah if exact_sah else 1.0,
                 "bytes": tree.stats["bytes"]}
            for workload, (o, d) in rays.items():
                counted = tree.intersect(o, d, threads=0)
                r[f"{workload}_steps"] = float(np.mean(counted["steps"])) if len(o) else 0.0
                r[f"{workload}_tests"] = float(np.mean(counted["tests"])) if len(o) else 0.0
                r[f"{workload}_per_exact"] = traced.ratio(f"{workload}/{q}", f"{workload}/exact")
            rows.append(r)
    return rows


def shared_folder() -> str:
    """The shared scenes folder, for messages."""
    from ..workloads import shared_scenes_dir
    return str(shared_scenes_dir() or "not found")


def machine_line(machine: dict) -> str:
    """Where the times were taken: the ratios to Embree's build move with the
    host (Embree picks its build kernels for the CPU at run time; the lab's
    builders are compiled once, for any x86-64)."""
    load = ""
    if machine.get("load_start") and machine.get("load_end"):
        load = (f"; load average (1/5/15 min) {' / '.join(map(str, machine['load_start']))} "
                f"at the start, {' / '.join(map(str, machine['load_end']))} at the end")
    return (f"Machine: {machine.get('cpu', '?')}, {machine.get('cores', '?')} cores, widest "
            f"instruction set {machine.get('isa', '?')}; started {machine.get('started', '?')}"
            f"{load}. Embree picks its build kernels for the CPU at run time and the lab's "
            "builders are compiled for any x86-64, so the ratios to Embree move with the host.")


def build_markdown(rows: list[dict], command: str, machine: dict | None = None) -> str:
    threads = rows[0]["threads"] if rows else 0
    # The BSP columns when every row has them (rows of one run all do).
    sweeps = bool(rows) and all("wn8_s" in r for r in rows)
    n = threads
    extra_head = (f" bsp_wn+kd K=8 exact | fast | exact / kd | fast / kd | "
                  f"bsp_ize+kd exact | fast | exact / kd | fast / kd |") if sweeps else ""
    lines = [
        f"Build times (median of {rows[0]['rounds'] if rows else 0} paired rounds, {n} threads "
        f"unless said; \"/ kd\" is over the exact kd build on {n} threads; `{command}`):",
        "",
        *([machine_line(machine), ""] if machine else []),
        f"| scene | triangles | Embree | kd exact, 1 thread | kd exact | kd fast | "
        f"kd 1 / Embree | kd exact / Embree | kd fast / Embree | kd SAH exact | kd SAH fast | "
        f"BVH | BVH / Embree |" + extra_head,
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|" +
        ("---:|" * 8 if sweeps else ""),
    ]
    for r in rows:
        extra = ""
        if sweeps:
            for key in SWEEP_BUILDS:
                extra += (f" {r[f'{key}_s']:.3f} s | {r[f'{key}_fast_s']:.3f} s | "
                          f"{r[f'{key}_per_kd']:.2f}× | {r[f'{key}_fast_per_kd']:.2f}× |")
        lines.append(f"| {r['scene']} | {r['triangles']:,} | {r['embree_s']:.3f} s | "
                     f"{r['kd_1_s']:.3f} s | {r['kd_n_s']:.3f} s | {r['kd_fast_s']:.3f} s | "
                     f"{r['kd_1_per_embree']:.2f}× | {r['kd_n_per_embree']:.2f}× | "
                     f"{r['kd_fast_per_embree']:.2f}× | {r['sah_cost']:.2f} | "
                     f"{r['kd_fast_sah_cost']:.2f} | {r['bvh_s']:.3f} s | "
                     f"{r['bvh_per_embree']:.2f}× |" + extra)
    quality = [(r["scene"], q) for r in rows for q in r.get("quality", [])]
    if quality:
        lines += [
            "",
            "What the build quality costs in the tree: SAH cost, steps and triangle tests per "
            "ray (counting path), and the hits-only trace time over the exact tree's on the "
            f"same rays (median of at least {TRACE_ROUNDS} paired rounds, one thread): primary "
            "rays in tile order and one ambient-occlusion ray from each of their hits.",
            "",
            "| scene | method | quality | build / Embree | SAH | SAH / exact | "
            "steps / primary | tests / primary | steps / AO | tests / AO | "
            "primary time / exact | AO time / exact | MiB |",
            "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        ]
        for scene, q in quality:
            lines.append(f"| {scene} | {q['method']} | {q['quality']} | "
                         f"{q['build_per_embree']:.2f}× | {q['sah_cost']:.2f} | "
                         f"{q['sah_per_exact']:.3f} | {q['primary_steps']:.1f} | "
                         f"{q['primary_tests']:.2f} | {q['ao_steps']:.1f} | {q['ao_tests']:.2f} | "
                         f"{q['primary_per_exact']:.3f} | {q['ao_per_exact']:.3f} | "
                         f"{q['bytes'] / 2**20:.1f} |")
    return "\n".join(lines) + "\n"


def bench_build(scene_names: list[str] | None = None, rounds: int = 3, threads: int = 0,
                log=print, sweeps: bool = False, side: int = DEFAULT_SIDE) -> list[dict]:
    """The rows of every scene named, or without names of DEFAULT_SCENES: a
    default shared mesh absent here is skipped (and said so), any other name
    that is no scene is an error naming the scenes there are; `threads` 0
    means all cores; `sweeps` adds the BSP builds; `side` is the quality
    table's image side (0: no quality table)."""
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
        rows.append(build_row(name, triangles, rounds, threads, sweeps, side))
        r = rows[-1]
        log(f"{name}: kd {r['kd_1_s']:.3f} s (1 thread), {r['kd_n_s']:.3f} s ({threads}), "
            f"fast {r['kd_fast_s']:.3f} s, Embree {r['embree_s']:.3f} s: exact "
            f"{r['kd_n_per_embree']:.2f}x, fast {r['kd_fast_per_embree']:.2f}x; "
            f"bvh {r['bvh_s']:.3f} s: {r['bvh_per_embree']:.2f}x Embree" +
            (f"; bsp_wn+kd K=8 {r['wn8_per_kd']:.2f}x kd (fast {r['wn8_fast_per_kd']:.2f}x), "
             f"bsp_ize+kd {r['ize_per_kd']:.2f}x kd (fast {r['ize_fast_per_kd']:.2f}x)"
             if sweeps else ""))
    return rows

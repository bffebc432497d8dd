"""The instanced-scene benchmark, `python -m bsplab bench-instanced`: per
world of `bsplab.instanced_scenes.WORLDS` and per method, the two-level
scene (`bsplab.build_instanced`: a tree per unique mesh, a BVH over the
instances) against the flat tree of the flattened scene (where it fits under
`flat_limit` triangles) and Embree over the flattened scene (under
`embree_limit`): build time, bytes, the builds' peak bytes, primary- and
random-ray time in paired rounds (`timing.paired_rounds`, one thread, hits
only), steps and tests per ray of each level (the counting path, once)."""

from __future__ import annotations

import numpy as np

import bsplab

from .. import instanced_scenes, oracle, workloads
from .timing import Tracer, paired_rounds

DEFAULT_WORLDS = ["grid25", "suzanne_grid", "city", "forest", "spheres10k"]
DEFAULT_METHODS = ["kd", "bvh"]
# Flat trees and Embree's flattened scene above these many triangles are not
# built: the point of two levels is that they need not be.
FLAT_LIMIT = 2_000_000
EMBREE_LIMIT = 10_000_000


def _camera(flat_lo, flat_hi) -> bsplab.Camera:
    """Above the world, looking down at its centre at 50 degrees."""
    lo, hi = np.asarray(flat_lo, float), np.asarray(flat_hi, float)
    c, ext = (lo + hi) / 2, hi - lo
    eye = c + np.array([0.25 * ext[0], -0.45 * ext[1], 0.6 * max(ext[0], ext[1])])
    return bsplab.Camera.look_at(tuple(eye), tuple(c), up=(0, 0, 1), fov_deg=50)


def _bounds(scene) -> tuple:
    b = scene.top_boxes(max_depth=0)
    return b["lo"][0], b["hi"][0]


def world_rows(world: str, methods: list[str], side: int, rays: int, rounds: int,
               flat_limit: int = FLAT_LIMIT, embree_limit: int = EMBREE_LIMIT,
               log=print) -> list[dict]:
    meshes, idx, mats = instanced_scenes.WORLDS[world]()
    rows = []
    embree = None
    for method in methods:
        # The builds' wall times through the lab's one timer (one round).
        built = paired_rounds({"two": Tracer(lambda: bsplab.build_instanced(meshes, idx, mats,
                                                                            method))}, 1)
        scene, two_s = built.results["two"], built.median("two")
        s = scene.stats
        lo, hi = _bounds(scene)
        cam = _camera(lo, hi)
        o_p, d_p = cam.rays(side, side)
        rng = np.random.default_rng(1)
        o_r = rng.uniform(lo, hi, (rays, 3)).astype(np.float32)
        d_r = rng.normal(size=(rays, 3))
        d_r = (d_r / np.linalg.norm(d_r, axis=1, keepdims=True)).astype(np.float32)
        n_flat = s["instanced_triangles"]
        flat_tris = scene.flatten() if n_flat <= max(flat_limit, embree_limit) else None
        flat = None
        flat_s = None
        if flat_tris is not None and n_flat <= flat_limit:
            built = paired_rounds({"flat": Tracer(lambda: bsplab.build(flat_tris, method))}, 1)
            flat, flat_s = built.results["flat"], built.median("flat")
        if embree is None and flat_tris is not None and n_flat <= embree_limit:
            embree = oracle.EmbreeTracer(flat_tris)
        del flat_tris
        row = {"world": world, "method": method, "meshes": s["meshes"],
               "instances": s["instances"], "instanced_triangles": n_flat,
               "mesh_triangles": s["mesh_triangles"], "two_level_build_s": two_s,
               "top_build_s": s["top_build_seconds"], "bottom_bytes": s["bottom_bytes"],
               "top_bytes": s["top_bytes"], "top_bytes_per_instance": s["top_bytes_per_instance"],
               "bottom_peak_bytes": int(sum(t.stats["peak_bytes"] for t in scene.meshes)),
               "flat_build_s": flat_s, "flat_bytes": flat.stats["bytes"] if flat else None,
               "flat_peak_bytes": flat.stats["peak_bytes"] if flat else None,
               "embree_build_s": embree.build_seconds if embree else None}
        for work, (o, d) in (("primary", (o_p, d_p)), ("random", (o_r, d_r))):
            tracers = {"two": Tracer(lambda o=o, d=d: scene.intersect(o, d, threads=1,
                                                                       counters=False))}
            if flat is not None:
                tracers["flat"] = Tracer(lambda o=o, d=d: flat.intersect(o, d, threads=1,
                                                                          counters=False))
            if embree is not None:
                tracers["embree"] = Tracer(lambda o=o, d=d: embree.intersect(o, d),
                                           seconds=lambda: embree.last_seconds)
            times = paired_rounds(tracers, rounds)
            row[f"{work}_rays"] = len(o)
            row[f"{work}_two_s"] = times.median("two")
            row[f"{work}_two_per_flat"] = times.ratio("two", "flat") if flat else None
            row[f"{work}_two_per_embree"] = times.ratio("two", "embree") if embree else None
            row[f"{work}_flat_per_embree"] = (times.ratio("flat", "embree")
                                              if flat and embree else None)
            counted = scene.intersect(o, d, counters=True)
            for k in ("top_steps", "instance_visits", "steps", "tests"):
                row[f"{work}_{k}"] = float(counted[k].mean())
            if flat is not None:
                fc = flat.intersect(o, d, counters=True)
                row[f"{work}_flat_steps"] = float(fc["steps"].mean())
                row[f"{work}_flat_tests"] = float(fc["tests"].mean())
                ref = times.results["flat"]
                same = np.array_equal(ref["prim"] >= 0, times.results["two"]["prim"] >= 0)
                row[f"{work}_same_hit_mask"] = bool(same)
        rows.append(row)
        log(f"{world} {method}: {s['instances']} instances of {s['meshes']} meshes "
            f"({n_flat:,} instanced triangles): two-level build {two_s:.3f} s"
            + (f", flat {flat_s:.2f} s" if flat_s else "")
            + f"; primary two-level {row['primary_two_s']:.3f} s"
            + (f" = {row['primary_two_per_flat']:.2f}x flat" if flat else "")
            + (f", {row['primary_two_per_embree']:.2f}x Embree" if embree else ""))
        del flat
    return rows


def _f(x, fmt, unit=""):
    return "—" if x is None else format(x, fmt) + unit


def markdown(rows: list[dict], command: str) -> str:
    rounds = rows[0].get("rounds", "") if rows else ""
    lines = [
        "# Instanced scenes: two levels against the flattened scene",
        "",
        f"Command: `{command}`. Generated by `bsplab.lab.instanced_bench`; every time on one "
        "thread for the traces (hits only), paired rounds (`bsplab.lab.timing`: the two-level "
        "scene, the flat tree and Embree over the flattened scene on the same rays, one after "
        "the other, rotating), each ratio the median of the per-round ratios. Builds use all "
        f"cores. A flat tree is built only up to {FLAT_LIMIT:,} instanced triangles and "
        f"Embree's flattened scene up to {EMBREE_LIMIT:,} (—: not built). The random rays "
        "are traced in spatial order by our kd paths (`ray_order=\"auto\"`, the default, "
        "which sorts rays in the instances' box: sorted by origin and direction, the hits "
        "returned in the caller's order) "
        "and as given by our BVH paths and Embree. Worlds: "
        "`bsplab.instanced_scenes.WORLDS` (suzanne_grid and grid25: 100 and 25 copies of the "
        "bunny standing in for the issue's Suzanne).",
        "",
        "## Build and memory",
        "",
        "| world | method | meshes | instances | instanced tris | two-level build | top build | "
        "bottom MiB | top B/instance | bottom peak MiB | flat build | flat MiB | flat peak MiB | "
        "Embree build |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    mib = 2.0 ** 20
    for r in rows:
        lines.append(
            f"| {r['world']} | {r['method']} | {r['meshes']} | {r['instances']:,} | "
            f"{r['instanced_triangles']:,} | {r['two_level_build_s']:.3f} s | "
            f"{r['top_build_s'] * 1e3:.1f} ms | {r['bottom_bytes'] / mib:.1f} | "
            f"{r['top_bytes_per_instance']:.0f} | {r['bottom_peak_bytes'] / mib:.1f} | "
            f"{_f(r['flat_build_s'], '.2f', ' s')} | "
            f"{_f(r['flat_bytes'] and r['flat_bytes'] / mib, '.1f')} | "
            f"{_f(r['flat_peak_bytes'] and r['flat_peak_bytes'] / mib, '.1f')} | "
            f"{_f(r['embree_build_s'], '.2f', ' s')} |")
    for work in ("primary", "random"):
        lines += [
            "",
            f"## {work.capitalize()} rays",
            "",
            "| world | method | rays | two-level s | two-level / flat | two-level / Embree | "
            "flat / Embree | top steps/ray | instances/ray | bottom steps/ray | bottom tests/ray | "
            "flat steps/ray | flat tests/ray |",
            "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        ]
        for r in rows:
            lines.append(
                f"| {r['world']} | {r['method']} | {r[f'{work}_rays']:,} | "
                f"{r[f'{work}_two_s']:.3f} | {_f(r[f'{work}_two_per_flat'], '.2f')} | "
                f"{_f(r[f'{work}_two_per_embree'], '.2f')} | "
                f"{_f(r[f'{work}_flat_per_embree'], '.2f')} | {r[f'{work}_top_steps']:.1f} | "
                f"{r[f'{work}_instance_visits']:.2f} | {r[f'{work}_steps']:.1f} | "
                f"{r[f'{work}_tests']:.2f} | {_f(r.get(f'{work}_flat_steps'), '.1f')} | "
                f"{_f(r.get(f'{work}_flat_tests'), '.2f')} |")
    return "\n".join(lines) + "\n"


def bench_instanced(worlds: list[str] | None = None, methods: list[str] | None = None,
                    side: int = 256, rays: int = 65_536, rounds: int = 3,
                    flat_limit: int = FLAT_LIMIT, embree_limit: int = EMBREE_LIMIT,
                    log=print) -> list[dict]:
    for w in worlds or []:
        if w not in instanced_scenes.WORLDS:
            raise ValueError(f"unknown world {w!r}; worlds: {', '.join(instanced_scenes.WORLDS)}")
    for m in methods or []:
        bsplab.method_table.get(m)
    rows = []
    for w in worlds or DEFAULT_WORLDS:
        for r in world_rows(w, methods or DEFAULT_METHODS, side, rays, rounds, flat_limit,
                            embree_limit, log):
            r["rounds"] = rounds
            rows.append(r)
    return rows

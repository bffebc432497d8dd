"""`python -m bsplab verdict`: the experiments behind the explanations of
docs/results_discussion.md. The discussion says *why* BSP planes pay on some
scenes and not on others; every "why" there points at a number this module
measures, so that a rerun checks the explanation instead of repeating it.

Per scene, on the results spec's own rays (primary and ambient occlusion),
one process traces in paired rounds (`timing.paired_rounds`), each tree on
the counting path and on the hits-only path a renderer takes:

* `kd`: the Wald-Havran kd-tree, the reference;
* `axes kd`: the sweep builder with the three axes alone (bsp_wn+kd, K = 3),
  which should be the kd-tree again (the parity of issue 13);
* `axes general`: the same sweep, the same planes, but every node stored as a
  general node (bsp_wn+, K = 3: without ^Kd every step is priced K_d, so the
  builder picks the same planes). Same steps, same tests, only the node
  encoding differs: the time ratio is the price of a general step alone;
* the best normal-based ^Kd trees (`bsp_wn+kd`, `bsp_cn+kd` at K = 8).

Beside the times it keeps every tree's exact counters (steps, general steps,
tests per ray), its node counts and SAH cost, and the share of the scene's
triangle area whose normal lies within a degree of an axis (where a
normal-based direction *is* an axis and ^Kd stores a kd node). The analysis
of the results run's rows (cost fit, ^Kd against plain, SAH against tests)
is in `verdict_report.py`."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .trials import load_scene, scene_references
from .spec import Spec, build_options, load_spec
from .store import load_average, machine_info
from .timing import Tracer, paired_rounds

SPECS = Path(__file__).resolve().parent.parent / "specs"


@dataclass(frozen=True)
class TreeSpec:
    """One tree of the experiment: its label in the tables, method and K."""
    label: str
    method: str
    k: int | None


# The label of the reference every ratio divides by.
KD = "kd"
TREES = (
    TreeSpec(KD, "kd", None),
    TreeSpec("axes kd", "bsp_wn+kd", 3),
    TreeSpec("axes general", "bsp_wn+", 3),
    TreeSpec("bsp_wn+kd 8", "bsp_wn+kd", 8),
    TreeSpec("bsp_cn+kd 8", "bsp_cn+kd", 8),
)
# The traced paths: the counting path writes steps, tests and hits per ray
# (where the lab's counters come from); the hits-only path is what render()
# and a renderer take, and what Embree is compared with in docs/benchmark.md.
PATHS = ("counting", "hits_only")
# Within this many degrees of an axis a normal counts as axis-aligned: the
# normal-based strategies then find an axis direction, which ^Kd stores as a
# kd node (their clustering merges directions closer than that).
AXIS_DEGREES = 1.0


def axis_aligned_share(triangles: np.ndarray, degrees: float = AXIS_DEGREES) -> float:
    """The share of the triangles' total area whose normal lies within
    `degrees` of one of the three axes (0 for a mesh of zero area)."""
    tris = np.asarray(triangles, dtype=np.float64)
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    area = np.linalg.norm(n, axis=1)
    total = area.sum()
    if total <= 0:
        return 0.0
    largest = np.abs(n).max(axis=1)  # |cos| of the angle to the nearest axis, times area
    aligned = largest >= np.cos(np.radians(degrees)) * area
    return float(area[aligned & (area > 0)].sum() / total)


def _tracer(tree, rays, path: str) -> Tracer:
    o, d, tmax = rays.origins, rays.directions, rays.tmax
    if path == "counting":
        return Tracer(lambda: tree.intersect(o, d, tmax=tmax, threads=1))
    return Tracer(lambda: tree.intersect(o, d, tmax=tmax, threads=1, counters=False))


def _tree_record(tree, hits: dict) -> dict:
    s = tree.stats
    return {"method": tree.method, "build_s": s["build_seconds"], "nodes": s["nodes"],
            "kd_nodes": s["kd_nodes"], "general_nodes": s["general_nodes"],
            "leaves": s["leaves"], "refs_per_tri": s["duplication"], "sah": s["sah_cost"],
            "steps": float(hits["steps"].mean()),
            "general_steps": float(hits["general_steps"].mean()),
            "tests": float(hits["tests"].mean())}


def _same_answers(a: dict, b: dict) -> bool:
    """The same triangle hit at the same distance on every ray."""
    return bool(np.array_equal(a["prim"], b["prim"]) and np.array_equal(a["t"], b["t"]))


def trace_scene(spec: Spec, scene: str, trees=TREES, rounds: int = 7) -> dict:
    """Builds the experiment's trees over `scene` and traces them on the
    spec's workloads in paired rounds; the scene's record."""
    from .. import build
    data = load_scene(scene)
    _, rays = scene_references(spec, scene, data)
    built = {t.label: build(data.triangles, method=t.method, threads=spec.build_threads,
                            **build_options(spec, t.method, t.k))
             for t in trees}
    out = {"scene": scene, "triangles": len(data.triangles),
           "axis_aligned_share": axis_aligned_share(data.triangles), "workloads": {}}
    for name, r in rays.items():
        tracers = {f"{label}|{path}": _tracer(tree, r, path)
                   for label, tree in built.items() for path in PATHS}
        times = paired_rounds(tracers, rounds)
        counted = {label: times.results[f"{label}|counting"] for label in built}
        out["workloads"][name] = {
            "rays": len(r.origins),
            "trees": {label: {**_tree_record(built[label], counted[label]),
                              "seconds": {p: times.seconds[f"{label}|{p}"] for p in PATHS},
                              "same_answers_as_kd": _same_answers(counted[label],
                                                                  counted[KD])}
                      for label in built}}
    return out


def ratio_to_kd(workload: dict, label: str, path: str) -> float:
    """The median over the rounds of the tree's time over kd's on `path`."""
    t = np.asarray(workload["trees"][label]["seconds"][path])
    kd = np.asarray(workload["trees"][KD]["seconds"][path])
    return float(np.median(t / kd))


def paired_ratio(workload: dict, label: str, reference: str, path: str) -> np.ndarray:
    """Per round: `label`'s time over `reference`'s on `path`."""
    return (np.asarray(workload["trees"][label]["seconds"][path])
            / np.asarray(workload["trees"][reference]["seconds"][path]))


def experiment_spec(scenes: list[str], **overrides) -> Spec:
    """The results spec's rays (size, AO settings) over `scenes`."""
    return load_spec(SPECS / "results.toml", scenes=scenes, methods=["kd"], **overrides)


DEFAULT_SCENES = ["bunny", "dragon_res2", "sportscar", "sibenik", "sponza_dabrovic",
                  "conference", "lost_empire"]


def run(scenes: list[str], out_json: Path, rounds: int = 7, log=print,
        command: str = "", **overrides) -> dict:
    """Every scene's record in one JSON file (written after each scene, so a
    long run shows its progress)."""
    spec = experiment_spec(scenes, **overrides)
    # Like the results file's record: when it ran and how loaded the machine
    # was (the timing itself is timing.paired_rounds', nothing here times).
    start = time.time()
    record = {"started": time.strftime("%Y-%m-%d %H:%M:%S"), "machine": machine_info(),
              "load_start": load_average(), "rounds": rounds,
              "width": spec.width, "height": spec.height, "command": command,
              "scenes": []}
    for scene in spec.scenes:
        log(f"verdict: {scene}")
        record["scenes"].append(trace_scene(spec, scene, rounds=rounds))
        record.update(minutes=round((time.time() - start) / 60, 1), load_end=load_average())
        out_json.parent.mkdir(parents=True, exist_ok=True)
        out_json.write_text(json.dumps(record, indent=1))
    return record

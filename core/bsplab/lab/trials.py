"""Trials: one tree of a spec (scene, method, K, seed, option variant), built
once and traced on every workload of the spec with the lab's timing protocol
(`timing.paired_rounds`) beside its references, giving one row per workload.

Counters (steps, tests, node counts) are exact and machine-independent;
times are kept per round so that reports can pair them."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import scenes, workloads
from ..camera import tile_order
from .spec import Spec, build_options
from .timing import PairedTimes, format_times, paired_rounds
from .tracers import HITS_ONLY_PATHS, Rays, trial_tracers


@dataclass(frozen=True)
class Trial:
    scene: str
    method: str
    k: int | None
    seed: int
    variant: str = ""   # canonical JSON of the variant's build options; "" for none

    @property
    def key(self) -> str:
        base = f"{self.scene}|{self.method}|{'' if self.k is None else self.k}|{self.seed}"
        # Without a variant the key is what results files before variants hold.
        return f"{base}|{self.variant}" if self.variant else base

    def label(self) -> str:
        k = "" if self.k is None else f" K={self.k}"
        v = f" {self.variant}" if self.variant else ""
        return f"{Path(self.scene).name} {self.method}{k} seed {self.seed}{v}"


def trials(spec: Spec) -> list[Trial]:
    """Every trial of the spec, ordered by scene (a worker keeps its scene loaded)."""
    return [Trial(scene, method, k, seed, variant)
            for scene in spec.scenes
            for method in spec.methods
            for k in spec.ks_of(method)
            for seed in spec.seeds_of(method)
            for variant in spec.variants_of(method)]


@dataclass
class SceneData:
    """Triangles and the camera of a scene (its own, or one framing it); an
    instanced world's triangles are its flattened scene, and `instanced`
    holds its (meshes, mesh_index, matrices)."""
    triangles: np.ndarray
    camera: object
    instanced: tuple | None = None

    def parts(self) -> tuple:
        """(meshes, mesh_index, matrices): a flat scene is one mesh under one
        identity instance."""
        if self.instanced is not None:
            return self.instanced
        return [self.triangles], np.zeros(1, np.int64), np.eye(4)[None, :3]


_scene_cache: dict = {}


def load_scene(scene: str) -> SceneData:
    """Loads a scene once per process (one at a time: the big ones are 10 MB+)."""
    if scene not in _scene_cache:
        from .spec import INSTANCED_PREFIX
        instanced = None
        if scene.startswith(INSTANCED_PREFIX):
            from .. import instanced_scenes
            instanced = instanced_scenes.WORLDS[scene[len(INSTANCED_PREFIX):]]()
            tris, camera = instanced_scenes.flatten(*instanced), None
        else:
            tris, camera = scenes.load_with_camera(scene)
        _scene_cache.clear()
        _scene_cache[scene] = SceneData(tris, camera or workloads.framing_camera(tris), instanced)
    return _scene_cache[scene]


def make_rays(spec: Spec, data: SceneData, embree) -> dict[str, Rays]:
    """The workloads' rays by name."""
    from .. import build
    o, d = data.camera.rays(spec.width, spec.height)
    # Primary rays tile by tile (camera.tile_order), for every tracer alike:
    # neighbouring rays are coherent, as the packet path needs, and Embree
    # gets the same order. (The secondary rays below start from the hits in
    # image order, as before.)
    order = tile_order(spec.width, spec.height)
    out = {"primary": Rays("primary", o[order], d[order], np.inf)}
    if {"ao", "diffuse"} & set(spec.workloads):
        # Secondary rays start at the primary hits; Embree's answer is the
        # reference, so every tree gets the same rays.
        hits = embree.intersect(o, d) if embree else build(data.triangles).intersect(o, d)
        lo, hi = workloads.bounds(data.triangles)
        so, sd = workloads.ambient_occlusion_rays(data.triangles, o, d, hits,
                                                  samples=spec.ao_samples)
        # AO: short rays (any occluder within reach); diffuse: a full bounce.
        out["ao"] = Rays("ao", so, sd, float(spec.ao_distance * np.linalg.norm(hi - lo)))
        out["diffuse"] = Rays("diffuse", so, sd, np.inf)
    if "random" in spec.workloads:  # the most incoherent rays: anywhere, any way
        ro, rd = workloads.random_rays(data.triangles, spec.random_rays, seed=1)
        out["random"] = Rays("random", ro, rd, np.inf)
    return {w: out[w] for w in spec.workloads}


_reference_cache: dict = {}


def scene_references(spec: Spec, scene: str, data: SceneData):
    """Embree over the scene (None where it can't run here) and the
    workloads' rays, made once per scene and ray settings: every trial of a
    scene traces the same rays beside the same Embree, so building them per
    trial would only repeat the work."""
    from .. import oracle
    # Not inside a Blender whose own Embree clashes with embreex's.
    usable = oracle.available() and oracle.foreign_embree_library() is None
    key = (scene, usable, spec.width, spec.height, tuple(spec.workloads), spec.ao_samples,
           spec.ao_distance, spec.random_rays)
    cached = _reference_cache.get(key)
    if cached is None or cached[0] is not data:  # the same triangles and camera
        embree = oracle.EmbreeTracer(data.triangles) if usable else None
        _reference_cache.clear()  # one scene at a time: the big ones are 10 MB+
        cached = _reference_cache[key] = (data, embree,
                                          make_rays(spec, data, embree))
    return cached[1], cached[2]


_kd_cache: dict = {}


def kd_reference(spec: Spec, scene: str, data: SceneData):
    """The kd-tree every trial of a scene is timed against, built once per process
    (with the spec's options, not a variant's: one reference for all trials)."""
    from .. import build
    opts = build_options(spec, "kd")
    key = (scene, id(data.triangles), json.dumps(opts, sort_keys=True))
    if key not in _kd_cache:
        _kd_cache.clear()
        _kd_cache[key] = build(data.triangles, method="kd", threads=spec.build_threads, **opts)
    return _kd_cache[key]


def run_trial(spec: Spec, trial: Trial, scene_data: SceneData | None = None,
             progress=None) -> list[dict]:
    """Builds the trial's tree and traces every workload; one row per workload."""
    from .. import Cancelled, build
    data = scene_data or load_scene(trial.scene)
    tris = data.triangles
    embree, rays = scene_references(spec, trial.scene, data)
    options = build_options(spec, trial.method, trial.k, trial.seed, trial.variant)
    if spec.instances == "two-level":
        from .. import build_instanced
        tree = TwoLevelTrial(build_instanced(*data.parts(), trial.method,
                                             threads=spec.build_threads, progress=progress,
                                             **options))
    else:
        tree = build(tris, method=trial.method, threads=spec.build_threads, progress=progress,
                     **options)
    # A kd trial is its own reference, unless a variant made it another kd-tree
    # (or it is a two-level scene: the reference is the flat kd-tree).
    own_reference = trial.method == "kd" and not trial.variant and spec.instances == "flat"
    kd = tree if own_reference else kd_reference(spec, trial.scene, data)

    def check_cancel():
        if progress is not None and progress.cancelled:
            raise Cancelled("cancelled")

    rows = []
    for r in rays.values():
        times = paired_rounds(trial_tracers(tree, kd, embree, spec, r), spec.repetitions,
                              between_rounds=check_cancel)
        if kd is tree:
            times.seconds["kd"] = times.seconds["ours"]
        slack = tree.slack if isinstance(tree, TwoLevelTrial) else None
        rows.append(_row(trial, tris, tree.stats, r, times, embree, slack))
    return rows


class TwoLevelTrial:
    """A two-level scene (InstancedTree) as a trial's tracers and rows see a
    tree: hits numbered in the flattened scene (Embree's and the kd
    reference's numbering), and the statistics of both levels summed under
    the flat tree's names (nodes, leaves, bytes: bottom + top; sah: the
    bottom trees', weighted by their instances' triangles)."""

    def __init__(self, scene):
        self.scene = scene

    def slack(self, rays: Rays, hits: dict, reference: dict) -> np.ndarray:
        """The oracle's tolerance for these hits (the transform's rounding,
        InstancedTree.transform_slack) against a reference's on the same rays."""
        o, d = rays.origins, rays.directions
        return np.maximum(
            self.scene.transform_slack(o, d, hits["t"], hits["instance"]),
            self.scene.transform_slack(o, d, reference["t"],
                                       self.scene.instance_of(reference["prim"])))

    def intersect(self, origins, directions, tmin=0.0, tmax=np.inf, **kwargs) -> dict:
        h = self.scene.intersect(origins, directions, tmin, tmax, **kwargs)
        h["prim"] = h.pop("flat_prim").astype(np.int32)
        return h

    @property
    def stats(self) -> dict:
        s = self.scene.stats
        bottom = [t.stats for t in self.scene.meshes]
        weights = np.bincount(self.scene.mesh_index, minlength=len(bottom))
        tris = np.array([b["triangles"] for b in bottom], float) * weights
        out = {k: sum(b[k] for b in bottom) for k in
               ("nodes", "kd_nodes", "general_nodes", "leaves", "box_bytes")}
        out["nodes"] += s["top_nodes"]
        out["leaves"] += s["top_leaves"]
        refs = sum(b["references"] for b in bottom)
        live = sum(b["triangles"] - b["degenerate"] for b in bottom)
        out.update(
            build_seconds=s["bottom_build_seconds"] + s["top_build_seconds"],
            duplication=refs / max(1, live), bytes=s["bytes"],
            sah_cost=float(np.dot(tris, [b["sah_cost"] for b in bottom]) / max(1.0, tris.sum())),
            level_planes=[], level_directions=[],
            max_depth=max(b["max_depth"] for b in bottom) + s["top_depth"],
            mean_leaf_size=refs / max(1, sum(b["leaves"] - b["empty_leaves"] for b in bottom)),
            warnings=[w for b in bottom for w in b.get("warnings", ())])
        return out


def _unexplained(hits: dict, embree_hits: dict, tris, rays: Rays,
                 slack=None) -> tuple[int, int]:
    """The rays oracle.compare finds failing (ours exactly wrong beyond
    rounding, or undecided: the "unexplained" column), and the grazing ones;
    `slack` (a two-level trial's) gives the transform's rounding."""
    from .. import oracle
    c = oracle.compare(hits, embree_hits, triangles=tris, origins=rays.origins,
                       directions=rays.directions,
                       slack=None if slack is None else slack(rays, hits, embree_hits))
    return len(c["failing"]), c["grazing"]


def _row(trial: Trial, tris, s: dict, rays: Rays, times: PairedTimes, embree,
         slack=None) -> dict:
    hits = times.results["ours"]
    unexplained = grazing = ""
    if embree is not None:
        unexplained, grazing = _unexplained(hits, times.results["embree"], tris, rays, slack)
    row = {
        "scene": trial.scene, "triangles": len(tris), "method": trial.method,
        "k": "" if trial.k is None else trial.k, "seed": trial.seed, "workload": rays.workload,
        "rays": len(rays.origins), "build_s": s["build_seconds"], "nodes": s["nodes"],
        "kd_nodes": s["kd_nodes"], "general_nodes": s["general_nodes"],
        "leaves": s["leaves"], "refs_per_tri": s["duplication"], "bytes": s["bytes"],
        "sah": s["sah_cost"],
        "level_planes": " ".join(map(str, s["level_planes"])),
        "level_directions": " ".join(map(str, s["level_directions"])),
        "trace_s": format_times(times.seconds["ours"]),
        "kd_s": format_times(times.seconds["kd"]),
        "embree_s": format_times(times.seconds.get("embree", [])),
        "steps": float(hits["steps"].mean()),
        "general_steps": float(hits["general_steps"].mean()),
        "tests": float(hits["tests"].mean()),
        "box_tests": float(hits["box_tests"].mean()),
        "hits": int((hits["prim"] >= 0).sum()),
        "unexplained": unexplained, "grazing": grazing,
        "embree_build_s": embree.build_seconds if embree else "",
        "variant": trial.variant, "max_depth": s["max_depth"],
        "mean_leaf_size": s["mean_leaf_size"], "box_bytes": s["box_bytes"],
        "warnings": "; ".join(s.get("warnings", ())),
        "cull_s": "", "cull_tests": "", "culled": "", "cull_differs": "",
    }
    if "culled" in times.results:
        on = times.results["culled"]
        row.update(cull_s=format_times(times.seconds["culled"]),
                   cull_tests=float(on["tests"].mean()), culled=float(on["culled"].mean()),
                   # Culling must never change an answer.
                   cull_differs=int((on["t"] != hits["t"]).sum()))
    for path in HITS_ONLY_PATHS:
        row[f"{path}_s"] = row[f"{path}_unexplained"] = ""
        if path in times.results:
            row[f"{path}_s"] = format_times(times.seconds[path])
            # Every path's every hit is checked: a fast path that went wrong shows.
            if embree is not None:
                row[f"{path}_unexplained"] = _unexplained(
                    times.results[path], times.results["embree"], tris, rays, slack)[0]
    return row

"""Sweep K on triangles in memory: the add-on's "Sweep K" (and any caller
with a scene that is not a file) runs the experiment runner in this process
through these two functions, and needs nothing else of the lab."""

from __future__ import annotations

import tempfile

import numpy as np

from .trials import SceneData, trials
from .report import Results, wrong_hits
from .runner import run
from .spec import make_spec


def sweep_k(triangles, camera, methods: list[str], ks: dict, *, repetitions: int = 3,
            workload: str = "primary", width: int = 64, height: int = 64,
            scene_name: str = "scene", progress=None, on_progress=None) -> list[dict]:
    """Result rows of every method at its K (`ks`: method -> [K, ...], or
    [None] for a method without K), each tree traced `repetitions` times
    beside kd and Embree (where Embree can run) on `camera`'s
    `width` x `height` rays or the secondary rays of `workload`.

    `progress` (a bsplab.Progress) lets another thread cancel;
    `on_progress(done, total, label)` is called as trials finish."""
    scene_key = "memory:" + scene_name
    with_k = {m: list(k) for m, k in ks.items() if list(k) != [None]}
    first_k = min((k for v in with_k.values() for k in v), default=6)
    spec = make_spec({
        "name": "sweep_k", "scenes": [scene_key], "methods": list(methods),
        "ks": [first_k], "method_ks": with_k, "repetitions": repetitions,
        "workloads": [workload], "width": width, "height": height, "executor": "inline",
    }, check_files=False)
    data = {scene_key: SceneData(np.asarray(triangles), camera)}
    total = len(trials(spec))
    if on_progress:
        on_progress(0, total, "starting")
    with tempfile.TemporaryDirectory() as tmp:
        return run(spec, tmp + "/sweep", fresh=True, scene_data=data, progress=progress,
                   on_progress=on_progress, quiet=True)


def sweep_table(rows: list[dict], methods: list[str]) -> dict:
    """Per method and K: median render time as % of kd (paired), its spread,
    tests and steps per ray, build time, × Embree and wrong hits."""
    res = Results(rows)
    scene, workload = res.scenes[0], res.workloads[0]
    out = {"methods": [], "embree": all(r["embree_s"] for r in rows)}
    for m in methods:
        points = []
        for k in res.ks(m):
            g = res.get(scene, workload, m, k)
            pct = res.pct_of_kd(g)
            points.append({
                "k": k, "pct_kd": float(np.median(pct)), "pct_min": float(pct.min()),
                "pct_max": float(pct.max()), "tests": g.mean("tests"), "steps": g.mean("steps"),
                "build_s": g.mean("build_s"), "x_embree": res.x_embree(g),
                "wrong": wrong_hits(g),
            })
        out["methods"].append({"name": m, "points": points})
    out["kd_x_embree"] = res.x_embree(res.kd(scene, workload))
    return out

"""Every traversal path gives the same answer, bit for bit, on every ray
family (bsplab.ray_families) for every method: culling on and off, the
counting and the hits-only path, one thread and two, packets, trace_path.

Culling is conservative only if it skips nothing a leaf would accept; the
leaves accept a hit only where culling would have tested its triangle
(core/src/kernels/leaf_acceptance.hpp). Of equally close hits the smallest
triangle index wins on every path (single_ray.hpp's Closest), so even a ray
through a shared edge, hit by two triangles at the same t, has one answer.
Rays lying in a tilted fan's plane along its spokes are the case that once
differed (291 of 2,000 for kd with and without culling)."""

from __future__ import annotations

import numpy as np
import pytest

import bsplab
from bsplab import ray_families, scenes

from conftest import SCENE_IDS, load_scene

METHODS = list(bsplab.methods())
FAMILIES = list(ray_families.FAMILIES)


def tilted_fan(count: int = 400) -> np.ndarray:
    """A flat fan of `count` slivers in a plane tilted off every axis."""
    u = np.array([1.0, 0.0, 0.3]) / np.linalg.norm([1.0, 0.0, 0.3])
    v = np.array([0.0, 1.0, -0.4]) / np.linalg.norm([0.0, 1.0, -0.4])
    verts, faces = scenes._fan((0.3, -0.2, 0.5), 2.0, u, v, count)
    return verts[faces].astype(np.float32)


def spoke_rays(tris: np.ndarray, n: int, seed: int = 1):
    """Rays lying in the fan's plane along its spokes (the shared edges from
    the centre to the rim), from before one end towards the other."""
    rng = np.random.default_rng(seed)
    k = rng.integers(0, len(tris), n)
    centre, rim = tris[k, 0].astype(np.float64), tris[k, 1].astype(np.float64)
    flip = rng.random(n) < 0.5
    a = np.where(flip[:, None], rim, centre)
    b = np.where(flip[:, None], centre, rim)
    o = (a - rng.uniform(0.0, 2.0, (n, 1)) * (b - a)).astype(np.float32)
    return o, (b - o).astype(np.float32)


_cache: dict = {}


def scene_rays(scene: str, per_family: int):
    """The triangles and every family's rays (seed 5) of a scene, plus the
    spoke rays on the tilted fan."""
    key = (scene, per_family)
    if key not in _cache:
        _cache.clear()
        tris = tilted_fan() if scene == "tilted_fan" else load_scene(scene)
        fams = {name: ray_families.family(name, tris, per_family, seed=5) for name in FAMILIES}
        if scene == "tilted_fan":
            o, d = spoke_rays(tris, 2000)
            fams["spokes"] = (o, d, np.full(len(o), np.inf, np.float32))
        _cache[key] = (tris, fams)
    return _cache[key]


def assert_same(a: dict, b: dict, what: str) -> None:
    bad = np.flatnonzero((a["t"] != b["t"]) | (a["prim"] != b["prim"]))
    assert len(bad) == 0, (
        f"{what}: {len(bad)} of {len(a['t'])} rays differ, e.g. rays {bad[:4]}: "
        f"t {a['t'][bad[:4]]} vs {b['t'][bad[:4]]}, prim {a['prim'][bad[:4]]} vs "
        f"{b['prim'][bad[:4]]}")
    assert np.array_equal(a["u"], b["u"]) and np.array_equal(a["v"], b["v"]), what


def check_paths(tree, o, d, tmax, label: str, trace_paths: int = 0) -> None:
    off = tree.intersect(o, d, tmax=tmax, cull=False)
    on = tree.intersect(o, d, tmax=tmax, cull=True)
    assert_same(on, off, f"{label}: cull=True vs cull=False")
    assert_same(tree.intersect(o, d, tmax=tmax, cull=True, counters=False), on,
                f"{label}: hits-only vs counting, culled")
    assert_same(tree.intersect(o, d, tmax=tmax, counters=False), off,
                f"{label}: hits-only vs counting")
    assert_same(tree.intersect(o, d, tmax=tmax, counters=False, threads=2), off,
                f"{label}: two threads vs one")
    assert_same(tree.intersect(o, d, tmax=tmax, counters=False, packets=True), off,
                f"{label}: packets vs single rays")
    # trace_path runs the counting loop with its own recording policy.
    for i in np.linspace(0, len(o) - 1, trace_paths).astype(int) if trace_paths else ():
        for cull, ref in ((False, off), (True, on)):
            p = tree.trace_path(o[i], d[i], tmax=float(tmax[i]), cull=cull)
            assert p["prim"] == ref["prim"][i] and (p["t"] == ref["t"][i] or
                                                    not np.isfinite(ref["t"][i])), (
                label, "trace_path", cull, i, p["t"], p["prim"], ref["t"][i], ref["prim"][i])
            assert p["steps"] == ref["steps"][i] and p["tests"] == ref["tests"][i], (label, i)
            assert p["box_tests"] == ref["box_tests"][i], (label, i)


def build(tris, method: str, **kw):
    info = bsplab.methods()[method]
    if "k" in info["params"]:
        kw.setdefault("k", 4)
    return bsplab.build(tris, method=method, **kw)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("scene", ["tilted_fan", "gen:room", "gen:tilted"])
def test_every_path_agrees_on_every_family(scene, method):
    tris, fams = scene_rays(scene, 300)
    tree = build(tris, method)
    for name, (o, d, tmax) in fams.items():
        check_paths(tree, o, d, tmax, f"{scene} {method} {name}", trace_paths=3)


@pytest.mark.parametrize("method", ["kd", "bsp_random", "bsp_wn+kd"])
def test_clipped_boxes_agree_too(method):
    tris, fams = scene_rays("tilted_fan", 300)
    tree = build(tris, method, leaf_boxes="clipped")
    for name, (o, d, tmax) in fams.items():
        check_paths(tree, o, d, tmax, f"tilted_fan clipped {method} {name}")


@pytest.mark.parametrize("method", ["kd", "bsp_wn+kd", "bsp_random", "bvh"])
def test_every_path_agrees_on_a_shared_mesh(method):
    shared = [s for s in SCENE_IDS if s.startswith("shared:")]
    if not shared:
        pytest.skip("no shared meshes here (BSPLAB_SCENES)")
    scene = "shared:lost_empire" if "shared:lost_empire" in shared else shared[0]
    tris, fams = scene_rays(scene, 400)
    tree = build(tris, method)
    for name, (o, d, tmax) in fams.items():
        check_paths(tree, o, d, tmax, f"{scene} {method} {name}")

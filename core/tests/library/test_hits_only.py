"""The hits-only path (`intersect(counters=False)`, and `render()` in the
shaded, normal and depth modes) against the counting path: the same tree must
give the same closest hits, bit for bit, for every method, ray family, range,
culling setting and thread count. Both paths are one traversal compiled
twice (core/src/trace/traverse.cpp), so any difference is a bug in the policy that
removes the counters."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

import bsplab
from bsplab import ray_families, scenes

from conftest import load_scene

render_module = importlib.import_module("bsplab.render")

METHODS = list(bsplab.methods())
HITS = ("t", "prim", "u", "v")
SCENES = ("gen:room", "gen:tilted", "gen:grids")


def family_rays(tris: np.ndarray, count: int, seed: int):
    """Every ray family's rays in one batch, with their tmax, and a tmin
    that starts a third of the rays part of the way along."""
    parts = [ray_families.family(name, tris, count, seed) for name in ray_families.FAMILIES]
    o, d, tmax = (np.concatenate(x) for x in zip(*parts))
    rng = np.random.default_rng(seed)
    tmin = np.where(rng.random(len(o)) < 0.3, rng.random(len(o)) * np.minimum(tmax, 1.0), 0.0)
    return o, d, tmin.astype(np.float32), tmax


def assert_same_hits(counted: dict, fast: dict, what: str) -> None:
    assert set(fast) == set(HITS), what
    for key in HITS:
        assert fast[key].dtype == counted[key].dtype, (what, key)
        # No tolerance, and not even -0 == +0: the same bytes. (No NaN
        # either: it is never a valid answer.)
        assert not np.isnan(fast[key].astype(np.float64)).any(), (what, key)
        assert np.array_equal(counted[key].view(np.uint8), fast[key].view(np.uint8)), (
            f"{what}: {key} differs on {int((counted[key] != fast[key]).sum())} rays")


@pytest.mark.parametrize("method", METHODS)
def test_hits_only_equals_the_counting_path(method):
    for scene_id in SCENES:
        tris = load_scene(scene_id)
        tree = bsplab.build(tris, method=method)
        o, d, tmin, tmax = family_rays(tris, 600, seed=8)
        hit_some = False
        for cull in (False, True):
            for lo, hi, span in ((0.0, np.inf, "0..inf"), (tmin, tmax, "per-ray")):
                counted = tree.intersect(o, d, tmin=lo, tmax=hi, cull=cull, threads=1)
                hit_some |= bool((counted["prim"] >= 0).any())
                for threads in (1, 2):
                    fast = tree.intersect(o, d, tmin=lo, tmax=hi, cull=cull, threads=threads,
                                          counters=False)
                    assert_same_hits(counted, fast,
                                     f"{scene_id} {method} cull={cull} {span} threads={threads}")
        assert hit_some, scene_id


def test_hits_only_on_a_scaled_tree():
    # Coordinates far from [1, 2) make the tree scale rays on the way in and
    # distances on the way out: that path must not depend on the counters.
    # The fan (9k triangles; its tilted fans give general nodes on most rays'
    # walks) rather than the spheres (48k): the same scaled path, a tenth of
    # the build (4.3 -> 0.5 s; 22 s -> ~3 s under ASan + UBSan).
    tris = scenes.generate("fan") * np.float32(3e5)
    tree = bsplab.build(tris, method="bsp_cn+kd")
    assert tree.stats["scale"] != 1.0
    o, d, tmin, tmax = family_rays(tris, 300, seed=2)
    for cull in (False, True):
        counted = tree.intersect(o, d, tmin=tmin, tmax=tmax, cull=cull)
        fast = tree.intersect(o, d, tmin=tmin, tmax=tmax, cull=cull, counters=False)
        assert_same_hits(counted, fast, f"scaled cull={cull}")
        assert (counted["prim"] >= 0).sum() > len(o) // 10


@pytest.fixture(scope="module")
def room():
    tris = scenes.generate("room")
    return bsplab.build(tris, method="bsp_wn+kd"), scenes.default_camera("room")


@pytest.mark.parametrize("mode", ["shaded", "normal", "depth"])
@pytest.mark.parametrize("cull", [False, True])
def test_render_modes_without_counters_give_the_same_image(room, mode, cull):
    tree, cam = room
    fast, fast_stats = bsplab.render(tree, cam, 96, 64, mode, cull=cull, threads=2)
    counted, counted_stats = bsplab.render(tree, cam, 96, 64, mode, cull=cull, counters=True)
    assert np.array_equal(fast, counted)
    assert fast_stats["counters"] is False and counted_stats["counters"] is True
    assert fast_stats["hits"] == counted_stats["hits"] > 0
    for key in ("mean_steps", "mean_tests", "mean_culled", "mean_general_steps",
                "max_steps", "max_tests", "max_culled"):
        assert fast_stats[key] is None, key
    assert counted_stats["mean_steps"] > 0 and counted_stats["max_tests"] > 0
    assert (counted_stats["mean_culled"] > 0) == cull


@pytest.mark.parametrize("mode", sorted(render_module.HEAT_COUNTERS))
def test_heatmaps_count_by_default(room, mode):
    tree, cam = room
    image, stats = bsplab.render(tree, cam, 32, 24, mode)
    assert stats["counters"] is True and stats["mean_steps"] > 0
    same, _ = bsplab.render(tree, cam, 32, 24, mode, counters=True)
    assert np.array_equal(image, same)
    with pytest.raises(ValueError, match="needs counters=True"):
        bsplab.render(tree, cam, 32, 24, mode, counters=False)


@pytest.mark.parametrize("bad", [1, 0, "yes", None, 1.0, [True]])
def test_intersect_rejects_a_counters_value_that_is_not_a_bool(room, bad):
    tree, _ = room
    o = np.zeros((1, 3), np.float32)
    d = np.ones((1, 3), np.float32)
    with pytest.raises(TypeError, match="counters must be True or False"):
        tree.intersect(o, d, counters=bad)
    # numpy's bools are bools.
    assert set(tree.intersect(o, d, counters=np.bool_(False))) == set(HITS)


@pytest.mark.parametrize("bad", [1, "no", 0.0])
def test_render_rejects_a_counters_value_that_is_not_a_bool(room, bad):
    tree, cam = room
    with pytest.raises(TypeError, match="counters must be True, False or None"):
        bsplab.render(tree, cam, 8, 8, "shaded", counters=bad)


def test_the_core_rejects_some_counter_arrays_without_the_others(room):
    tree, _ = room
    n = 4
    o = np.zeros((n, 3), np.float32)
    d = np.ones((n, 3), np.float32)
    lo, hi = np.zeros(1, np.float32), np.full(1, np.inf, np.float32)
    f = [np.empty(n, np.float32) for _ in range(3)]
    prim = np.empty(n, np.int32)
    steps = np.empty(n, np.uint32)
    with pytest.raises(ValueError, match="all five counter arrays or none"):
        bsplab._core.intersect(tree._tree, o, d, lo, hi, f[0], prim, f[1], f[2],
                               steps, None, None, None, None, 1, False, None)


@pytest.mark.parametrize("method", ["kd", "bsp_wn"])
@pytest.mark.parametrize("scene_id", SCENES)
def test_both_stepping_loops_give_the_counting_paths_hits(scene_id, method):
    """The hits-only path picks its loop per range of rays: camera rays in
    pixel order are coherent (the plain loop), random rays are not (the loop
    that prefetches the child above every kd node and skips empty children
    from their parent without pushing them; single_ray.hpp,
    ray_coherence.hpp). Each, and a batch of both halves split between two
    threads, must give the counting path's hits, on kd trees and on trees of
    general nodes."""
    from bsplab import workloads
    tris = load_scene(scene_id)
    tree = bsplab.build(tris, method=method)
    co, cd = workloads.primary_rays(tris, 40, 30)
    ro, rd = workloads.random_rays(tris, 1200)
    batches = {"camera": (co, cd), "random": (ro, rd),
               "camera+random": (np.concatenate([co, ro]), np.concatenate([cd, rd]))}
    for name, (o, d) in batches.items():
        counted = tree.intersect(o, d, threads=1)
        assert (counted["prim"] >= 0).any(), name
        for threads in (1, 2):
            assert_same_hits(counted, tree.intersect(o, d, threads=threads, counters=False),
                             f"{scene_id} {name} threads={threads}")


@pytest.mark.parametrize("method", ["kd", "bsp_wn"])
def test_empty_leaves_skipped_from_their_parent_still_count_as_steps(method):
    """The walk skips an empty child from its parent (single_ray.hpp): no
    loop turn, no stack entry. A step is still a node the walk visits in the
    old sense, so the skipped leaf is counted, and recorded by trace_path with
    its range, on every path alike (docs/performance.md)."""
    from bsplab import workloads
    tris = load_scene("gen:room")
    tree = bsplab.build(tris, method=method)
    o, d = workloads.random_rays(tris, 60)
    counted = tree.intersect(o, d, threads=1)
    empty_leaves = 0
    for i in range(len(o)):
        path = tree.trace_path(o[i], d[i])
        assert path["steps"] == counted["steps"][i], i
        assert len(path["node"]) == path["steps"], i
        leaf_rows = np.flatnonzero(path["kind"] == bsplab.tree.KINDS.index("leaf"))
        # Leaves with no triangle reference recorded are the empty ones.
        empty_leaves += len(set(leaf_rows) - set(path["test_step"].tolist()))
    assert empty_leaves > 0

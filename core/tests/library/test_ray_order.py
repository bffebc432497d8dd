"""Incoherent batches traced in spatial order (core/src/trace/ray_order.hpp,
Tree.intersect's and InstancedTree.intersect's ray_order): the single-ray
hits-only path of a kd or BSP tree, and of an instanced scene of them, sorts
an incoherent batch of 4,096 rays or more by the rays' origins and
directions, traces it in that order and writes the hits (and instances)
back in the caller's order; the BVH keeps the given order, and must give
the same hits either way. The hits must be the counting path's (which keeps the given order)
bit for bit on every ray family, method, limit, thread count and window,
and Embree's; and only incoherent batches may take the sorted path."""

from __future__ import annotations

import functools

import numpy as np
import pytest

import bsplab
from bsplab import instanced_scenes, oracle, ray_families, workloads

from conftest import SCENE_IDS, load_scene
from test_paths_agree import assert_same, tilted_fan

METHODS = list(bsplab.methods())
MIN_RAYS = 4096  # ray_order.hpp's kOrderMinRays
WINDOW = 1 << 18  # ray_order.hpp's kOrderWindow


def orders(o, d) -> bool:
    return bsplab._core.orders_rays(np.ascontiguousarray(o, np.float32),
                                    np.ascontiguousarray(d, np.float32))


def shuffled_families(tris, per_family: int, seed: int = 7):
    """Every ray family's rays in one batch, shuffled (so the batch is
    incoherent), with per-ray tmin and tmax: the families' own limits, and
    a start a little along the ray for a fifth of the rays."""
    parts = [ray_families.family(name, tris, per_family, seed) for name in ray_families.FAMILIES]
    o = np.concatenate([p[0] for p in parts])
    d = np.concatenate([p[1] for p in parts])
    tmax = np.concatenate([p[2] for p in parts])
    rng = np.random.default_rng(seed)
    perm = rng.permutation(len(o))
    o, d, tmax = o[perm], d[perm], tmax[perm]
    lo, hi = workloads.bounds(tris)
    tmin = np.where(rng.random(len(o)) < 0.2,
                    rng.uniform(0.0, 0.05, len(o)) * float(np.linalg.norm(hi - lo)),
                    0.0).astype(np.float32)
    return o, d, np.minimum(tmin, tmax).astype(np.float32), tmax


def build(tris, method: str, **kw):
    if "k" in bsplab.methods()[method]["params"]:
        kw.setdefault("k", 4)
    return bsplab.build(tris, method=method, **kw)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("scene", ["tilted_fan", "gen:room", "gen:tilted"])
def test_spatial_order_gives_the_counting_paths_hits_on_every_family(scene, method):
    tris = tilted_fan() if scene == "tilted_fan" else load_scene(scene)
    o, d, tmin, tmax = shuffled_families(tris, 400)
    assert len(o) >= MIN_RAYS and orders(o, d), "the batch must take the sorted path"
    tree = build(tris, method)
    counted = tree.intersect(o, d, tmin=tmin, tmax=tmax)
    assert (counted["prim"] >= 0).sum() > len(o) // 10, "too few hits to tell anything"
    for threads in (1, 2):
        assert_same(tree.intersect(o, d, tmin=tmin, tmax=tmax, counters=False,
                                   ray_order="spatial", threads=threads),
                    counted, f"{scene} {method} spatial order, {threads} threads")
    assert_same(tree.intersect(o, d, tmin=tmin, tmax=tmax, counters=False, ray_order="given"),
                counted, f"{scene} {method} given order")
    # Shared limits (one tmin and tmax for every ray) stay shared.
    counted = tree.intersect(o, d, tmax=2.0)
    assert_same(tree.intersect(o, d, tmax=2.0, counters=False, ray_order="spatial"), counted,
                f"{scene} {method} spatial order, one tmax")
    if method != "bvh":
        culled = tree.intersect(o, d, tmin=tmin, tmax=tmax, cull=True)
        assert_same(tree.intersect(o, d, tmin=tmin, tmax=tmax, cull=True, counters=False,
                                   ray_order="spatial"),
                    culled, f"{scene} {method} spatial order, culled")


@pytest.mark.parametrize("method", ["kd", "bsp_wn+kd", "bsp_random", "bvh"])
def test_spatial_order_agrees_with_embree_on_a_shared_mesh(method):
    shared = [s for s in SCENE_IDS if s.startswith("shared:")]
    if not shared:
        pytest.skip("no shared meshes here (BSPLAB_SCENES)")
    scene = "shared:sibenik" if "shared:sibenik" in shared else shared[0]
    tris = load_scene(scene)
    o, d, tmin, tmax = shuffled_families(tris, 600)
    ro, rd = workloads.random_rays(tris, 20_000, seed=3)
    o, d = np.concatenate([o, ro]), np.concatenate([d, rd])
    tmax = np.concatenate([tmax, np.full(len(ro), np.inf, np.float32)])
    assert orders(o, d)
    tree = build(tris, method)
    hits = tree.intersect(o, d, tmax=tmax, counters=False, ray_order="spatial", threads=2)
    assert_same(hits, tree.intersect(o, d, tmax=tmax), f"{scene} {method}")
    ref = oracle.EmbreeTracer(tris).intersect(o, d, tmax=tmax)
    c = oracle.compare(hits, ref, triangles=tris, origins=o, directions=d, tmax=tmax)
    assert len(c["failing"]) == 0, (scene, method, len(c["failing"]))
    assert len(oracle.leaks(hits, ref, triangles=tris, origins=o, directions=d,
                            tmax=tmax)) == 0, (scene, method)


def test_a_batch_of_two_windows_comes_back_in_the_callers_order():
    """More rays than one window (ray_order.hpp sorts at most kOrderWindow at
    a time): each window's hits go back to its own rays, per-ray limits
    included."""
    tris = load_scene("gen:room")
    tree = bsplab.build(tris, "kd")
    o, d = workloads.random_rays(tris, WINDOW + 5000, seed=11)
    rng = np.random.default_rng(11)
    tmax = rng.uniform(0.5, 8.0, len(o)).astype(np.float32)
    assert orders(o, d) and orders(o[WINDOW:], d[WINDOW:])
    counted = tree.intersect(o, d, tmax=tmax)
    assert 0 < (counted["prim"] >= 0).sum() < len(o)
    assert_same(tree.intersect(o, d, tmax=tmax, counters=False, ray_order="spatial", threads=2),
                counted,
                "two windows")


def test_only_incoherent_batches_are_sorted():
    """Camera rays (pixel or tile order) and rays cast from a camera's hits
    in pixel order (ambient occlusion) trace as they come: they are already
    coherent, and sorting them measured slower. Random rays, and random
    rays lying along the axes, are sorted; so are shuffled secondary rays.
    Fewer than kOrderMinRays rays are not."""
    tris = load_scene("gen:room")
    cam = workloads.framing_camera(tris)
    for order in ("image", "tiles"):
        assert not orders(*cam.rays(128, 128, order=order)), order
    po, pd = cam.rays(128, 128, order="image")
    hits = oracle.EmbreeTracer(tris).intersect(po, pd)
    ao, ad = workloads.ambient_occlusion_rays(tris, po, pd, hits)
    assert len(ao) >= MIN_RAYS and not orders(ao, ad), "ambient occlusion in pixel order"
    perm = np.random.default_rng(2).permutation(len(ao))
    assert orders(ao[perm], ad[perm]), "shuffled ambient occlusion rays"
    ro, rd = workloads.random_rays(tris, MIN_RAYS, seed=4)
    assert orders(ro, rd)
    assert not orders(ro[:-1], rd[:-1]), "one ray short of kOrderMinRays"
    axis = np.zeros_like(rd)
    axis[np.arange(len(rd)), np.random.default_rng(5).integers(0, 3, len(rd))] = 1.0
    assert orders(ro, axis)
    # One origin for all (a point light's shadow rays, a camera's): coherent.
    assert not orders(np.zeros_like(ro), rd)


def box_rays(lo, hi, scale: float, n: int, seed: int):
    """Random rays from a box `scale` times the given one about its centre."""
    c, r = (lo + hi) / 2, (hi - lo) / 2
    rng = np.random.default_rng(seed)
    o = rng.uniform(c - scale * r, c + scale * r, (n, 3)).astype(np.float32)
    d = rng.normal(size=(n, 3))
    return o, (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)


def test_auto_order_sorts_only_batches_whose_walks_pay():
    """ray_order="auto" (the default) sorts an incoherent batch only when a
    probe of its rays walks at least 8 nodes a ray (ray_order.hpp's
    kOrderMinSteps; 4 on one thread, below): random rays in the room's box walk about 23, rays from
    a box ten times its size mostly miss the room and walk less than one,
    too few for the sort to pay. Both batches are incoherent ("spatial"
    sorts both), and every order gives the same hits. A BVH never sorts."""
    tris = load_scene("gen:room")
    tree = bsplab.build(tris, "kd")
    lo, hi = workloads.bounds(tris)
    for scale, walks in ((1.0, True), (10.0, False)):
        o, d = box_rays(lo, hi, scale, MIN_RAYS + 100, seed=21)
        assert orders(o, d), scale
        counted = tree.intersect(o, d)
        assert (counted["steps"].mean() >= 8) == walks, (scale, counted["steps"].mean())
        assert bsplab._core.orders_rays(o, d, tree._tree, threads=2) == walks, scale
        for order in ("auto", "spatial", "given"):
            assert_same(tree.intersect(o, d, counters=False, ray_order=order, threads=2),
                        counted, f"{order} order, box x {scale}")
        if walks:
            assert not bsplab._core.orders_rays(o, d, bsplab.build(tris, "bvh")._tree)


def test_auto_order_in_an_instanced_scene():
    """The same in two levels, where the probe's walk is the top level's and
    the mesh trees' steps together and the bar is 16
    (kOrderMinInstancedSteps; 8 on one thread); a scene of BVH mesh trees never sorts."""
    it = build_world("touching", "kd")
    root = it.top_boxes(max_depth=0)
    for scale, walks in ((1.0, True), (10.0, False)):
        o, d = box_rays(root["lo"][0], root["hi"][0], scale, MIN_RAYS + 100, seed=23)
        assert orders(o, d), scale
        counted = it.intersect(o, d)
        walk = (counted["steps"] + counted["top_steps"]).mean()
        assert (walk >= 16) == walks, (scale, walk)
        assert bsplab._core.orders_instanced_rays(it._scene, o, d, threads=2) == walks, scale
        for order in ("auto", "spatial", "given"):
            assert_same_instanced(it.intersect(o, d, counters=False, ray_order=order),
                                  counted, f"{order} order, box x {scale}")
        if walks:
            bvh = build_world("touching", "bvh")
            assert not bsplab._core.orders_instanced_rays(bvh._scene, o, d)


def test_auto_order_halves_its_bar_on_one_thread():
    """On one thread the bars are 4 and 8 steps a ray (ray_order.hpp's
    kOrderMinStepsOneThread, kOrderMinInstancedStepsOneThread): the sort
    runs on one thread whatever the trace's count, so beside a one-thread
    trace it pays for shorter walks. Rays from a box twice the room's walk
    about 4.6 nodes, and rays from 1.5 times the touching world's box about
    9 (top level and mesh trees): sorted on one thread, not on two, with
    the same hits either way."""
    tris = load_scene("gen:room")
    tree = bsplab.build(tris, "kd")
    lo, hi = workloads.bounds(tris)
    o, d = box_rays(lo, hi, 2.0, MIN_RAYS + 100, seed=21)
    counted = tree.intersect(o, d)
    assert 4 <= counted["steps"].mean() < 8, counted["steps"].mean()
    assert bsplab._core.orders_rays(o, d, tree._tree, threads=1)
    assert not bsplab._core.orders_rays(o, d, tree._tree, threads=2)
    for threads in (1, 2):
        assert_same(tree.intersect(o, d, counters=False, threads=threads), counted,
                    f"auto order, {threads} threads")

    it = build_world("touching", "kd")
    root = it.top_boxes(max_depth=0)
    o, d = box_rays(root["lo"][0], root["hi"][0], 1.5, MIN_RAYS + 100, seed=23)
    counted = it.intersect(o, d)
    walk = (counted["steps"] + counted["top_steps"]).mean()
    assert 8 <= walk < 16, walk
    assert bsplab._core.orders_instanced_rays(it._scene, o, d, threads=1)
    assert not bsplab._core.orders_instanced_rays(it._scene, o, d, threads=2)
    for threads in (1, 2):
        assert_same_instanced(it.intersect(o, d, counters=False, threads=threads), counted,
                              f"auto order, {threads} threads")


def test_ray_order_is_checked():
    tris = load_scene("gen:room")
    tree = bsplab.build(tris, "kd")
    o, d = workloads.random_rays(tris, 10)
    with pytest.raises(ValueError, match="ray_order must be one of 'auto', 'spatial', 'given'"):
        tree.intersect(o, d, counters=False, ray_order="sorted")


def test_a_sorted_batch_reports_progress_and_can_be_cancelled():
    tris = load_scene("gen:room")
    tree = bsplab.build(tris, "kd")
    o, d = workloads.random_rays(tris, 3 * MIN_RAYS, seed=6)
    assert orders(o, d)
    p = bsplab.Progress()
    hits = tree.intersect(o, d, counters=False, ray_order="spatial", progress=p)
    assert_same(hits, tree.intersect(o, d), "with progress")
    assert p.value == pytest.approx(1.0, abs=1e-3)
    cancelled = bsplab.Progress()
    cancelled.cancel()
    with pytest.raises(bsplab.Cancelled):
        tree.intersect(o, d, counters=False, ray_order="spatial", progress=cancelled)


# Instanced scenes (InstancedTree.intersect): the single-ray hits-only path
# sorts an incoherent batch too (unless every mesh tree is a BVH), and
# writes each ray's instance back with its hit.

@functools.lru_cache(maxsize=None)
def world_families(world: str):
    """The shuffled families of a world's flattened scene (made once: the
    transformed world flattens to 278,280 triangles)."""
    meshes, idx, mats = instanced_scenes.TEST_SCENES[world]()
    return shuffled_families(instanced_scenes.flatten(meshes, idx, mats), 400)


def build_world(world: str, method: str):
    meshes, idx, mats = instanced_scenes.TEST_SCENES[world]()
    options = {"k": 4} if "k" in bsplab.methods()[method]["params"] else {}
    return bsplab.build_instanced(meshes, idx, mats, method, **options)


def assert_same_instanced(a: dict, b: dict, what: str) -> None:
    assert_same(a, b, what)
    assert np.array_equal(a["instance"], b["instance"]), what
    assert np.array_equal(a["flat_prim"], b["flat_prim"]), what


# Every method on the touching cubes (shared faces, edges and corners
# between instances); three on the transformed world (rotations, mirrors,
# shears; a large fan).
INSTANCED_CASES = ([("touching", m) for m in METHODS] +
                   [("transformed", m) for m in ("kd", "bsp_wn+kd", "bvh")])


@pytest.mark.parametrize("world,method", INSTANCED_CASES)
def test_spatial_order_in_an_instanced_scene_gives_the_counting_paths_hits(world, method):
    it = build_world(world, method)
    o, d, tmin, tmax = world_families(world)
    assert len(o) >= MIN_RAYS and orders(o, d), "the batch must take the sorted path"
    counted = it.intersect(o, d, tmin=tmin, tmax=tmax)
    assert (counted["instance"] >= 0).sum() > len(o) // 10, "too few hits to tell anything"
    assert len(np.unique(counted["instance"])) > 4, "hits on too few instances"
    for threads in (1, 2):
        assert_same_instanced(it.intersect(o, d, tmin=tmin, tmax=tmax, counters=False,
                                           ray_order="spatial", threads=threads),
                              counted, f"{world} {method} spatial order, {threads} threads")
    assert_same_instanced(it.intersect(o, d, tmin=tmin, tmax=tmax, counters=False,
                                       ray_order="given"),
                          counted, f"{world} {method} given order")
    counted = it.intersect(o, d, tmax=2.0)
    assert_same_instanced(it.intersect(o, d, tmax=2.0, counters=False, ray_order="spatial"),
                          counted,
                          f"{world} {method} spatial order, one tmax")


def test_an_instanced_batch_of_two_windows_comes_back_in_the_callers_order():
    it = build_world("transformed", "kd")
    flat = it.flatten()
    o, d = workloads.random_rays(flat, WINDOW + 5000, seed=12)
    tmax = np.random.default_rng(12).uniform(0.5, 6.0, len(o)).astype(np.float32)
    assert orders(o, d) and orders(o[WINDOW:], d[WINDOW:])
    counted = it.intersect(o, d, tmax=tmax)
    assert 0 < (counted["instance"] >= 0).sum() < len(o)
    assert_same_instanced(it.intersect(o, d, tmax=tmax, counters=False, ray_order="spatial",
                                       threads=2), counted, "two windows")


def test_an_instanced_sorted_batch_reports_progress_and_can_be_cancelled():
    it = build_world("transformed", "bsp_wn+kd")
    o, d = workloads.random_rays(it.flatten(), 3 * MIN_RAYS, seed=13)
    assert orders(o, d)
    p = bsplab.Progress()
    assert_same_instanced(it.intersect(o, d, counters=False, ray_order="spatial", progress=p),
                          it.intersect(o, d), "with progress")
    assert p.value == pytest.approx(1.0, abs=1e-3)
    cancelled = bsplab.Progress()
    cancelled.cancel()
    with pytest.raises(bsplab.Cancelled):
        it.intersect(o, d, counters=False, ray_order="spatial", progress=cancelled)
    with pytest.raises(ValueError, match="ray_order must be one of 'auto', 'spatial', 'given'"):
        it.intersect(o, d, counters=False, ray_order="sorted")

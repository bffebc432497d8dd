"""Rays lying in split planes take the in-plane walk
(core/src/trace/kernels/in_plane.hpp): below a node whose plane the ray lies
in, the flat child of a later node along the same plane is skipped.

The generated fan scene has a floor fan of 4,096 slivers in the plane z = 0,
which the builders isolate in flat cells (half of bsp_ize+kd's leaves); a ray
lying in the floor walked every one of them (2,411 steps per floor ray for
bsp_ize+kd, where the same rays 1e-4 above and below the floor took 870 and
173). Checked here: the in-plane walk costs no more than the two shifted
copies of each ray together, its hits are Embree's (no leaks), and every path
(culling, counters, threads, packets, trace_path) gives its answer."""

from __future__ import annotations

import functools

import numpy as np
import pytest

import bsplab
from bsplab import oracle, ray_families, scenes

from test_paths_agree import check_paths

# Methods whose trees split along the floor's plane as kd nodes (kd, ^Kd),
# as general nodes (bsp_ize, bsp_wn: the axis planes are general there) and
# both.
METHODS = ["kd", "rbsp", "bsp_random+", "bsp_wn", "bsp_wn+kd", "bsp_ize", "bsp_ize+kd"]
SHIFT = 1e-4  # the shifted copies' distance from the floor


@pytest.fixture(scope="module")
def fan():
    return scenes.generate("fan")


def floor_rays(n: int, seed: int = 3):
    """Rays lying exactly in the floor plane z = 0, through the floor fan
    (radius 4 about the origin) from outside it, most near its centre where
    the slivers meet."""
    rng = np.random.default_rng(seed)
    ang = rng.uniform(0, 2 * np.pi, n)
    start = np.stack([6 * np.cos(ang), 6 * np.sin(ang), np.zeros(n)], axis=1)
    target = np.concatenate([rng.uniform(-0.3, 0.3, (n, 2)), np.zeros((n, 1))], axis=1)
    d = target - start
    return start.astype(np.float32), d.astype(np.float32)


def build(tris, method):
    kw = {"k": 4} if "k" in bsplab.methods()[method]["params"] else {}
    return bsplab.build(tris, method=method, **kw)


@functools.lru_cache(maxsize=None)
def fan_tree(method):
    """The fan's tree, built once for both tests of a method (tracing does
    not change a tree): the build was most of each case's time, 3-7 s under
    ASan + UBSan for the BSP methods."""
    return build(scenes.generate("fan"), method)


@pytest.mark.parametrize("method", METHODS)
def test_floor_rays_cost_no_more_than_their_shifted_copies(method):
    tree = fan_tree(method)
    o, d = floor_rays(400)
    assert (o[:, 2] == 0).all() and (d[:, 2] == 0).all()
    in_plane = tree.intersect(o, d)["steps"].astype(np.int64)
    shifted = 0
    for dz in (SHIFT, -SHIFT):
        oo = o.copy()
        oo[:, 2] = dz
        shifted = shifted + tree.intersect(oo, d)["steps"].astype(np.int64)
    # Per ray the in-plane walk may visit the cells on both sides (and the
    # box of cells the two copies leave at different depths); over the
    # family it must not walk the flat cells' subtrees on top.
    assert in_plane.sum() <= shifted.sum(), (method, in_plane.mean(), shifted.mean())


@pytest.mark.parametrize("method", METHODS)
def test_in_plane_rays_agree_with_embree_and_on_every_path(fan, method):
    if not oracle.available():
        pytest.skip("embreex is not installed")
    tree = fan_tree(method)
    o1, d1 = floor_rays(300)
    o2, d2, _ = ray_families.family("in_planes", fan, 300, seed=4)
    o3, d3, _ = ray_families.family("along_edges", fan, 300, seed=4)
    o = np.concatenate([o1, o2, o3])
    d = np.concatenate([d1, d2, d3])
    tmax = np.full(len(o), np.inf, np.float32)
    check_paths(tree, o, d, tmax, f"fan {method} in-plane", trace_paths=12)
    ours = tree.intersect(o, d)
    ref = oracle.EmbreeTracer(fan).intersect(o, d)
    leaks = oracle.leaks(ours, ref, triangles=fan, origins=o, directions=d)
    assert len(leaks) == 0, (method, leaks[:8])


def test_rays_in_a_face_plane_of_the_scene_box():
    """A closed box whose top face is the scene box's face: rays lying in
    that plane start the walk on its inner side (the flat cell above the
    box's top is skipped from the root), and still hit the box's walls where
    they cross them."""
    verts, faces = scenes._box((0.0, 0.0, 0.0), (2.0, 2.0, 2.0), n=4)
    tris = verts[faces].astype(np.float32)
    top = float(tris[..., 2].max())
    rng = np.random.default_rng(9)
    n = 400
    o = np.concatenate([rng.uniform(-3, 3, (n, 2)), np.full((n, 1), top)], axis=1)
    d = np.concatenate([rng.normal(size=(n, 2)), np.zeros((n, 1))], axis=1)
    o, d = o.astype(np.float32), d.astype(np.float32)
    tmax = np.full(n, np.inf, np.float32)
    ref = oracle.EmbreeTracer(tris).intersect(o, d) if oracle.available() else None
    for method in ("kd", "bsp_ize", "bsp_wn+kd"):
        tree = build(tris, method)
        check_paths(tree, o, d, tmax, f"box top {method}", trace_paths=12)
        if ref is not None:
            ours = tree.intersect(o, d)
            assert len(oracle.leaks(ours, ref, triangles=tris, origins=o, directions=d)) == 0

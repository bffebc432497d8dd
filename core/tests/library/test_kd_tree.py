"""The kd-tree's statistics, ray ranges, degenerate input and options."""

from __future__ import annotations

import numpy as np
import pytest

import bsplab
from bsplab import oracle, scenes, workloads


def brute_force(tris, o, d, tmin, tmax):
    """Closest hit over all triangles in double precision (Moller-Trumbore)."""
    T = tris.astype(np.float64)
    e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
    best_t = np.full(len(o), np.inf)
    best_p = np.full(len(o), -1)
    for i in range(len(o)):
        D = d[i].astype(np.float64)
        p = np.cross(D, e2)
        det = (e1 * p).sum(1)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = o[i] - T[:, 0]
            u = (s * p).sum(1) / det
            q = np.cross(s, e1)
            v = (D * q).sum(1) / det
            t = (e2 * q).sum(1) / det
        ok = (det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > tmin[i]) & (t < tmax[i])
        if ok.any():
            j = np.flatnonzero(ok)[np.argmin(t[ok])]
            best_t[i], best_p[i] = t[j], j
    return best_t, best_p


def test_stats_are_consistent():
    tris = scenes.generate("room")
    tree = bsplab.build(tris)
    s = tree.stats
    assert s["triangles"] == len(tris)
    assert s["nodes"] == s["interior_nodes"] + s["leaves"]
    assert s["leaves"] == s["interior_nodes"] + 1  # a full binary tree
    assert s["references"] >= s["triangles"] - s["degenerate"]
    assert s["duplication"] == pytest.approx(s["references"] / (s["triangles"] - s["degenerate"]))
    assert 0 < s["max_depth"] <= s["depth_limit"]
    assert s["bytes"] >= 8 * s["nodes"] + 36 * s["triangles"]
    assert s["node_bytes"] == 8 * s["nodes"]
    assert s["sah_cost"] > 0 and s["build_seconds"] > 0
    assert s["max_leaf_size"] >= s["mean_leaf_size"] > 0


def test_tmin_and_tmax_are_respected():
    tris = scenes.generate("room")
    o, d = workloads.random_rays(tris, 300, seed=11)
    rng = np.random.default_rng(5)
    full = bsplab.build(tris).intersect(o, d)
    # Ranges that cut around the first hit, so the answer must change.
    finite = np.where(np.isfinite(full["t"]), full["t"], 10.0)
    tmin = (finite * rng.uniform(0.5, 1.5, len(o))).astype(np.float32)
    tmax = (tmin + finite * rng.uniform(0.1, 3.0, len(o))).astype(np.float32)
    tree = bsplab.build(tris)
    hits = tree.intersect(o, d, tmin=tmin, tmax=tmax)
    hit = hits["prim"] >= 0
    assert (hits["t"][hit] > tmin[hit]).all() and (hits["t"][hit] < tmax[hit]).all()
    bt, bp = brute_force(tris, o, d, tmin, tmax)
    agree = (hits["prim"] == bp) | (np.isclose(hits["t"], bt, rtol=1e-4))
    assert agree.mean() > 0.995, np.flatnonzero(~agree)
    assert hits["prim"][~hit].size == 0 or (hits["prim"][~hit] == -1).all()
    # A range that excludes everything gives no hits.
    none = tree.intersect(o, d, tmin=0.0, tmax=1e-9)
    assert (none["prim"] == -1).all()


def test_tmax_matches_embree():
    pytest.importorskip("embreex")
    tris = scenes.generate("spheres")
    o, d = workloads.random_rays(tris, 20_000, seed=2)
    tmax = np.float32(3.0)
    ours = bsplab.build(tris).intersect(o, d, tmax=tmax)
    ref = oracle.EmbreeTracer(tris).intersect(o, d, tmax=tmax)
    c = oracle.compare(ours, ref, triangles=tris, origins=o, directions=d)
    assert len(c["failing"]) == 0
    assert (ours["t"][ours["prim"] >= 0] < 3.0).all()


def test_degenerate_triangles_are_counted_and_never_hit():
    tris = scenes.generate("room").copy()
    n = len(tris)
    # Zero-area: a point and a segment, placed where rays will pass.
    lo, hi = workloads.bounds(tris)
    c = ((lo + hi) / 2).astype(np.float32)
    point = np.stack([c, c, c])
    segment = np.stack([c - 1, c, c + 1])
    tris = np.concatenate([tris, point[None], segment[None]]).astype(np.float32)
    tree = bsplab.build(tris)
    assert tree.stats["degenerate"] == 2
    o = np.repeat(c[None] + np.float32([0, 0, 0.5]), 64, axis=0)
    d = np.random.default_rng(0).normal(size=(64, 3)).astype(np.float32)
    hits = tree.intersect(o, d)
    assert not np.isin(hits["prim"], [n, n + 1]).any()


def test_vertices_and_indices_input_equals_triangle_input():
    v, f = scenes.generate_mesh("room")
    a = bsplab.build((v, f))
    b = bsplab.build(v[f])
    assert a.node_bytes() == b.node_bytes()
    np.testing.assert_array_equal(a.triangles, b.triangles)


def test_float64_input_is_accepted():
    tris = scenes.generate("room")
    a = bsplab.build(tris.astype(np.float64))
    assert a.node_bytes() == bsplab.build(tris).node_bytes()


def test_cost_options_change_the_tree():
    tris = scenes.generate("spheres")
    cheap = bsplab.build(tris, intersect_cost=0.5)
    dear = bsplab.build(tris, intersect_cost=8.0)
    assert dear.stats["nodes"] > cheap.stats["nodes"]
    shallow = bsplab.build(tris, max_depth=4)
    assert shallow.stats["max_depth"] <= 4
    big_leaves = bsplab.build(tris, leaf_size=64)
    assert big_leaves.stats["nodes"] < cheap.stats["nodes"] or big_leaves.stats["mean_leaf_size"] > 1


def test_duplication_bound_holds():
    tris = scenes.generate("fan")
    tree = bsplab.build(tris, max_duplication=1.5, intersect_cost=50.0)
    assert tree.stats["references"] <= 1.5 * len(tris)


def test_memory_limit_raises():
    tris = scenes.generate("spheres")
    with pytest.raises(MemoryError):
        bsplab.build(tris, memory_limit_mb=0.01)


def test_single_triangle_and_flat_scene():
    tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], np.float32)
    tree = bsplab.build(tri)
    hits = tree.intersect([[0.2, 0.2, 1.0], [2, 2, 1]], [[0, 0, -1], [0, 0, -1]])
    assert hits["prim"].tolist() == [0, -1]
    assert hits["t"][0] == pytest.approx(1.0)
    assert hits["u"][0] == pytest.approx(0.2) and hits["v"][0] == pytest.approx(0.2)
    # A ray lying in the plane of the (flat) scene.
    grid = scenes.generate_mesh("room")  # any mesh; flatten it to z = 0
    v, f = grid
    v = v.copy()
    v[:, 2] = 0
    flat = bsplab.build((v, f))
    assert flat.stats["nodes"] >= 1
    h = flat.intersect([[0.1, 0.1, 5.0]], [[0.01, 0.02, -1.0]])
    assert h["prim"][0] >= 0

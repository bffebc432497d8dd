"""The BSP family: the method table, options, ^Kd nodes, per-level
statistics and seeds. (The cells' surface areas are C++ unit tests:
cpp_tests/test_cell.cpp.)"""

from __future__ import annotations

import numpy as np
import pytest

import bsplab
from bsplab import scenes

METHODS = bsplab.methods()
# The BSP family: every method of split planes but kd (the BVH has boxes: test_bvh.py).
FAMILY = [m for m in METHODS if m != "kd" and METHODS[m]["structure"] != "bvh"]


@pytest.fixture(scope="module")
def room():
    return scenes.generate("room")


def test_the_table_names_the_whole_family():
    for name in ("kd", "rbsp", "rbsp+kd", "bsp_random", "bsp_random+", "bsp_random+kd",
                 "bsp_wn", "bsp_wn+", "bsp_wn+kd", "bsp_cn", "bsp_cn+", "bsp_cn+kd",
                 "bsp_ize", "bsp_ize+kd"):
        assert name in METHODS, name
    for name, info in METHODS.items():
        assert info["kd_nodes"] == name.endswith("+kd")
        if "k" in info["params"]:
            assert info["min_k"] == (3 if info["plus_axes"] else 1)


@pytest.mark.parametrize("method", FAMILY)
def test_node_kinds_follow_the_kd_variant(room, method):
    s = bsplab.build(room, method=method).stats
    assert s["interior_nodes"] == s["kd_nodes"] + s["general_nodes"]
    if METHODS[method]["kd_nodes"]:
        assert s["kd_nodes"] > 0  # the room is full of axis-aligned planes
    else:
        assert s["kd_nodes"] == 0 and s["general_nodes"] > 0
    assert s["plane_bytes"] == 16 * s["general_nodes"]
    # Nodes, planes, triangles, culling boxes and the reference array (one-triangle leaves
    # keep their triangle inline, so at most one reference per leaf entry).
    rest = (s["bytes"] - 8 * s["nodes"] - 16 * s["general_nodes"] - 36 * s["triangles"]
            - s["box_bytes"])
    assert 0 <= rest <= 4 * s["references"] and rest % 4 == 0


@pytest.mark.parametrize("method", ["kd", "rbsp", "bsp_random", "bsp_wn+kd", "bsp_ize"])
def test_level_statistics(room, method):
    s = bsplab.build(room, method=method).stats
    planes, dirs = s["level_planes"], s["level_directions"]
    assert sum(planes) == s["interior_nodes"]
    assert len(planes) == len(dirs) and len(planes) <= s["max_depth"]
    assert all(0 < d <= p for p, d in zip(planes, dirs))
    assert planes[0] == 1
    if method == "kd":
        assert max(dirs) <= 3
    if method == "rbsp":
        assert max(dirs) <= 13  # the fixed set
    if method == "bsp_random":
        # Fresh random directions at every node: nearly all distinct.
        assert sum(dirs) > 0.9 * sum(planes)


def test_rbsp_uses_its_fixed_set(room):
    dop = bsplab.build(room, method="rbsp", k=7, rbsp_set="dop").stats
    spiral = bsplab.build(room, method="rbsp", k=7, rbsp_set="spiral").stats
    assert max(dop["level_directions"]) <= 7 and max(spiral["level_directions"]) <= 7
    a = bsplab.build(room, method="rbsp", k=7, rbsp_set="dop").node_bytes()
    assert a != bsplab.build(room, method="rbsp", k=7, rbsp_set="spiral").node_bytes()


def test_rbsp_kd_has_kd_nodes_at_every_k(room):
    # auto without a k-DOP set: the axes plus K - 3 spiral points, so the
    # room's walls still get (fast) kd nodes; the pure spiral has no axis.
    for k in (4, 6, 10):
        auto = bsplab.build(room, method="rbsp+kd", k=k).stats
        assert auto["kd_nodes"] > 0, k
        assert max(auto["level_directions"]) <= k
    assert auto["general_nodes"] > 0  # K = 10: seven spiral directions to choose from
    assert bsplab.build(room, method="rbsp+kd", k=6, rbsp_set="spiral").stats["kd_nodes"] == 0


@pytest.mark.parametrize("method", ["bsp_random", "bsp_wn+", "bsp_cn+kd", "bsp_ize"])
def test_seed_decides_the_tree(room, method):
    a = bsplab.build(room, method=method, seed=1).node_bytes()
    assert a == bsplab.build(room, method=method, seed=1).node_bytes()
    assert a != bsplab.build(room, method=method, seed=2).node_bytes()


def test_more_directions_find_cheaper_trees():
    tris = scenes.generate("spheres")
    costs = [bsplab.build(tris, method="bsp_random+", k=k).stats["sah_cost"] for k in (3, 9)]
    assert costs[1] < costs[0]


def test_kd_variant_costs_change_the_tree(room):
    cheap = bsplab.build(room, method="bsp_wn+kd", alpha=0.0, general_cost=1.0).stats
    dear = bsplab.build(room, method="bsp_wn+kd", alpha=10.0, general_cost=100.0).stats
    assert dear["general_nodes"] < cheap["general_nodes"]


@pytest.mark.parametrize("method, options, exc, words", [
    ("bsp_wn", {"k": 0}, ValueError, "k must be"),
    ("bsp_wn", {"k": 65}, ValueError, "k must be"),
    ("bsp_wn+", {"k": 2}, ValueError, "axes"),
    ("bsp_cn+kd", {"k": 1.5}, ValueError, "whole"),
    ("bsp_magic", {}, ValueError, "unknown method"),
    ("bsp_wn+kd", {"alpha": -0.1}, ValueError, "alpha"),
    ("bsp_wn+kd", {"general_cost": 0}, ValueError, "general_cost"),
    ("rbsp", {"k": 5, "rbsp_set": "dop"}, ValueError, "K = 3, 7, 9 or 13"),
    ("rbsp", {"rbsp_set": "cube"}, ValueError, "rbsp_set"),
    ("kd", {"k": 4}, TypeError, "unknown build option"),
    ("bsp_wn", {"alpha": 0.1}, TypeError, "unknown build option"),
    ("bsp_random", {"seed": -1}, ValueError, "seed"),
])
def test_bad_bsp_options(room, method, options, exc, words):
    with pytest.raises(exc, match=words):
        bsplab.build(room, method=method, **options)


def test_bsp_memory_limit_raises(room):
    with pytest.raises(MemoryError):
        bsplab.build(room, method="bsp_wn+kd", memory_limit_mb=0.01)


def test_cancel_stops_a_bsp_build():
    p = bsplab.Progress()
    p.cancel()
    with pytest.raises(bsplab.Cancelled):
        bsplab.build(scenes.generate("spheres"), method="bsp_cn+kd", progress=p)

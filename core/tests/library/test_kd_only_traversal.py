"""The kd-only traversal (single_ray.hpp: trace_one with kGeneral = false).

A tree without general nodes is traced by an instantiation that takes every
interior node for a kd node. kd trees always take it; a ^Kd BSP tree takes it
when its builder happened to choose only axis planes (the axis-aligned "grids"
scene with bsp_wn+kd). Its hits must agree with Embree's on every path: with
and without counters, with and without leaf culling."""

from __future__ import annotations

import numpy as np
import pytest

import bsplab
from bsplab import oracle, ray_families, scenes, workloads

from test_agreement import check_agreement

pytest.importorskip("embreex", reason="embreex is the oracle")


def rays(tris):
    # The families' rays without their tmax, as test_ray_families compares
    # them with Embree (whose range ends differently at exactly t = tmax).
    parts = [ray_families.family(f, tris, 400, 3) for f in ray_families.FAMILIES]
    o, d, _ = (np.concatenate(x) for x in zip(*parts))
    po, pd = workloads.primary_rays(tris, 64, 64)
    ro, rd = workloads.random_rays(tris, 5000, seed=3)
    return [("families", o, d), ("primary", po, pd), ("random", ro, rd)]


@pytest.mark.parametrize("scene, method", [("grids", "bsp_wn+kd"), ("room", "kd"),
                                           ("tilted", "kd")])
@pytest.mark.parametrize("counters", [False, True])
@pytest.mark.parametrize("cull", [False, True])
def test_trees_without_general_nodes_agree_with_embree(scene, method, counters, cull):
    tris = scenes.generate(scene)
    tree = bsplab.build(tris, method=method)
    # Otherwise this test would not exercise the kd-only traversal.
    assert tree.stats["general_nodes"] == 0 and tree.stats["kd_nodes"] > 0
    emb = oracle.EmbreeTracer(tris)
    for name, o, d in rays(tris):
        hits = tree.intersect(o, d, cull=cull, counters=counters, threads=1)
        ref = emb.intersect(o, d)
        if name == "families":
            # Grazing rays are what some families are made of: they may go
            # either way, every other ray must agree.
            c = oracle.compare(hits, ref, triangles=tris, origins=o, directions=d)
            assert len(c["failing"]) == 0, (name, c["failing"][:5])
        else:
            c = check_agreement(tris, o, d, hits, ref)
            assert c["same_prim"] > 0.2 * len(o), (name, c["same_prim"])

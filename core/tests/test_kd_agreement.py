"""Every kd-tree hit must agree with Embree's closest hit on the same rays."""

from __future__ import annotations

import numpy as np
import pytest

import bsplab
from bsplab import oracle, workloads

embreex = pytest.importorskip("embreex", reason="embreex is the oracle")

N_RAYS = 100_000
SIDE = 317  # 317^2 = 100,489 primary rays


def check_agreement(tris, origins, directions, hits):
    ref = oracle.EmbreeTracer(tris).intersect(origins, directions)
    c = oracle.compare(hits, ref, triangles=tris, origins=origins, directions=directions)
    assert len(c["unexplained"]) == 0, (
        f"{len(c['unexplained'])} rays disagree with Embree, e.g. ray "
        f"{c['unexplained'][:5]}: ours prim {hits['prim'][c['unexplained'][:5]]} "
        f"t {hits['t'][c['unexplained'][:5]]}, Embree prim {ref['prim'][c['unexplained'][:5]]} "
        f"t {ref['t'][c['unexplained'][:5]]}")
    # Grazing rays (within a few ulps of an edge) may go either way, but rarely.
    assert c["grazing"] <= max(2, len(origins) // 20_000), c["grazing"]
    return c


@pytest.fixture(scope="module")
def trees():
    cache = {}

    def get(scene_id, tris):
        if scene_id not in cache:
            cache.clear()  # one big tree alive at a time
            cache[scene_id] = bsplab.build(tris, method="kd")
        return cache[scene_id]
    return get


def test_primary_rays_agree_with_embree(scene, trees):
    scene_id, tris = scene
    tree = trees(scene_id, tris)
    o, d = workloads.primary_rays(tris, SIDE, SIDE)
    hits = tree.intersect(o, d)
    c = check_agreement(tris, o, d, hits)
    assert c["same_prim"] > 0.2 * len(o) or scene_id.startswith("gen:fan")


def test_random_rays_agree_with_embree(scene, trees):
    scene_id, tris = scene
    tree = trees(scene_id, tris)
    o, d = workloads.random_rays(tris, N_RAYS, seed=7)
    hits = tree.intersect(o, d)
    check_agreement(tris, o, d, hits)
    # Misses report the documented sentinels.
    miss = hits["prim"] < 0
    assert np.isinf(hits["t"][miss]).all()
    assert (hits["t"][~miss] > 0).all()


def test_results_identical_across_thread_counts(scene, trees):
    scene_id, tris = scene
    tree = trees(scene_id, tris)
    o, d = workloads.random_rays(tris, 20_000, seed=3)
    one = tree.intersect(o, d, threads=1)
    two = tree.intersect(o, d, threads=2)
    four = tree.intersect(o, d, threads=4)
    for key in one:
        np.testing.assert_array_equal(one[key], two[key], err_msg=key)
        np.testing.assert_array_equal(one[key], four[key], err_msg=key)


def test_build_is_deterministic_across_thread_counts():
    from bsplab import scenes
    tris = scenes.generate("spheres")
    a = bsplab.build(tris, threads=1)
    b = bsplab.build(tris, threads=2)
    assert a.node_bytes() == b.node_bytes()
    assert a.stats["references"] == b.stats["references"]

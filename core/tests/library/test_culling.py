"""Leaf culling with the ray segment's box: never loses the closest hit,
counts what it skips, and can be switched off per build and per trace."""

from __future__ import annotations

import numpy as np
import pytest

import bsplab
from bsplab import oracle, scenes, workloads

METHODS = list(bsplab.methods())


def grazing_rays(tris: np.ndarray, count: int, seed: int = 4):
    """Rays aimed exactly at triangle vertices and at points on edges, from
    random points in the scene box: the cases where a padded box is tight."""
    rng = np.random.default_rng(seed)
    pick = rng.integers(0, len(tris), count)
    a = rng.integers(0, 3, count)
    b = (a + 1) % 3
    w = np.where(rng.random(count) < 0.5, 0.0, rng.random(count))  # vertex or edge point
    target = (tris[pick, a] * (1 - w[:, None]) + tris[pick, b] * w[:, None]).astype(np.float64)
    lo, hi = workloads.bounds(tris)
    origins = rng.uniform(lo, hi, (count, 3))
    d = target - origins
    keep = np.linalg.norm(d, axis=1) > 1e-3 * np.linalg.norm(hi - lo)
    return origins[keep].astype(np.float32), d[keep].astype(np.float32)


@pytest.mark.parametrize("boxes", ["triangle", "clipped"])
@pytest.mark.parametrize("method", METHODS)
def test_culling_never_loses_the_closest_hit(method, boxes):
    # The room has walls and floors lying in split planes and furniture
    # standing on them; the rays graze vertices and edges.
    tris = scenes.generate("room")
    kw = {"k": 4} if "k" in bsplab.methods()[method]["params"] else {}
    tree = bsplab.build(tris, method=method, leaf_boxes=boxes, **kw)
    o, d = grazing_rays(tris, 20_000)
    on = tree.intersect(o, d, cull=True)
    off = tree.intersect(o, d, cull=False)
    # Culling only skips tests that cannot hit inside the leaf: the closest
    # distance is the same, bit for bit. Where two triangles tie at exactly
    # that distance (a ray through a shared vertex or edge), the first one
    # tested wins, and culling may change the order of the tests.
    np.testing.assert_array_equal(on["t"], off["t"])
    tie = on["prim"] != off["prim"]
    assert (on["prim"][tie] >= 0).all() and (off["prim"][tie] >= 0).all()
    # Each side's triangle really is hit there (on its boundary, at most a
    # few ulps outside, as the watertight test decides edges).
    for prim in (on["prim"][tie], off["prim"][tie]):
        dist, scale = oracle.edge_distance(tris, prim, o[tie], d[tie])
        assert (dist >= -8 * np.finfo(np.float32).eps * scale).all()
    if tree.structure == "bvh":  # its leaves' boxes are tight: cull is a no-op
        assert on["culled"].sum() == off["culled"].sum() == 0
    else:
        assert on["culled"].sum() > 0 and off["culled"].sum() == 0
    assert on["tests"].sum() <= off["tests"].sum()
    if oracle.available():
        ref = oracle.EmbreeTracer(tris).intersect(o, d)
        c = oracle.compare(on, ref, triangles=tris, origins=o, directions=d)
        assert len(c["failing"]) == 0


@pytest.mark.parametrize("scene_id", ["gen:spheres", "gen:fan", "shared:sponza_dabrovic"])
@pytest.mark.parametrize("method", ["kd", "bsp_wn+kd", "bsp_ize"])
def test_clipped_boxes_agree_with_embree(scene_id, method):
    pytest.importorskip("embreex")
    from conftest import SCENE_IDS, load_scene
    if scene_id not in SCENE_IDS:
        pytest.skip(f"{scene_id} is not available here")
    tris = load_scene(scene_id)
    tree = bsplab.build(tris, method=method, leaf_boxes="clipped")
    emb = oracle.EmbreeTracer(tris)
    for o, d in (workloads.primary_rays(tris, 200, 200), workloads.random_rays(tris, 40_000)):
        hits = tree.intersect(o, d, cull=True)
        c = oracle.compare(hits, emb.intersect(o, d), triangles=tris, origins=o, directions=d)
        assert len(c["failing"]) == 0
        assert hits["culled"].sum() > 0


def test_box_kinds_cost_what_they_say():
    tris = scenes.generate("spheres")
    none = bsplab.build(tris, leaf_boxes="none").stats
    tri = bsplab.build(tris, leaf_boxes="triangle").stats
    clip = bsplab.build(tris, leaf_boxes="clipped").stats
    assert none["box_bytes"] == 0 and none["leaf_boxes"] == "none"
    assert tri["box_bytes"] == 24 * tri["triangles"]
    assert clip["box_bytes"] == 24 * clip["references"]
    assert tri["bytes"] - none["bytes"] == tri["box_bytes"]


def test_no_boxes_means_no_culling():
    tris = scenes.generate("room")
    tree = bsplab.build(tris, leaf_boxes="none")
    o, d = workloads.random_rays(tris, 5000)
    assert tree.intersect(o, d, cull=True)["culled"].sum() == 0


def test_clipped_boxes_cull_more_than_triangle_boxes():
    tris = scenes.generate("spheres")
    o, d = workloads.primary_rays(tris, 160, 120, scenes.default_camera("spheres"))
    culled = {b: bsplab.build(tris, leaf_boxes=b).intersect(o, d, cull=True)["culled"].sum()
              for b in ("triangle", "clipped")}
    assert culled["clipped"] > culled["triangle"]


def test_culling_is_off_unless_asked_for():
    tris = scenes.generate("spheres")
    tree = bsplab.build(tris)
    o, d = workloads.random_rays(tris, 5000)
    assert tree.intersect(o, d)["culled"].sum() == 0
    assert tree.intersect(o, d, cull=True)["culled"].sum() > 0
    cam = scenes.default_camera("spheres")
    assert bsplab.render(tree, cam, 32, 24, "heat_culled")[1]["cull"] is True
    # Shaded counts only when asked (its default is the hits-only path).
    shaded = bsplab.render(tree, cam, 32, 24, "shaded", counters=True)[1]
    assert shaded["cull"] is False and shaded["mean_culled"] == 0


def test_bad_culling_options():
    tris = scenes.generate("room")
    with pytest.raises(ValueError, match="leaf_boxes"):
        bsplab.build(tris, leaf_boxes="spheres")
    tree = bsplab.build(tris)
    with pytest.raises(TypeError, match="cull"):
        tree.intersect(np.zeros((1, 3)), np.ones((1, 3)), cull="yes")

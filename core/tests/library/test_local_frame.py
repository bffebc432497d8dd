"""The trees' local frame (core/src/frame.hpp): a scene far from the origin
is built and walked relative to a point near its centre, exactly; what the
tree gives back - triangles, bounds, the inspectors' geometry, trace_path -
is in the input's units. (Hits against Embree and the cost at 1e6:
test_ray_families.py's shifted tests.)"""

from __future__ import annotations

import numpy as np
import pytest

import bsplab
from bsplab import ray_families

from conftest import load_scene


def moved_room(shift: float):
    tris = load_scene("gen:room")
    (base, _), (moved, _), _, _ = ray_families.shifted("outside_camera", tris, 10, shift)
    return base, moved


def test_scenes_near_the_origin_keep_no_frame():
    """Within kFrameMinCentre of its sizes from the origin a scene is built
    as before the frame existed (the tree hashes pin its bytes)."""
    tris = load_scene("gen:room")
    assert bsplab.build(tris, method="kd").stats["offset"] == (0.0, 0.0, 0.0)
    size = float(np.ptp(tris.reshape(-1, 3), axis=0).max())
    near = (tris.astype(np.float64) + 3.0 * size).astype(np.float32)
    assert bsplab.build(near, method="kd").stats["offset"] == (0.0, 0.0, 0.0)


def test_only_the_far_axes_move():
    tris = load_scene("gen:room")
    far_x = (tris.astype(np.float64) + [1e6, 0.0, 0.0]).astype(np.float32)
    offset = bsplab.build(far_x, method="kd").stats["offset"]
    assert offset[0] != 0.0 and offset[1:] == (0.0, 0.0)


@pytest.mark.parametrize("method", ["kd", "bvh", "bsp_wn+kd"])
def test_a_moved_tree_gives_back_the_input_units(method):
    base, moved = moved_room(1e6)
    tree = bsplab.build(moved, method=method)
    origin_tree = bsplab.build(base, method=method)
    assert all(o != 0.0 for o in tree.stats["offset"])
    np.testing.assert_array_equal(tree.triangles, moved)
    pts = moved.reshape(-1, 3)
    assert tree.bounds == (tuple(float(x) for x in pts.min(0)),
                           tuple(float(x) for x in pts.max(0)))
    # The same walk as the origin copy's: the same hit, the same steps.
    centre = pts.astype(np.float64).mean(0)
    o = np.float32(centre + [0.0, 0.0, 3.0 * np.ptp(pts[:, 2])])
    d = np.array([0.01, 0.02, -1.0], np.float32)
    path = tree.trace_path(o, d)
    hit = tree.intersect(o[None], d[None])
    assert path["prim"] == hit["prim"][0] >= 0 and path["t"] == hit["t"][0]
    # The inspectors' geometry in world units.
    on_surface = moved[0].astype(np.float64).mean(0)
    assert tree.node_at(on_surface) is not None and tree.node_at(centre - 1e3) is None
    lo, hi = pts.min(0).astype(np.float64), pts.max(0).astype(np.float64)
    if tree.structure == "bvh":
        boxes = tree.node_boxes(0)
        np.testing.assert_array_equal(boxes["lo"][0], pts.min(0))
        np.testing.assert_array_equal(boxes["hi"][0], pts.max(0))
        assert np.isfinite(path["box_lo"]).all()
        assert (path["box_lo"] >= lo - 1e-3).all() and (path["box_hi"] <= hi + 1e-3).all()
        return
    polys = tree.split_polygons(3)
    v = polys["vertices"].astype(np.float64)
    assert len(v) and (v >= lo - 1e-3).all() and (v <= hi + 1e-3).all()
    # Every polygon lies in its plane n.x = d (world units).
    for i in range(len(polys["node"])):
        n, dist = polys["plane"][i, :3], polys["plane"][i, 3]
        ring = v[polys["offsets"][i]:polys["offsets"][i + 1]]
        np.testing.assert_allclose(ring @ n, dist, atol=1e-3 * np.ptp(pts))
    # trace_path's kd planes (axis normals) at the scene's world coordinates.
    rows = np.isfinite(path["plane"][:, 3]) & (np.abs(path["plane"][:, :3]).max(1) == 1.0)
    assert rows.any() and (np.abs(path["plane"][rows, 3]) > 1e5).all()

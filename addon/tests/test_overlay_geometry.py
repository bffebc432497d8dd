"""The viewport overlay's arrays (addon/overlay/geometry.py), checked without
Blender against the core's split_polygons / leaf_cells / node_at: what the
draw handler hands to batch_for_shader."""

from __future__ import annotations

import functools

import numpy as np
import pytest

import bsplab
from bsplab import scenes
from bsplab.tree import KINDS

from addon_without_blender import addon_module

geometry = addon_module("overlay.geometry")
cache_module = addon_module("overlay.cache")
Settings = geometry.OverlaySettings


@functools.lru_cache(maxsize=None)
def tree_of(method: str, scene: str = "room") -> bsplab.Tree:
    options = {"k": 4} if "k" in bsplab.methods()[method]["params"] else {}
    return bsplab.build(scenes.generate(scene), method=method, **options)


def assert_every_vertex_is_drawn(out):
    counts = np.bincount(out["face_indices"].ravel(), minlength=len(out["face_positions"]))
    assert (counts > 0).all()


# bsp_cn+kd on the fan has kd and general planes within depth 6.
@pytest.mark.parametrize("method, scene", [("kd", "room"), ("bsp_cn+kd", "fan")])
def test_batches_are_the_split_polygons_coloured_by_kind(method, scene):
    tree = tree_of(method, scene)
    settings = Settings(max_depth=6, alpha=0.3)
    out = geometry.overlay_geometry(tree, settings)
    polys = tree.split_polygons(6)
    sizes = np.diff(polys["offsets"])
    # Vertex count = the sum of the polygons' sizes; a fan of n - 2 triangles
    # and an outline of n edges per polygon.
    assert len(out["face_positions"]) == sizes.sum() == len(out["face_colours"])
    assert len(out["face_indices"]) == (sizes - 2).sum()
    assert len(out["line_indices"]) == sizes.sum()
    assert out["face_indices"].max() < len(out["face_positions"])
    assert np.array_equal(out["face_positions"], polys["vertices"].astype(np.float32))
    assert out["polygons"] == len(sizes) and not out["cut"]
    assert_every_vertex_is_drawn(out)
    # Every vertex carries its polygon's kind colour: x red, y green, z blue,
    # general yellow, with the faces' alpha; outlines the same RGB, opaque.
    kind_of_vertex = np.repeat(polys["kind"], sizes)
    table = {KINDS.index(name): rgb for name, rgb in
             zip(("x", "y", "z", "general"), geometry.DEFAULT_KIND_COLOURS)}
    expected = np.array([table[k] for k in kind_of_vertex], np.float32)
    assert np.allclose(out["face_colours"][:, :3], expected)
    assert np.allclose(out["face_colours"][:, 3], 0.3)
    assert np.allclose(out["line_colours"][:, :3], expected)
    assert np.allclose(out["line_colours"][:, 3], geometry.OUTLINE_ALPHA)
    if method == "bsp_cn+kd":
        assert (polys["kind"] == KINDS.index("general")).any()


def test_depth_colours_run_along_the_ramp():
    tree = tree_of("kd")
    out = geometry.overlay_geometry(tree, Settings(max_depth=5, colour_by="depth"))
    sizes = np.diff(tree.split_polygons(5)["offsets"])
    depth = np.repeat(out["depth"], sizes)
    low, high = (np.array(c, np.float32) for c in geometry.DEPTH_RAMP)
    assert np.allclose(out["face_colours"][depth == 0, :3], low)
    assert np.allclose(out["face_colours"][depth == 5, :3], high)
    assert (depth == 5).any()


def test_depth_slider_is_monotone():
    tree = tree_of("kd")
    previous = None
    for depth in range(0, 9):
        out = geometry.overlay_geometry(tree, Settings(max_depth=depth))
        assert out["depth"].max() <= depth
        if previous is not None:
            # A deeper slider keeps every polygon and adds the next level's.
            assert out["polygons"] >= previous["polygons"]
            assert np.array_equal(out["node"][:previous["polygons"]], previous["node"])
        previous = out


def test_cap_cuts_and_the_note_says_so():
    tree = tree_of("kd")
    whole = geometry.overlay_geometry(tree, Settings(max_depth=8))
    assert whole["notes"] == ["{:,} split polygons".format(whole["polygons"])]
    cap = whole["polygons"] // 3
    out = geometry.overlay_geometry(tree, Settings(max_depth=8, cap=cap))
    assert out["cut"] and out["polygons"] == cap
    assert out["polygon_total"] == whole["polygons"]
    assert out["notes"] == ["showing {:,} of {:,} split polygons (cut at {:,})".format(
        cap, whole["polygons"], cap)]
    # Past COUNT_FACTOR times the cap the total is not counted.
    tiny = geometry.overlay_geometry(tree, Settings(max_depth=8, cap=1))
    assert tiny["polygons"] == 1
    assert tiny["notes"][0] == "showing 1 of more than {} split polygons (cut at 1)".format(
        geometry.COUNT_FACTOR)


def test_cursor_scope_draws_only_the_subtree_under_the_cursor():
    tree = tree_of("kd")
    cursor = np.mean(np.array(tree.bounds), axis=0) + 0.137
    root, root_depth = tree.node_at(cursor, max_depth=3)
    assert root_depth == 3
    out = geometry.overlay_geometry(tree, Settings(max_depth=4, scope="cursor", subtree_depth=3),
                                    cursor)
    assert (out["root"], out["root_depth"]) == (root, 3)
    assert out["notes"][0] == "subtree of node {:,} (depth 3)".format(root)
    # The whole tree's polygons whose node lies under `root`: those whose
    # centre's path passes through `root` at depth 3 (a polygon's centre is
    # inside its node's cell, hence inside its ancestors').
    whole = tree.split_polygons(3 + 4)
    under = [node for node, depth, centre in zip(whole["node"], whole["depth"],
                                                 polygon_centres(whole))
             if depth >= 3 and tree.node_at(centre, max_depth=3)[0] == root]
    assert out["polygons"] > 0
    assert sorted(out["node"]) == sorted(under)
    # Outside the box: nothing, and why.
    far = geometry.overlay_geometry(tree, Settings(scope="cursor"), (1e6, 1e6, 1e6))
    assert far["polygons"] == 0 and len(far["face_indices"]) == 0
    assert far["notes"] == ["3D cursor is outside the tree's box"]


def polygon_centres(polys):
    offsets = polys["offsets"]
    return [polys["vertices"][a:b].astype(np.float64).mean(axis=0)
            for a, b in zip(offsets[:-1], offsets[1:])]


def test_cells_are_the_wireframes_of_the_cells_below_the_planes():
    tree = tree_of("kd")
    out = geometry.overlay_geometry(tree, Settings(max_depth=3, cells=True))
    cells = tree.leaf_cells(max_depth=4)
    assert out["cells"] == len(cells["node"]) > 0
    assert np.array_equal(out["cell_indices"], cells["edges"])
    assert len(out["cell_positions"]) == len(out["cell_colours"]) == len(cells["vertices"])
    assert out["notes"][-1] == "{:,} cells".format(out["cells"])
    off = geometry.overlay_geometry(tree, Settings(max_depth=3))
    assert off["cells"] == 0 and len(off["cell_indices"]) == 0


def test_cache_walks_only_when_something_changed():
    tree = tree_of("kd")
    cache = cache_module.GeometryCache()
    first = cache.get(tree, Settings(), (0, 0, 0))
    assert cache.get(tree, Settings(), (1, 2, 3)) is first  # the cursor matters only under it
    assert cache.builds == 1
    assert cache.get(tree, Settings(max_depth=2), (1, 2, 3)) is not first
    cursor = Settings(scope="cursor")
    a = cache.get(tree, cursor, (0, 0, 0))
    assert cache.get(tree, cursor, (0, 0, 0)) is a
    cache.get(tree, cursor, (0.5, 0, 0))
    assert cache.builds == 4
    other = tree_of("bsp_cn+kd", "fan")
    assert cache.made_from(tree) and not cache.made_from(other)
    assert cache.get(other, cursor, (0.5, 0, 0)) is not a
    assert cache.made_from(other) and not cache.made_from(tree)
    assert cache.get(None, cursor) is None and cache.builds == 0


@pytest.mark.parametrize("change, message", [
    ({"colour_by": "height"}, "colour_by must be one of"),
    ({"scope": "everything"}, "scope must be one of"),
    ({"max_depth": -1}, "max_depth must be >= 0"),
    ({"cap": 0}, "cap must be >= 1"),
    ({"alpha": 1.5}, "alpha must be in"),
])
def test_bad_settings_are_named(change, message):
    with pytest.raises(ValueError, match=message):
        Settings(**change)

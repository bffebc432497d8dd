"""The tree overlay of a two-level build (addon/overlay/in_place.py), checked
without Blender on the real core: the top level's boxes are InstancedTree.top_boxes',
the instance drawn in place is the one under the cursor, and its planes and
cells are its mesh tree's carried to the world (inside its world box)."""

from __future__ import annotations

import functools

import numpy as np
import pytest

import bsplab
from bsplab import instanced_scenes, scenes

from addon_without_blender import addon_module

geometry = addon_module("overlay.geometry")
cache_module = addon_module("overlay.cache")
in_place = addon_module("overlay.in_place")
Settings = geometry.OverlaySettings


def placements():
    """Four instances of two meshes, apart from each other: instance 0 the
    fan as it is, 1 the cube turned 45 degrees about z and scaled 2 at x = 10,
    2 the cube mirrored at y = 10, 3 the fan sheared at (10, 10, 0)."""
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    turn = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) * 2.0
    mirror = np.diag([-1.0, 1.0, 1.0])
    shear = np.array([[1.0, 0.4, 0], [0, 1, 0], [0, 0, 1]])
    fan = scenes.generate("fan")
    lo, hi = fan.reshape(-1, 3).min(axis=0), fan.reshape(-1, 3).max(axis=0)
    fan = ((fan - lo) / (hi - lo).max()).astype(np.float32)  # into [0, 1]^3
    matrices = [instanced_scenes.affine(np.eye(3), (0, 0, 0)),
                instanced_scenes.affine(turn, (10, 0, 0)),
                instanced_scenes.affine(mirror, (0, 10, 0)),
                instanced_scenes.affine(shear, (10, 10, 0))]
    return [fan, instanced_scenes.cube()], np.array([0, 1, 1, 0]), np.array(matrices)


@functools.lru_cache(maxsize=None)
def scene_of(method="kd"):
    meshes, index, matrices = placements()
    return bsplab.build_instanced(meshes, index, matrices, method)


def world_box(tree, instance):
    """The world box of `instance`'s mesh box (its 8 corners carried)."""
    lo, hi = (np.asarray(c) for c in tree.meshes[tree.mesh_index[instance]].bounds)
    corners = np.array([[(hi if (k >> a) & 1 else lo)[a] for a in range(3)] for k in range(8)])
    world = tree.to_world(instance, corners)
    return world.min(axis=0), world.max(axis=0)


def inside(points, box, slack=1e-4):
    lo, hi = box
    return bool(((points >= lo - slack) & (points <= hi + slack)).all())


@pytest.mark.parametrize("depth", [0, 1, 3, 8])
def test_the_top_boxes_are_the_cores_at_each_depth(depth):
    tree = scene_of()
    out = in_place.two_level_geometry(tree, Settings(max_depth=depth), cursor=None)
    top = tree.top_boxes(depth)
    assert out["top_boxes"] == out["top_total"] == len(top["node"]) > 0
    assert np.array_equal(out["top_node"], top["node"])
    assert np.array_equal(out["top_depth"], top["depth"])
    # 8 corners and 12 edges per box, after the (here absent) instance's part.
    assert len(out["face_positions"]) == 8 * len(top["node"])
    assert len(out["line_indices"]) == 12 * len(top["node"])
    assert np.array_equal(out["face_positions"][:8], np.array(
        [[(top["hi"][0] if (k >> a) & 1 else top["lo"][0])[a] for a in range(3)]
         for k in range(8)], np.float32))
    # Coloured by depth on the flat overlay's ramp.
    low = np.array(geometry.DEPTH_RAMP[0], np.float32)
    assert np.allclose(out["line_colours"][0, :3], low)
    assert out["instance"] is None and len(out["face_indices"]) == 0
    assert "no 3D cursor" in " ".join(out["notes"])


def test_the_top_boxes_are_capped_shallow_levels_first():
    tree = scene_of()
    out = in_place.two_level_geometry(tree, Settings(max_depth=8, cap=3), cursor=None)
    assert out["top_boxes"] == 3 and out["top_total"] == len(tree.top_boxes(8)["node"]) > 3
    assert out["cut"]
    assert list(out["top_depth"]) == sorted(out["top_depth"])
    assert "showing 3 of {:,} top-level boxes (cut at 3)".format(out["top_total"]) in out["notes"]


@pytest.mark.parametrize("cursor, instance", [
    ((0.5, 0.5, 0.5), 0), ((10.0, 0.5, 1.0), 1), ((-0.5, 10.5, 0.5), 2),
    ((10.9, 10.5, 0.5), 3)])
def test_the_instance_under_the_cursor_is_drawn_in_place(cursor, instance):
    tree = scene_of()
    assert in_place.instance_under(tree, cursor) == instance
    out = in_place.two_level_geometry(tree, Settings(max_depth=4, cells=True), cursor)
    assert out["instance"] == instance and out["mesh"] == tree.mesh_index[instance]
    polys = tree.instance_split_polygons(instance, 4)
    sizes = np.diff(polys["offsets"])
    assert out["polygons"] == len(sizes) > 0
    # The instance's polygons first, then the top boxes' corners.
    assert len(out["face_positions"]) == sizes.sum() + 8 * out["top_boxes"]
    assert np.array_equal(out["face_positions"][:sizes.sum()], polys["vertices"])
    assert len(out["face_indices"]) == (sizes - 2).sum()
    assert out["face_indices"].max() < sizes.sum()
    # The outline edges and the boxes' edges, all within the positions.
    assert len(out["line_indices"]) == sizes.sum() + 12 * out["top_boxes"]
    assert out["line_indices"].max() < len(out["face_positions"])
    # Cells: the mesh tree's, carried to the world, inside the instance's box.
    cells = tree.instance_leaf_cells(instance, max_depth=5)
    assert out["cells"] == len(cells["node"]) > 0
    assert np.array_equal(out["cell_positions"], cells["vertices"])
    box = world_box(tree, instance)
    assert inside(out["instance_cells"], box)
    assert inside(out["face_positions"][:sizes.sum()], box)
    # ... and not inside any other instance's box (they are apart).
    others = [i for i in range(len(tree.mesh_index)) if i != instance]
    assert not any(inside(out["face_positions"][:sizes.sum()], world_box(tree, i)) for i in others)


def test_a_cursor_over_no_instance_draws_the_top_level_only():
    tree = scene_of()
    out = in_place.two_level_geometry(tree, Settings(max_depth=4, cells=True), (5.0, 5.0, 0.5))
    assert out["instance"] is None and out["polygons"] == 0 and out["cells"] == 0
    assert in_place.NO_INSTANCE_NOTE in out["notes"]
    assert out["top_boxes"] == len(tree.top_boxes(4)["node"])


def test_the_cursor_scope_draws_the_instances_subtree():
    tree = scene_of()
    cursor = (10.0, 0.5, 1.0)  # in instance 1, the turned cube
    settings = Settings(max_depth=3, scope="cursor", subtree_depth=2)
    out = in_place.two_level_geometry(tree, settings, cursor)
    local = in_place.object_point(tree, 1, cursor)
    node, depth = tree.meshes[1].node_at(local, max_depth=2)
    assert (out["root"], out["root_depth"]) == (node, depth)
    assert out["polygons"] == len(tree.instance_split_polygons(1, 3, root=node)["node"])
    assert "subtree of its node {:,} (depth {})".format(node, depth) in out["notes"]


def test_colour_by_kind_is_the_mesh_trees_kind():
    tree = scene_of()
    out = in_place.two_level_geometry(tree, Settings(max_depth=4), (0.5, 0.5, 0.5))
    polys = tree.instance_split_polygons(0, 4)
    table = geometry.kind_colour_table(Settings())
    expected = np.repeat(table[polys["kind"]], np.diff(polys["offsets"]), axis=0)
    assert np.allclose(out["face_colours"][:len(expected), :3], expected)


def test_a_bvh_mesh_tree_draws_its_boxes_in_place():
    tree = scene_of("bvh")
    out = in_place.two_level_geometry(tree, Settings(max_depth=3), (10.0, 0.5, 1.0))
    boxes = tree.instance_node_boxes(1, 3)
    assert out["instance"] == 1 and out["boxes"] == len(boxes["node"]) > 0
    assert len(out["face_indices"]) == 0  # boxes: no faces
    assert np.array_equal(out["instance_cells"], boxes["corners"].reshape(-1, 3))
    assert inside(out["instance_cells"], world_box(tree, 1))
    assert geometry.BVH_NOTE in out["notes"]


def test_the_cache_follows_the_cursor_for_a_two_level_build_in_either_scope():
    tree = scene_of()
    cache = cache_module.GeometryCache()
    settings = Settings(max_depth=2)
    first = cache.get(tree, settings, (0.5, 0.5, 0.5))
    assert first["instance"] == 0 and cache.get(tree, settings, (0.5, 0.5, 0.5)) is first
    moved = cache.get(tree, settings, (10.0, 0.5, 1.0))
    assert moved is not first and moved["instance"] == 1 and cache.builds == 2

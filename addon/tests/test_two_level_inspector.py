"""The ray inspector on a two-level build (addon/inspector/trace.py, walk_arrays.py),
checked without Blender on the real core: its rows are
InstancedTree.trace_path's walk, its hit is intersect()'s, and what it
draws lies where the walk went (the top boxes entered, the cells inside
each instance entered in world space, the tested triangles)."""

from __future__ import annotations

import numpy as np
import pytest

from addon_without_blender import addon_module
from test_two_level_overlay import inside, scene_of, world_box

walk_arrays = addon_module("inspector.walk_arrays")
trace = addon_module("inspector.trace")

# Down onto instance 1 (the turned cube at x = 10): it enters that instance.
DOWN_ON_CUBE = ((10.0, 0.3, 20.0), (0.0, 0.0, -1.0))
# Along y at x = 10.5, z = 0.5: through the turned cube (y ~ 0) and the
# sheared fan (y ~ 10).
ALONG_Y = ((10.5, -20.0, 0.5), (0.0, 1.0, 0.0))


def inspect(method, ray):
    tree = scene_of(method)
    origin, direction = ray
    names = (["'Object {}'".format(i) for i in range(4)], ["Fan", "Cube"])
    return tree, trace.inspect_two_level(tree, origin, direction, "ray", names)


@pytest.mark.parametrize("method", ["kd", "bvh"])
@pytest.mark.parametrize("ray", [DOWN_ON_CUBE, ALONG_Y])
def test_the_walk_is_trace_paths_and_the_hit_intersects(method, ray):
    tree, inspection = inspect(method, ray)
    path = tree.trace_path(*ray)
    totals = inspection["counts"]
    assert totals["top_steps"] == path["top_steps"] == len(inspection["top_rows"]) > 0
    assert totals["instance_visits"] == path["instance_visits"] == len(inspection["visits"]) > 0
    for key in ("steps", "tests", "general_steps", "box_tests"):
        assert totals[key] == path[key]
    # The top rows are the top nodes visited, in order, with their t ranges.
    for row, node, t_range in zip(inspection["top_rows"], path["top"]["node"],
                                  path["top"]["t_range"]):
        boxes = tree.top_boxes()
        index = int(np.flatnonzero(boxes["node"] == node)[0])
        assert row[1] == ("leaf" if boxes["leaf"][index] else "box")
        assert (row[2], row[3]) == tuple(t_range)
        assert row[4] == tuple(boxes["instances"][index].tolist()) if boxes["leaf"][index] \
            else row[4] == ()
    # Each instance entered: its own steps, as the flat inspector's rows.
    for visit, entered in zip(inspection["visits"], path["instances"]):
        assert visit["instance"] == entered["instance"]
        assert visit["rows"] == trace.step_rows(entered["path"])
        assert len(visit["rows"]) == len(entered["path"]["node"])
    assert sum(len(v["rows"]) for v in inspection["visits"]) == len(inspection["rows"])
    # The hit is intersect()'s, instance and all.
    hits = tree.intersect(np.array([ray[0]], np.float32), np.array([ray[1]], np.float32))
    assert totals["hit_instance"] == hits["instance"][0] >= 0
    assert totals["hit_prim"] == hits["prim"][0] and totals["hit_t"] == hits["t"][0]
    assert [v["hit"] for v in inspection["visits"]].count(True) == 1


def test_the_ray_down_on_the_cube_hits_instance_1():
    tree, inspection = inspect("kd", DOWN_ON_CUBE)
    totals = inspection["counts"]
    assert totals["hit_instance"] == 1 and totals["hit_mesh"] == 1
    # The cube scaled 2: its top at z = 2, 18 below the origin.
    assert totals["hit_t"] == pytest.approx(18.0, abs=1e-4)
    assert inspection["visits"][-1]["instance"] == 1


def test_draw_data_top_boxes_cells_in_place_and_triangles():
    tree, inspection = inspect("kd", ALONG_Y)
    data = walk_arrays.two_level_draw_data(tree, inspection)
    path = inspection["path"]
    # The top boxes entered: 24 line ends each, first, in the top colour.
    assert data["top_vertices"] == 24 * path["top_steps"]
    top = data["cell_coords"][:data["top_vertices"]]
    assert np.allclose(data["cell_colours"][:data["top_vertices"]], walk_arrays.TOP_BOX_COLOUR)
    lo, hi = path["top"]["box_lo"][0], path["top"]["box_hi"][0]
    assert inside(top[:24], (lo, hi))
    # Each instance's crossed cells, in world space inside that instance's box.
    assert [i for i, _ in data["instance_cells"]] == [v["instance"] for v in path["instances"]]
    for (instance, cells), visit in zip(data["instance_cells"], path["instances"]):
        leaves = visit["path"]["node"][visit["path"]["kind"] == trace.LEAF]
        expected = sum(2 * len(tree.instance_leaf_cells(instance, max_depth=0,
                                                        root=int(n))["edges"]) for n in leaves)
        assert len(cells) == expected > 0
        assert inside(cells, world_box(tree, instance))
    assert len(data["cell_coords"]) == data["top_vertices"] + sum(
        len(c) for _, c in data["instance_cells"])
    # The tested triangles, in world units; the hit's in green and on the ray.
    hit_instance, hit_prim = inspection["counts"]["hit_instance"], inspection["counts"]["hit_prim"]
    hit_visit = next(v for v in path["instances"] if v["instance"] == hit_instance)
    drawn = sum(int(np.count_nonzero(v["path"]["test_result"] != trace.SEEN))
                for v in path["instances"])
    assert data["tri_coords"].shape == (3 * drawn, 3)
    green = np.flatnonzero(np.all(np.isclose(data["tri_colours"], walk_arrays.HIT_COLOUR),
                                  axis=1))
    assert len(green) == 3
    mesh = tree.meshes[hit_visit["mesh"]]
    assert np.allclose(data["tri_coords"][green],
                       tree.to_world(hit_instance, mesh.triangles[hit_prim]), atol=1e-6)
    assert np.allclose(data["hit"][0], np.array(ALONG_Y[0]) + inspection["counts"]["hit_t"]
                       * np.array(ALONG_Y[1]), atol=1e-4)


def test_a_bvh_mesh_tree_draws_the_boxes_it_entered_in_place():
    tree, inspection = inspect("bvh", DOWN_ON_CUBE)
    data = walk_arrays.two_level_draw_data(tree, inspection)
    for (instance, cells), visit in zip(data["instance_cells"], inspection["path"]["instances"]):
        entered = trace.entered_boxes(visit["path"])[0]
        assert len(cells) == 24 * len(entered) > 0
        assert inside(cells, world_box(tree, instance))


def test_a_ray_that_misses_the_scene_is_still_drawn():
    tree = scene_of()
    inspection = trace.inspect_two_level(tree, (100.0, 100.0, 100.0), (1.0, 0.0, 0.0), "ray")
    assert inspection["missed_box"] and inspection["counts"]["top_steps"] == 0
    assert inspection["counts"]["hit_instance"] is None and inspection["visits"] == []
    data = walk_arrays.two_level_draw_data(tree, inspection)
    assert len(data["hit"]) == 0 and len(data["cell_coords"]) == 0 and len(data["tri_coords"]) == 0
    assert data["ray"][1][0] > 100.0


def test_a_ray_between_the_instances_enters_the_top_level_only():
    tree = scene_of()
    # Down through (5, 5): inside the scene's box, in no instance's.
    inspection = trace.inspect_two_level(tree, (5.0, 5.0, 20.0), (0.0, 0.0, -1.0), "ray")
    assert not inspection["missed_box"] and inspection["counts"]["top_steps"] >= 1
    assert inspection["counts"]["hit_instance"] is None
    data = walk_arrays.two_level_draw_data(tree, inspection)
    assert data["top_vertices"] == 24 * inspection["counts"]["top_steps"]

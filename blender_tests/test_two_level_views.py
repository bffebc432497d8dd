"""The tree overlay and the ray inspector on a two-level build (issue 24):
the overlay draws the top level's boxes and the instance under the 3D cursor
in place, named in the panel; the inspector lists the top level's steps,
then each instance entered with its steps, and the hit with its instance.
On test_instances.py's scene (a 3 x 3 grid of a collection of a cube and a
tetrahedron, linked duplicates, curves, text, a metaball)."""

import bpy
import numpy as np
import pytest

import bsplab_test_utils as utils
from test_instances import GRID, build_instanced_scene, press
from test_ui import draw


@pytest.fixture
def instanced_scene(addon):
    return build_instanced_scene(utils.reset_file("two_level"))


def labels(panel):
    return [text for kind, text in draw(panel) if kind == "label"]


def kept(addon):
    build = addon.state.STATE.shown_build
    return build, build.tree()


def instance_named(build, name):
    """The index of the instance the extraction named `name`."""
    return list(build.instance_names).index(name)


def grid_cube_point(objects, i, j):
    """A point inside the cube of grid cell (i, j): the empty's origin lifted
    to the cube's centre (the cube sits at z 0.4 in the collection)."""
    empty = objects["grid"][i * GRID + j]
    return tuple(empty.matrix_world @ utils.Vector((0.0, 0.0, 0.4)))


# -----------------------------------------------------------------------------
# The overlay


def test_overlay_draws_the_top_boxes_and_the_instance_under_the_cursor(addon, core,
                                                                        instanced_scene):
    scene = instanced_scene["scene"]
    press(scene)
    build, tree = kept(addon)
    assert tree.structure == "two_level"
    props = scene.bsplab_overlay
    props.show, props.max_depth, props.cells = True, 3, True
    try:
        scene.cursor.location = grid_cube_point(instanced_scene, 1, 2)
        arrays = addon.overlay.draw.current_geometry(scene)
        assert arrays["top_boxes"] == len(tree.top_boxes(3)["node"]) > 0
        assert np.array_equal(arrays["top_node"], tree.top_boxes(3)["node"])
        instance = instance_named(build, "'Prop Cube' in 'Grid 1 2'")
        assert arrays["instance"] == instance
        assert build.mesh_names[arrays["mesh"]] == "Prop Cube"
        assert arrays["polygons"] == len(tree.instance_split_polygons(instance, 3)["node"]) > 0
        # The cells drawn in place lie inside the instance's world box (its
        # mesh box's corners carried by the matrix).
        lo, hi = (np.asarray(c) for c in tree.meshes[arrays["mesh"]].bounds)
        corners = np.array([[(hi if (k >> a) & 1 else lo)[a] for a in range(3)]
                            for k in range(8)])
        world = tree.to_world(instance, corners)
        cells = arrays["instance_cells"]
        assert len(cells) > 0
        assert (cells >= world.min(axis=0) - 1e-4).all() and (cells <= world.max(axis=0) + 1e-4).all()
        texts = labels(addon.overlay.panel.BSPLAB_PT_overlay)
        assert addon.overlay.panel.TWO_LEVEL_NOTE in texts
        assert ("In place: instance {} 'Prop Cube' in 'Grid 1 2' (mesh 'Prop Cube')".format(
            instance)) in texts
        assert "{:,} top-level boxes".format(arrays["top_boxes"]) in texts
        # Another cell of the grid: another instance, new arrays.
        scene.cursor.location = grid_cube_point(instanced_scene, 0, 0)
        moved = addon.overlay.draw.current_geometry(scene)
        assert moved["instance"] == instance_named(build, "'Prop Cube' in 'Grid 0 0'")
    finally:
        props.show = False


def test_overlay_with_the_cursor_over_no_instance(addon, core, instanced_scene):
    scene = instanced_scene["scene"]
    press(scene)
    props = scene.bsplab_overlay
    props.show = True
    try:
        scene.cursor.location = (0.0, 0.0, 30.0)  # high above everything
        arrays = addon.overlay.draw.current_geometry(scene)
        assert arrays["instance"] is None and arrays["polygons"] == 0
        assert arrays["top_boxes"] > 0
        texts = labels(addon.overlay.panel.BSPLAB_PT_overlay)
        assert addon.overlay.in_place.NO_INSTANCE_NOTE in texts
        assert not any(t.startswith("In place:") for t in texts)
    finally:
        props.show = False


def test_the_flat_overlay_is_unchanged_after_a_two_level_one(addon, core, instanced_scene):
    scene = instanced_scene["scene"]
    scene.bsplab.instances = "flatten"
    press(scene)
    props = scene.bsplab_overlay
    props.show, props.max_depth = True, 4
    try:
        tree = addon.overlay.draw.kept_tree()
        assert tree.structure != "two_level"
        arrays = addon.overlay.draw.current_geometry(scene)
        assert "two_level" not in arrays
        assert arrays["polygons"] == len(tree.split_polygons(4)["node"])
        assert addon.overlay.panel.TWO_LEVEL_NOTE not in labels(addon.overlay.panel.BSPLAB_PT_overlay)
    finally:
        props.show = False


# -----------------------------------------------------------------------------
# The ray inspector


def test_inspector_lists_both_levels_and_the_hit_instance(addon, core, instanced_scene):
    scene = instanced_scene["scene"]
    press(scene)
    build, tree = kept(addon)
    # Straight down onto grid cell (0, 0)'s cube (not turned), beside its
    # tetrahedron: the cube's top at z 0.8.
    empty = instanced_scene["grid"][0].location
    origin, direction = (empty.x + 0.33, empty.y + 0.33, 10.0), (0.0, 0.0, -1.0)
    assert bpy.ops.bsplab.inspect_ray(origin=origin, direction=direction) == {'FINISHED'}
    inspection = addon.state.STATE.inspection
    assert inspection["structure"] == "two_level"
    path = tree.trace_path(origin, direction)
    totals = inspection["counts"]
    assert totals["top_steps"] == path["top_steps"] == len(inspection["top_rows"]) > 0
    assert [v["instance"] for v in inspection["visits"]] == [v["instance"]
                                                            for v in path["instances"]]
    for visit, entered in zip(inspection["visits"], path["instances"]):
        assert len(visit["rows"]) == len(entered["path"]["node"])
        assert [r[3:5] for r in visit["rows"]] == [tuple(t) for t in entered["path"]["t_range"]]
    hit = instance_named(build, "'Prop Cube' in 'Grid 0 0'")
    assert totals["hit_instance"] == path["instance"] == hit
    assert totals["hit_t"] == pytest.approx(9.2, abs=1e-4)
    rows = dict(addon.inspector.panel.count_rows(inspection))
    assert rows["Top Steps"].startswith(str(path["top_steps"]))
    assert rows["Instances"] == "{} entered".format(path["instance_visits"])
    assert rows["In"] == "instance {} 'Prop Cube' in 'Grid 0 0' (mesh 'Prop Cube')".format(hit)
    texts = labels(addon.inspector.panel.BSPLAB_PT_inspector)
    assert "Top level" in texts and "top node" in texts
    assert "Instance {} 'Prop Cube' in 'Grid 0 0' (mesh 'Prop Cube') - hit".format(hit) in texts
    # The drawn cells of the hit instance lie in its world box.
    data = inspection["draw"]
    assert data["top_vertices"] == 24 * path["top_steps"]
    cells = dict(data["instance_cells"])[hit]
    mesh = tree.meshes[tree.mesh_index[hit]]
    lo, hi = (np.asarray(c) for c in mesh.bounds)
    world = tree.to_world(hit, np.array([[(hi if (k >> a) & 1 else lo)[a] for a in range(3)]
                                         for k in range(8)]))
    assert len(cells) and (cells >= world.min(axis=0) - 1e-4).all()
    assert (cells <= world.max(axis=0) + 1e-4).all()


def test_a_preview_pixel_of_a_two_level_build(addon, core, instanced_scene):
    scene = instanced_scene["scene"]
    press(scene)
    build, tree = kept(addon)
    width, height = build.render_size
    image_h = bpy.data.images[addon.jobs.preview.IMAGE_NAME].size[1]
    cam = addon.jobs.scene_reader.make_camera(core, build.camera)
    origins, directions = cam.rays(width, height)
    hits = tree.intersect(origins, directions, counters=False)
    for x, row in ((width // 2, height // 2), (width // 4, height - 3), (3, 1)):
        assert bpy.ops.bsplab.inspect_pixel(x=x, y=image_h - 1 - row) == {'FINISHED'}
        inspection = addon.state.STATE.inspection
        i = row * width + x
        assert np.array_equal(inspection["origin"], origins[i])
        expected = int(hits["instance"][i])
        assert inspection["counts"]["hit_instance"] == (expected if expected >= 0 else None)
        if expected >= 0:
            assert inspection["counts"]["hit_prim"] == hits["prim"][i]
            assert inspection["counts"]["hit_t"] == hits["t"][i]


def test_a_ray_that_misses_a_two_level_scene(addon, core, instanced_scene):
    scene = instanced_scene["scene"]
    press(scene)
    assert bpy.ops.bsplab.inspect_ray(origin=(500.0, 500.0, 500.0),
                                      direction=(1.0, 0.0, 0.0)) == {'FINISHED'}
    inspection = addon.state.STATE.inspection
    assert inspection["missed_box"]
    assert dict(addon.inspector.panel.count_rows(inspection))["Hit"] == \
        "none: missed the scene's box"
    assert len(inspection["draw"]["hit"]) == 0
    labels(addon.inspector.panel.BSPLAB_PT_inspector)  # draws without an error


def test_the_inspector_caps_the_two_level_steps(addon, core, instanced_scene):
    scene = instanced_scene["scene"]
    press(scene)
    empty = instanced_scene["grid"][0].location
    assert bpy.ops.bsplab.inspect_ray(origin=(empty.x + 0.33, empty.y + 0.33, 10.0),
                                      direction=(0.0, 0.0, -1.0)) == {'FINISHED'}
    inspection = addon.state.STATE.inspection
    panel = addon.inspector.panel
    total = len(inspection["top_rows"]) + sum(len(v["rows"]) for v in inspection["visits"])
    sections, more = panel.two_level_sections(inspection, 2)
    assert sum(len(rows) for _, _, rows in sections) == 2 and more == total - 2

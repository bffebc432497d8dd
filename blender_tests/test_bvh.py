"""The add-on with a BVH (method "bvh"): in the method menu with its own
options (no K, no strategy), Build & Render and its statistics, the heat map
of box tests, the tree overlay's boxes by depth, the ray inspector's entered
boxes, and the A/B comparison kd against bvh."""

import bpy
import numpy as np
import pytest

from test_ui import RecordingLayout, draw

BVH = "bvh"


class GridLayout(RecordingLayout):
    """RecordingLayout with the grid the A/B statistics are drawn in."""

    def _child(self, *_args, **_kwargs):
        return GridLayout(self.log, self.icons)

    column = row = box = split = grid_flow = _child


def press(scene, method=BVH, mode="shaded"):
    scene.bsplab.method = method
    scene.bsplab.render_mode = mode
    assert bpy.ops.bsplab.build_render() == {'FINISHED'}
    return scene.bsplab.stats


def kept_tree(addon):
    return addon.state.STATE.shown_build.tree()


def test_bvh_is_in_the_method_menu_with_its_options_only(addon, core, empty_scene):
    items = [item[0] for item in addon.tree_options.method_enum_items(None, bpy.context)]
    assert BVH in items
    empty_scene.bsplab.method = BVH
    props = [name for kind, name in draw(addon.build_render.panel.BSPLAB_PT_main)
             if kind == "prop"]
    params = core.methods()[BVH]["params"]
    assert "k" not in params and "strategy" not in params
    assert "k" not in props and "bins" in props
    for name in addon.tree_options.TREE_OPTIONS:  # every option it takes, no other
        assert (name in props) == (name in params), name


def test_build_and_render_a_bvh_shows_its_statistics(addon, core, test_scene):
    scene = test_scene["scene"]
    scene.bsplab.compare_with_embree = True
    stats = press(scene, mode="heat_box_tests")
    tree = kept_tree(addon)
    assert tree.structure == "bvh" and stats["build"]["structure"] == "bvh"
    assert stats["render"]["max_box_tests"] > 0
    embree = stats["embree"]
    if embree["available"]:  # not in a Blender whose own Embree clashes (3.4)
        compared = embree["compare"]
        assert compared["agree"] + compared["embree_wrong"] + compared["grazing"] >= \
        compared["rays"]
    else:
        assert embree["message"]
    labels = [text for kind, text in draw(addon.build_render.panel.BSPLAB_PT_stats)
              if kind == "label"]
    assert "Box Tests / Ray" in labels and "BVH (boxes)" in labels
    for meaningless in ("Kd / General", "Duplication", "Empty Leaves", "Leaf Boxes"):
        assert meaningless not in labels


def test_overlay_draws_the_bvh_boxes_by_depth(addon, core, test_scene):
    scene = test_scene["scene"]
    press(scene)
    props = scene.bsplab_overlay
    props.show, props.max_depth = True, 3
    geometry = addon.overlay.draw.current_geometry(scene)
    boxes = kept_tree(addon).node_boxes(3)
    n = len(boxes["node"])
    assert geometry["polygons"] == n > 0
    assert geometry["face_positions"].shape == (8 * n, 3)
    assert len(geometry["line_indices"]) == 12 * n and len(geometry["face_indices"]) == 0
    labels = [text for kind, text in draw(addon.overlay.panel.BSPLAB_PT_overlay)
              if kind == "label"]
    assert any(label.startswith("BVH: boxes") for label in labels)
    assert "{:,} node boxes".format(n) in labels
    props.show = False


def test_inspector_lists_and_draws_the_boxes_the_ray_entered(addon, core, test_scene):
    scene = test_scene["scene"]
    press(scene)
    build = addon.state.STATE.shown_build
    width, height = build.render_size
    image = bpy.data.images[addon.jobs.preview.IMAGE_NAME]
    assert bpy.ops.bsplab.inspect_pixel(x=width // 2, y=image.size[1] - 1 - height // 2) == \
        {'FINISHED'}
    inspection = addon.state.STATE.inspection
    path = inspection["path"]
    assert inspection["counts"]["box_tests"] == path["box_tests"] > 0
    assert {row[1] for row in inspection["rows"]} == {"box", "leaf"}
    # One wireframe (12 edges) per entered box, first blue, last magenta.
    data, draw_mod = inspection["draw"], addon.inspector.draw
    steps = len(path["node"])
    assert data["cell_coords"].shape == (24 * steps, 3)
    assert tuple(data["cell_colours"][0]) == pytest.approx(tuple(draw_mod.FIRST_CELL))
    assert tuple(data["cell_colours"][-1]) == pytest.approx(tuple(draw_mod.LAST_CELL))
    lo, hi = data["cell_coords"].min(axis=0), data["cell_coords"].max(axis=0)
    assert np.allclose(lo, path["box_lo"].min(axis=0)) and np.allclose(
        hi, path["box_hi"].max(axis=0))
    labels = [text for kind, text in draw(addon.inspector.panel.BSPLAB_PT_inspector)
              if kind == "label"]
    assert "Box Tests" in labels and "General" not in labels


def test_compare_kd_against_bvh(addon, core, test_scene):
    scene = test_scene["scene"]
    compare = scene.bsplab_compare
    compare.enabled, compare.method, compare.view = True, BVH, "diff_box_tests"
    stats = press(scene, method="kd")
    assert stats["b"]["build"]["structure"] == "bvh"
    assert stats["build"]["structure"] == "bsp"
    (name_a, name_b), rows = addon.build_render.statistics.compare_grid(stats)
    assert (name_a, name_b) == ("kd", BVH)
    boxes = {label: (a, b) for label, a, b, _ in rows}["Boxes/Ray"]
    assert boxes[0] == "0.00" and float(boxes[1]) > 0
    labels = [text for kind, text in draw(addon.build_render.panel.BSPLAB_PT_stats,
                                          GridLayout()) if kind == "label"]
    assert "B: bvh" in labels and "Boxes/Ray" in labels
    compare.enabled = False

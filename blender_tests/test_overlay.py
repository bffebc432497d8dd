"""The tree overlay (addon/overlay.py, overlay_panel.py): its draw handler's
life and the arrays it would draw. In background mode the handler is added
but never called, so the drawing itself is checked by gui_check_overlay.py
under Xvfb."""

import bpy
import numpy as np
import pytest

import bsplab_test_utils as utils
from test_ui import draw, RecordingLayout


def build(scene):
    assert bpy.ops.bsplab.build_render() == {'FINISHED'}


def panel_labels(addon):
    return [text for kind, text in draw(addon.overlay.panel.BSPLAB_PT_overlay) if kind == "label"]


def draw_header(addon):
    layout = RecordingLayout()
    cls = addon.overlay.panel.BSPLAB_PT_overlay
    panel = type("Panel", (), {"layout": layout, "TOGGLE": cls.TOGGLE})()
    cls.draw_header(panel, bpy.context)
    return layout.log


def test_registered_with_its_panel_and_settings(addon, empty_scene):
    assert hasattr(bpy.types, "BSPLAB_PT_overlay")
    props = empty_scene.bsplab_overlay
    assert props.show is False and props.max_depth == 8 and props.scope == "whole"
    assert not addon.overlay.draw.handler_installed()
    # The header's tick box is the toggle.
    assert draw_header(addon) == [("prop", "show")]


def test_toggling_adds_and_removes_the_handler(addon, empty_scene):
    props = empty_scene.bsplab_overlay
    props.show = True
    assert addon.overlay.draw.handler_installed()
    props.show = True  # setting it again adds no second handler
    props.show = False
    assert not addon.overlay.draw.handler_installed()


def test_without_a_tree_the_panel_says_build_first(addon, empty_scene):
    empty_scene.bsplab_overlay.show = True
    assert addon.overlay.draw.kept_tree() is None
    assert addon.overlay.draw.current_geometry(empty_scene) is None
    assert addon.overlay.panel.NO_TREE_MESSAGE in panel_labels(addon)
    assert addon.overlay.panel.NO_TREE_MESSAGE.startswith("Build & Render first")


def test_overlay_arrays_are_the_kept_trees_split_planes(addon, core, test_scene):
    scene = test_scene["scene"]
    build(scene)
    props = scene.bsplab_overlay
    props.show, props.max_depth, props.alpha = True, 5, 0.4
    tree = addon.overlay.draw.kept_tree()
    assert tree is not None
    draw_header(addon)  # a new tree: the header asks the viewports to redraw
    geometry = addon.overlay.draw.current_geometry(scene)
    polys = tree.split_polygons(5)
    sizes = np.diff(polys["offsets"])
    assert geometry["polygons"] == len(sizes) > 0
    assert len(geometry["face_positions"]) == sizes.sum() == len(geometry["face_colours"])
    assert len(geometry["face_indices"]) == (sizes - 2).sum()
    assert geometry["face_positions"].dtype == np.float32
    # Kind colours: the panel's swatches, per vertex, with the panel's alpha.
    x = core.tree.KINDS.index("x")
    first_x = int(np.argmax(polys["kind"] == x))
    assert polys["kind"][first_x] == x
    row = polys["offsets"][first_x]
    assert np.allclose(geometry["face_colours"][row], (*props.colour_x, 0.4), atol=1e-4)
    assert "{:,} split polygons".format(len(sizes)) in panel_labels(addon)
    # The same arrays until something changes; a new colour makes new ones.
    assert addon.overlay.draw.current_geometry(scene) is geometry
    props.colour_x = (0.0, 1.0, 1.0)
    recoloured = addon.overlay.draw.current_geometry(scene)
    assert recoloured is not geometry
    assert np.allclose(recoloured["face_colours"][row, :3], (0.0, 1.0, 1.0))


def test_cap_and_cells_notes(addon, core, test_scene):
    scene = test_scene["scene"]
    build(scene)
    props = scene.bsplab_overlay
    props.show, props.max_depth, props.cells = True, 6, True
    whole = addon.overlay.draw.current_geometry(scene)["polygons"]
    props.cap = 5
    geometry = addon.overlay.draw.current_geometry(scene)
    assert geometry["cut"] and geometry["polygons"] == 5
    labels = panel_labels(addon)
    assert "showing 5 of {:,} split polygons (cut at 5)".format(whole) in labels
    assert geometry["cells"] == 5 and geometry["cells_cut"]
    assert "5 cells (cut at 5)" in labels
    assert len(geometry["cell_indices"]) > 0


def test_under_cursor_draws_the_cursors_subtree(addon, core, test_scene):
    scene = test_scene["scene"]
    build(scene)
    props = scene.bsplab_overlay
    props.show, props.scope, props.subtree_depth, props.max_depth = True, "cursor", 2, 3
    scene.cursor.location = (0.3, 0.2, 1.1)  # inside the subdivided cube
    tree = addon.overlay.draw.kept_tree()
    node, depth = tree.node_at((0.3, 0.2, 1.1), max_depth=2)
    geometry = addon.overlay.draw.current_geometry(scene)
    assert (geometry["root"], geometry["root_depth"]) == (node, depth)
    assert geometry["polygons"] == len(tree.split_polygons(3, root=node)["node"])
    assert "subtree of node {:,} (depth {})".format(node, depth) in panel_labels(addon)
    scene.cursor.location = (500.0, 500.0, 500.0)
    assert addon.overlay.draw.current_geometry(scene)["polygons"] == 0
    assert "3D cursor is outside the tree's box" in panel_labels(addon)


def test_loading_a_file_removes_the_handler_and_the_arrays(addon, core, test_scene):
    scene = test_scene["scene"]
    build(scene)
    scene.bsplab_overlay.show = True
    assert addon.overlay.draw.current_geometry(scene) is not None
    utils.reset_file()
    assert not addon.overlay.draw.handler_installed()
    assert addon.overlay.draw.kept_tree() is None
    assert addon.state.STATE.overlay_batches[0] is None


def test_unregister_removes_the_handler(addon, empty_scene):
    empty_scene.bsplab_overlay.show = True
    assert addon.overlay.draw.handler_installed()
    addon.unregister()
    try:
        assert not addon.overlay.draw.handler_installed()
        assert not hasattr(bpy.types.Scene, "bsplab_overlay")
        assert addon.state.before_load not in bpy.app.handlers.load_pre
    finally:
        addon.register()
    utils.reset_file()
    assert not addon.overlay.draw.handler_installed()


@pytest.mark.parametrize("name, value", [("max_depth", -1), ("cap", 0), ("alpha", 2.0)])
def test_out_of_range_settings_are_clamped_by_the_properties(addon, empty_scene, name, value):
    props = empty_scene.bsplab_overlay
    setattr(props, name, value)
    settings = addon.overlay.geometry.settings_of(props)  # valid: no ValueError
    assert getattr(settings, name) == getattr(props, name) != value


def test_colour_by_depth_shows_the_ramp_in_the_legend(addon, core, test_scene):
    scene = test_scene["scene"]
    build(scene)
    props = scene.bsplab_overlay
    props.show, props.colour_by, props.max_depth = True, "depth", 4
    assert "depth 0 orange \u2192 depth 4 blue" in panel_labels(addon)
    geometry = addon.overlay.draw.current_geometry(scene)
    ramp = addon.overlay.geometry.DEPTH_RAMP
    # Polygon 0 is the root's (depth 0): its first vertex has the ramp's start.
    assert geometry["depth"][0] == 0
    assert np.allclose(geometry["face_colours"][0, :3], ramp[0])
    deepest = np.repeat(geometry["depth"], np.diff(scene_offsets(addon, 4)))
    assert (deepest == 4).any()
    assert np.allclose(geometry["face_colours"][deepest == 4, :3], ramp[1])


def scene_offsets(addon, depth):
    return addon.overlay.draw.kept_tree().split_polygons(depth)["offsets"]

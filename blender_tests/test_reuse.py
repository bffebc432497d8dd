"""Pressing Build & Render again: the tree is re-used while the scene's
triangles and the build options are unchanged, rebuilt when they change
(addon/tree_cache.py)."""

import bpy
import numpy as np
import pytest

import bsplab_test_utils as utils
from test_operator import core_render_of_scene
from test_ui import draw


def press(scene):
    """Press the button; return whether the tree was re-used."""
    assert bpy.ops.bsplab.build_render() == {'FINISHED'}
    return scene.bsplab.stats["build"]["reused"]


def panel_row(addon, label):
    """The text the Statistics panel draws beside `label`."""
    texts = [text for kind, text in draw(addon.build_render.panel.BSPLAB_PT_stats) if kind == "label"]
    return texts[texts.index(label) + 1]


def preview_pixels(addon):
    return utils.image_pixels_top_down(bpy.data.images[addon.jobs.preview.IMAGE_NAME]).copy()


def test_second_press_reuses_the_tree_and_renders_the_new_shading(addon, core, test_scene):
    scene = test_scene["scene"]
    assert press(scene) is False
    assert panel_row(addon, "Tree") == "new"
    first = scene.bsplab.stats
    shaded = preview_pixels(addon)

    scene.bsplab.render_mode = "normal"
    assert press(scene) is True
    assert panel_row(addon, "Tree") == "reused"
    second = scene.bsplab.stats
    # The re-used tree's own statistics: the build time of the first press.
    assert second["build"]["build_seconds"] == first["build"]["build_seconds"]
    assert second["build"]["nodes"] == first["build"]["nodes"]
    assert second["render"]["mode"] == "normal"
    # The image is updated: the normal-mode render of the scene.
    normal = preview_pixels(addon)
    _, expected = core_render_of_scene(core, scene, 80, 60, "normal")
    assert np.allclose(normal, expected, atol=1e-6)
    assert not np.allclose(normal, shaded)


@pytest.mark.parametrize("change", ["preview_size", "camera", "threads", "cull"])
def test_what_does_not_change_the_tree_reuses_it(addon, core, test_scene, change):
    scene = test_scene["scene"]
    assert press(scene) is False
    if change == "preview_size":
        scene.bsplab.preview_percentage = 25
    elif change == "camera":
        test_scene["camera"].location.x += 1.0
        bpy.context.view_layer.update()
    elif change == "threads":
        scene.bsplab.threads = 1
    else:
        scene.bsplab.cull = True
    assert press(scene) is True
    width, height = (40, 30) if change == "preview_size" else (80, 60)
    _, expected = core_render_of_scene(core, scene, width, height)
    assert np.allclose(preview_pixels(addon), expected, atol=1e-6)


def _move_a_vertex(test_scene):
    mesh = test_scene["cube"].data
    mesh.vertices[0].co.z -= 0.5
    mesh.update()


def _change_the_modifier(test_scene):
    test_scene["cube"].modifiers["Subdivision"].levels = 1


def _move_an_object(test_scene):
    test_scene["cube"].location.x += 0.5


def _change_the_method(test_scene):
    test_scene["scene"].bsplab.method = "rbsp"


def _change_a_build_option(test_scene):
    test_scene["scene"].bsplab.leaf_size = 4


def _hide_an_object(test_scene):
    test_scene["instancers"][0].hide_set(True)


@pytest.mark.parametrize("change", [_move_a_vertex, _change_the_modifier, _move_an_object,
                                    _change_the_method, _change_a_build_option,
                                    _hide_an_object],
                         ids=lambda f: f.__name__.lstrip("_"))
def test_what_changes_the_tree_rebuilds_it(addon, core, test_scene, change):
    scene = test_scene["scene"]
    assert press(scene) is False
    change(test_scene)
    bpy.context.view_layer.update()
    assert press(scene) is False
    assert panel_row(addon, "Tree") == "new"
    # The new tree's picture, not the old one's.
    _, expected = core_render_of_scene(core, scene, 80, 60)
    assert np.allclose(preview_pixels(addon), expected, atol=1e-6)
    assert press(scene) is True  # and that tree is kept in turn


def test_loading_a_file_forgets_the_tree(addon, core, test_scene):
    scene = test_scene["scene"]
    assert press(scene) is False
    cache = addon.state.STATE.tree_cache
    assert len(cache) == 1
    assert addon.state.before_load in bpy.app.handlers.load_pre
    # The very same scene again, in a new file: built anew, not re-used.
    test_scene = dict(utils.build_test_scene(utils.reset_file()))
    assert len(cache) == 0
    assert press(bpy.context.scene) is False


def test_unregister_forgets_the_tree(addon, core, test_scene):
    assert press(test_scene["scene"]) is False
    cache = addon.state.STATE.tree_cache
    assert len(cache) == 1
    addon.unregister()
    try:
        assert len(cache) == 0
        assert addon.state.before_load not in bpy.app.handlers.load_pre
    finally:
        addon.register()
    assert addon.state.before_load in bpy.app.handlers.load_pre


@pytest.mark.parametrize("build, tree, embree", [
    ({"reused": True, "fingerprint_seconds": 0.012}, "reused", "reused"),
    ({"reused": False, "fingerprint_seconds": 0.012}, "new", "new"),
    ({}, "-", None),  # statistics saved before the add-on kept trees
])
def test_stats_rows_say_whether_the_tree_was_reused(addon, build, tree, embree):
    stats = {"build": dict(build, build_seconds=1.5),
             "embree": {"available": True, "bsplab_seconds": 0.02, "embree_seconds": 0.01,
                        "time_ratio": 2.0, "compare": {},
                        **({"embree_reused": embree == "reused"} if embree else {})}}
    rows = dict(row for _, section in addon.build_render.statistics.sections(stats) for row in section)
    assert rows["Tree"] == tree
    assert rows["Build Time"] == "1.50 s"
    assert rows["Fingerprint"] == ("12.0 ms" if build else "-")
    assert rows.get("Embree Scene") == embree

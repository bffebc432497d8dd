"""The ray inspector (addon/inspector*.py): a preview pixel's ray is the ray
the preview traced, its walk is trace_path's, the viewport arrays are sized
and coloured as documented, and every bad pick says why."""

import types

import bpy
import numpy as np
import pytest

import bsplab_test_utils as utils
from test_ui import draw


def press(scene, mode="shaded"):
    scene.bsplab.render_mode = mode
    assert bpy.ops.bsplab.build_render() == {'FINISHED'}


def kept(addon):
    build = addon.state.STATE.shown_build
    return build, build.tree()


def preview_rays(addon, core):
    """The camera rays Build & Render traced, and its kept tree's hits of them."""
    build, tree = kept(addon)
    cam = addon.jobs.scene_reader.make_camera(core, build.camera)
    origins, directions = cam.rays(*build.render_size)
    hits = tree.intersect(origins, directions, cull=build.cull, counters=False)
    return origins, directions, hits


def pick(addon, x, y):
    """Inspect preview pixel (x, y from the bottom); the inspection."""
    assert bpy.ops.bsplab.inspect_pixel(x=x, y=y) == {'FINISHED'}
    return addon.state.STATE.inspection


def fails_with(operator, text, **props):
    """The operator is cancelled with an error report containing `text`."""
    with pytest.raises(RuntimeError, match=text):
        operator(**props)


def image_size(addon):
    return tuple(bpy.data.images[addon.jobs.preview.IMAGE_NAME].size)


def assert_same_walk(inspection, path):
    assert inspection["counts"]["steps"] == path["steps"] == len(inspection["rows"])
    for key in ("general_steps", "tests", "culled"):
        assert inspection["counts"][key] == path[key]
    for key in ("node", "kind", "t_range", "test_prim", "test_result"):
        assert np.array_equal(inspection["path"][key], path[key])


def test_a_pixel_ray_is_the_ray_the_preview_traced(addon, core, test_scene):
    press(test_scene["scene"])
    build, _ = kept(addon)
    width, height = build.render_size
    origins, directions, _ = preview_rays(addon, core)
    cam = addon.jobs.scene_reader.make_camera(core, build.camera)
    for row in range(height):
        for x in range(width):
            o, d = addon.inspector.trace.pixel_ray(cam, width, height, x, row)
            i = row * width + x
            assert np.array_equal(o, origins[i]) and np.array_equal(d, directions[i]), (x, row)


@pytest.mark.parametrize("mode", ["shaded", "heat_steps", "heat_culled"])
def test_pick_gives_the_preview_hit_and_trace_paths_walk(addon, core, test_scene, mode):
    scene = test_scene["scene"]
    press(scene, mode)
    build, tree = kept(addon)
    assert build.cull == (mode == "heat_culled")
    width, height = build.render_size
    _, image_h = image_size(addon)
    origins, directions, hits = preview_rays(addon, core)
    # The cube's centre, the ground below it, the sky above.
    for x, row in ((width // 2, height // 2), (width // 2, height - 2), (3, 1)):
        i = row * width + x
        inspection = pick(addon, x, image_h - 1 - row)
        assert np.array_equal(inspection["origin"], origins[i])
        assert np.array_equal(inspection["direction"], directions[i])
        totals = inspection["counts"]
        if hits["prim"][i] < 0:
            assert totals["hit_prim"] is None
        else:
            assert totals["hit_prim"] == hits["prim"][i]
            assert totals["hit_t"] == hits["t"][i]
        assert_same_walk(inspection, tree.trace_path(origins[i], directions[i],
                                                     cull=build.cull))
    assert pick(addon, width // 2, image_h - 1 - height // 2)["counts"]["hit_prim"] is not None


@pytest.mark.parametrize("method", ["kd", "bsp_wn+kd"])
def test_step_rows_say_kind_plane_range_and_tests(addon, core, test_scene, method):
    test_scene["scene"].bsplab.method = method
    press(test_scene["scene"])
    build, tree = kept(addon)
    width, height = build.render_size
    inspection = pick(addon, width // 2, image_size(addon)[1] - 1 - height // 2)
    path = inspection["path"]
    if method != "kd":  # the general planes are listed too
        assert inspection["counts"]["general_steps"] > 0
        general = np.flatnonzero(path["kind"] == core.tree.KINDS.index("general"))
        n0, n1, n2, d = path["plane"][general[0]]
        assert inspection["rows"][general[0]][2] == "({:.2f},{:.2f},{:.2f})p = {:.3g}".format(
            n0, n1, n2, d)
    tested_refs = np.isin(path["test_result"], (0, 1))
    assert sum(row[5] for row in inspection["rows"]) == np.count_nonzero(tested_refs)
    for i, (number, kind, plane, t0, t1, tests, culled) in enumerate(inspection["rows"]):
        assert number == i + 1
        assert kind == core.tree.KINDS[path["kind"][i]]
        assert (t0, t1) == tuple(path["t_range"][i])
        if kind in ("x", "y", "z"):
            assert plane == "{} = {:.3g}".format(kind, path["plane"][i][3])
        if kind != "leaf":
            assert plane and tests == 0 and culled == 0
        else:
            assert plane == ""
            assert tests == np.count_nonzero(tested_refs & (path["test_step"] == i))


def test_draw_data_sizes_and_colours(addon, core, test_scene):
    press(test_scene["scene"])
    build, tree = kept(addon)
    width, height = build.render_size
    inspection = pick(addon, width // 2, image_size(addon)[1] - 1 - height // 2)
    data, path = inspection["draw"], inspection["path"]
    draw_mod = addon.inspector.draw
    hit_prim, hit_t = inspection["counts"]["hit_prim"], inspection["counts"]["hit_t"]
    # The ray from the eye to the hit point.
    expected_end = inspection["origin"].astype(np.float64) + hit_t * inspection["direction"]
    assert data["ray"].shape == (2, 3)
    assert np.allclose(data["ray"][1], expected_end, atol=1e-5)
    assert np.array_equal(data["hit"], data["ray"][1:])
    # One triangle per reference tested (repeats left out), the hit in green.
    drawn = path["test_result"] != 3
    assert data["tri_coords"].shape == (3 * np.count_nonzero(drawn), 3)
    assert data["tri_colours"].shape == (3 * np.count_nonzero(drawn), 4)
    prims = path["test_prim"][drawn]
    for k, prim in enumerate(prims):
        assert np.array_equal(data["tri_coords"][3 * k:3 * k + 3], tree.triangles[prim])
        colour = tuple(data["tri_colours"][3 * k])
        if prim == hit_prim:
            assert colour == pytest.approx(draw_mod.HIT_COLOUR)
        elif path["test_result"][drawn][k] == 0:
            assert colour == pytest.approx(draw_mod.MISS_COLOUR)
    assert hit_prim in prims
    # The visited leaves' own cells, first blue, last magenta; each holds the
    # middle of the ray's stretch through it.
    leaves = np.flatnonzero(path["kind"] == 3)
    edges = [tree.leaf_cells(max_depth=0, root=int(path["node"][i]))["edges"] for i in leaves]
    assert data["cell_coords"].shape == (2 * sum(len(e) for e in edges), 3)
    assert tuple(data["cell_colours"][0]) == pytest.approx(tuple(draw_mod.FIRST_CELL))
    assert tuple(data["cell_colours"][-1]) == pytest.approx(tuple(draw_mod.LAST_CELL))
    o, d = inspection["origin"].astype(np.float64), inspection["direction"].astype(np.float64)
    for i in leaves:
        t0, t1 = path["t_range"][i]
        if t1 - t0 > 1e-4:
            point = o + (t0 + t1) / 2 * d
            assert tree.node_at(point)[0] == path["node"][i]


def test_a_viewport_ray_that_misses_the_box_is_still_drawn(addon, core, test_scene):
    press(test_scene["scene"])
    origin, direction = (100.0, 100.0, 100.0), (1.0, 0.0, 0.0)
    assert bpy.ops.bsplab.inspect_ray(origin=origin, direction=direction) == {'FINISHED'}
    inspection = addon.state.STATE.inspection
    assert inspection["missed_box"] and inspection["counts"]["steps"] == 0
    assert ("Hit", "none: missed the tree box") in addon.inspector.panel.count_rows(inspection)
    ray = inspection["draw"]["ray"]
    assert np.array_equal(ray[0], origin) and ray[1][0] > 100.0 and len(inspection["draw"]["hit"]) == 0


def test_a_viewport_ray_walk_is_trace_paths(addon, core, test_scene):
    press(test_scene["scene"])
    _, tree = kept(addon)
    origin, direction = (0.3, 0.2, 10.0), (0.0, 0.0, -1.0)
    assert bpy.ops.bsplab.inspect_ray(origin=origin, direction=direction) == {'FINISHED'}
    inspection = addon.state.STATE.inspection
    # The subdivided cube's top (rounded below z = 2 by the subdivision).
    assert 8.0 <= inspection["counts"]["hit_t"] < 9.0
    assert_same_walk(inspection, tree.trace_path(origin, direction))


def test_panel_lists_counts_and_caps_the_steps(addon, core, test_scene, monkeypatch):
    panel = addon.inspector.panel
    assert ("label", "Pick a preview pixel or a viewport point") in draw(panel.BSPLAB_PT_inspector)
    press(test_scene["scene"])
    build, _ = kept(addon)
    width, height = build.render_size
    inspection = pick(addon, width // 2, image_size(addon)[1] - 1 - height // 2)
    log = draw(panel.BSPLAB_PT_inspector)
    assert ("operator", "bsplab.inspect_pick") in log and ("operator", "bsplab.inspect_clear") in log
    labels = [text for kind, text in log if kind == "label"]
    steps = inspection["counts"]["steps"]
    assert labels[labels.index("Steps") + 1].startswith(str(steps))
    assert labels[labels.index("Tests") + 1] == str(inspection["counts"]["tests"])
    assert labels.count("node") == 1  # the header
    assert "leaf" in labels
    monkeypatch.setattr(panel, "MAX_ROWS", 2)
    lines, more = panel.step_lines(inspection, 2)
    assert len(lines) == 2 and more == steps - 2
    monkeypatch.setattr(panel, "step_lines", lambda insp: (lines, more))
    assert "... {} more steps".format(more) in [t for k, t in draw(panel.BSPLAB_PT_inspector)
                                                if k == "label"]
    assert bpy.ops.bsplab.inspect_clear() == {'FINISHED'}
    assert addon.state.STATE.inspection is None


# -----------------------------------------------------------------------------
# Bad picks


def test_no_tree_yet(addon, test_scene):
    fails_with(bpy.ops.bsplab.inspect_pixel, "No tree to inspect yet", x=1, y=1)
    fails_with(bpy.ops.bsplab.inspect_ray, "No tree to inspect yet")


def test_tree_no_longer_kept(addon, test_scene):
    press(test_scene["scene"])
    addon.state.STATE.forget_trees()
    fails_with(bpy.ops.bsplab.inspect_pixel, "no longer kept", x=1, y=1)


@pytest.mark.parametrize("x, y", [(-1, 5), (5, -1), (10**6, 5), (5, 10**6)])
def test_pixel_outside_the_image(addon, test_scene, x, y):
    press(test_scene["scene"])
    fails_with(bpy.ops.bsplab.inspect_pixel, "outside the preview image", x=x, y=y)


def test_pixel_on_the_colour_bar(addon, test_scene):
    press(test_scene["scene"], "heat_tests")
    build, _ = kept(addon)
    image_w, image_h = image_size(addon)
    bar_rows = image_h - build.render_size[1]
    assert bar_rows > 0
    fails_with(bpy.ops.bsplab.inspect_pixel, "on the colour bar", x=2, y=bar_rows - 1)
    # The render's bottom row, just above the bar, is fine.
    assert bpy.ops.bsplab.inspect_pixel(x=2, y=bar_rows) == {'FINISHED'}


def change(test_scene, what):
    cube = test_scene["cube"]
    if what == "move":
        cube.location.x += 0.5
    elif what == "modifier":
        cube.modifiers[0].levels = 1
    elif what == "hide":
        cube.hide_set(True)
    elif what == "delete":
        bpy.data.objects.remove(test_scene["ground"])
    elif what == "add":
        utils.link(test_scene["scene"], "New", utils.quad_mesh("New"), (0, 0, 5))
    bpy.context.view_layer.update()


@pytest.mark.parametrize("what", ["move", "modifier", "hide", "delete", "add"])
def test_scene_changed_since_the_build(addon, test_scene, what):
    scene = test_scene["scene"]
    press(scene)
    change(test_scene, what)
    fails_with(bpy.ops.bsplab.inspect_pixel, "scene changed since the last Build", x=1, y=1)
    fails_with(bpy.ops.bsplab.inspect_ray, "scene changed since the last Build")
    press(scene)  # a new build of the scene as it is now
    assert bpy.ops.bsplab.inspect_pixel(x=1, y=1) == {'FINISHED'}


def test_moving_the_camera_keeps_the_previews_rays(addon, core, test_scene):
    scene = test_scene["scene"]
    press(scene)
    origins, directions, _ = preview_rays(addon, core)
    test_scene["camera"].location.x += 1.0
    # Neither a selection nor the render mode changes the triangles.
    test_scene["cube"].select_set(True)
    scene.bsplab.render_mode = "normal"
    bpy.context.view_layer.update()
    build, _ = kept(addon)
    width, height = build.render_size
    inspection = pick(addon, 4, image_size(addon)[1] - 1 - 7)
    assert np.array_equal(inspection["direction"], directions[7 * width + 4])
    assert np.array_equal(inspection["origin"], origins[0])


def test_preview_image_replaced(addon, test_scene):
    press(test_scene["scene"])
    image = bpy.data.images[addon.jobs.preview.IMAGE_NAME]
    image.scale(7, 5)
    fails_with(bpy.ops.bsplab.inspect_pixel, "no longer the last Build", x=1, y=1)
    bpy.data.images.remove(image)
    fails_with(bpy.ops.bsplab.inspect_pixel, "is gone", x=1, y=1)


def test_pick_needs_a_window(addon, test_scene):
    press(test_scene["scene"])
    fails_with(bpy.ops.bsplab.inspect_pick, "Picking needs a window")


def test_zero_direction(addon, test_scene):
    press(test_scene["scene"])
    fails_with(bpy.ops.bsplab.inspect_ray, "must not be", direction=(0.0, 0.0, 0.0))


def test_a_loaded_file_forgets_the_inspection(addon, test_scene):
    press(test_scene["scene"])
    assert bpy.ops.bsplab.inspect_pixel(x=1, y=1) == {'FINISHED'}
    utils.reset_file()
    assert addon.state.STATE.inspection is None
    assert addon.state.STATE.shown_build is None


def test_an_unexpected_failure_is_reported_not_raised(addon, test_scene, monkeypatch):
    press(test_scene["scene"])

    def broken(*_args):
        raise KeyError("boom")
    monkeypatch.setattr(addon.inspector.operators.trace, "inspect", broken)
    fails_with(bpy.ops.bsplab.inspect_pixel, "ray inspector failed: KeyError", x=1, y=1)


def test_image_editor_point_to_pixel(addon, test_scene):
    """region_to_view gives the image's 0..1 coordinates: the pixel is their
    floor times the size; another image in the editor is refused."""
    press(test_scene["scene"])
    image = bpy.data.images[addon.jobs.preview.IMAGE_NAME]
    width, height = image.size
    region = types.SimpleNamespace(view2d=types.SimpleNamespace(
        region_to_view=lambda x, y: (x / 1000.0, y / 1000.0)))
    space = types.SimpleNamespace(image=image)
    u, v = (10.5 / width, (height - 0.5) / height)
    assert addon.inspector.operators.image_editor_pixel(space, region, u * 1000, v * 1000) == (10, height - 1)
    other = bpy.data.images.new("Other", 4, 4)
    with pytest.raises(addon.jobs.worker.UserError, match="does not show the 'BSP Lab Preview'"):
        addon.inspector.operators.image_editor_pixel(types.SimpleNamespace(image=other), region, 1, 1)
    with pytest.raises(addon.jobs.worker.UserError, match="does not show"):
        addon.inspector.operators.image_editor_pixel(types.SimpleNamespace(image=None), region, 1, 1)


def test_region_under_prefers_the_sidebar(addon):
    """A click on a sidebar that overlaps the 3D view's main region is no pick."""
    def rect(kind, x, y, w, h):
        return types.SimpleNamespace(type=kind, x=x, y=y, width=w, height=h)
    main, ui = rect('WINDOW', 0, 0, 800, 600), rect('UI', 600, 0, 200, 600)
    area = types.SimpleNamespace(type='VIEW_3D', x=0, y=0, width=800, height=600,
                                 regions=[main, ui])
    window = types.SimpleNamespace(screen=types.SimpleNamespace(areas=[area]))
    assert addon.inspector.operators.region_under(window, 100, 100) == (area, main)
    assert addon.inspector.operators.region_under(window, 700, 100) == (area, None)
    assert addon.inspector.operators.region_under(window, 900, 100) == (None, None)


@pytest.mark.parametrize("view", ["split", "diff_steps"])
def test_an_ab_preview_picks_the_tree_shown_there(addon, core, test_scene, view):
    """Split: left of the line tree A's walk, right of it tree B's, on the
    line a message. A difference map is picked as A's."""
    from test_compare import set_b
    scene = test_scene["scene"]
    set_b(scene, view=view)
    press(scene)
    build, tree_a = kept(addon)
    width, height = build.render_size
    column = addon.compare.images.split_column(width)
    image_h = image_size(addon)[1]
    for x, side in ((column - 3, "A"), (column + 3, "B")):
        inspection = pick(addon, x, image_h - 1 - height // 2)
        tree = build.split_b() if view == "split" and side == "B" else tree_a
        assert tree is not None
        path = tree.trace_path(inspection["origin"], inspection["direction"], cull=build.cull)
        assert_same_walk(inspection, path)
        assert inspection["source"].endswith(", tree " + side) == (view == "split")
        if tree is not tree_a:  # and B's walk is not A's
            walk_a = tree_a.trace_path(inspection["origin"], inspection["direction"])
            assert not np.array_equal(walk_a["kind"], inspection["path"]["kind"])
    if view == "split":
        assert build.split_b() is not tree_a
        fails_with(bpy.ops.bsplab.inspect_pixel, "on the line between A and B",
                   x=column, y=image_h - 1 - height // 2)
    else:
        assert build.split_b() is None

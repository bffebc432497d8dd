"""The ray inspector in a real Blender window (run by run_all.sh unless
BSPLAB_GUI_CHECK=0; needs Xvfb, xdotool and ImageMagick's `import`).

    xvfb-run -a -s "-screen 0 1600x900x24" blender --factory-startup -noaudio \\
        --python blender_tests/gui_check_inspector.py -- OUT_DIR

Builds the test scene with Build & Render, starts the panel's eyedropper
(bsplab.inspect_pick, modal) and clicks - a real xdotool click - a preview
pixel on the cube in an Image Editor; checks that the inspection is that
pixel's and that its hit is the preview's. Then turns the 3D view to look at
the ray from the side, screenshots the screen and asserts on its pixels:
the hit colour (green) around the projected hit point, the ray colour
(yellow) along the projected ray. Last, a click in the 3D view inspects
the view's ray, and a ray passing above the tree's box is drawn alone. Writes OUT_DIR/gui_check_inspector.json, the screenshots,
and exits 0 when every check passed.
"""

import json
import math
import os
import pathlib
import shutil
import sys

import bpy
import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import bsplab_test_utils as utils  # noqa: E402
import gui_utils  # noqa: E402
from gui_utils import grab_screen  # noqa: E402

OUT, _, report = utils.gui_check_output("/tmp/bsplab_gui")
WAITS = gui_utils.Waits()
POLL = gui_utils.POLL_SECONDS
SEARCH = 10  # pixels around a projected point searched for its colour


def area_of(kind):
    window = bpy.context.window_manager.windows[0]
    return window, max((a for a in window.screen.areas if a.type == kind),
                       key=lambda a: a.width * a.height)


def main_region(area):
    return next(r for r in area.regions if r.type == 'WINDOW')


def screenshot(name):
    """The screen as (H, W, 3) floats, row 0 at the top, and its file."""
    path = OUT / (name + ".png")
    pixels = grab_screen(path).astype(np.float32) / 255.0
    report["events"].append("screenshot " + str(path))
    return pixels, path


def colour_near(pixels, window, point, test):
    """How many pixels around window point `point` pass `test(rgb)`."""
    x, y = int(point[0]), int(window.height - point[1])
    patch = pixels[max(0, y - SEARCH):y + SEARCH + 1, max(0, x - SEARCH):x + SEARCH + 1]
    return int(np.count_nonzero(test(patch)))


def greenish(p):
    return (p[..., 1] > 0.55) & (p[..., 1] > p[..., 0] + 0.3) & (p[..., 1] > p[..., 2] + 0.3)


def yellowish(p):
    return (p[..., 0] > 0.6) & (p[..., 1] > 0.5) & (p[..., 2] < 0.35)


def to_window(region, point3d):
    from bpy_extras import view3d_utils
    rv3d = region.data
    xy = view3d_utils.location_3d_to_region_2d(region, rv3d, point3d)
    return None if xy is None else (region.x + xy[0], region.y + xy[1])


def pick_at(point):
    """Press the panel's Pick Ray (the modal eyedropper: its handler is in
    place when the call returns), then click at window point `point`; the
    caller waits for the new inspection (`inspected_since`)."""
    window, area = area_of('VIEW_3D')
    ui = next(r for r in area.regions if r.type == 'UI')
    state["inspection_before"] = utils.load_addon().state.STATE.inspection
    with bpy.context.temp_override(window=window, area=area, region=ui):
        result = bpy.ops.bsplab.inspect_pick('INVOKE_DEFAULT')
    report["events"].append("eyedropper -> {}".format(sorted(result)))
    gui_utils.click(window, *point)


def picked(what):
    """True once the click of pick_at made a new inspection (raises after
    the time-out)."""
    return WAITS.until(what, lambda: utils.load_addon().state.STATE.inspection
                       not in (None, state["inspection_before"]))


def finish():
    checks = ("pixel_pick_ok", "hit_matches_preview", "green_at_hit", "yellow_on_ray",
              "viewport_pick_ok", "missed_box", "yellow_on_missed_ray")
    report["ok"] = all(report.get(name) for name in checks) and "error" not in report
    (OUT / "gui_check_inspector.json").write_text(json.dumps(report, indent=1))
    sys.stdout.flush()
    os._exit(0 if report["ok"] else 1)


state = {"phase": "start"}


def setup():
    scene = bpy.context.scene
    for obj in list(scene.objects):
        bpy.data.objects.remove(obj)
    utils.build_test_scene(scene)
    scene.bsplab.instances = "flatten"  # the inspector walks flat trees only (yet)
    scene.bsplab.preview_percentage = 100
    window, area = area_of('VIEW_3D')
    area.spaces.active.show_region_ui = True
    others = [a for a in window.screen.areas if a.type != 'VIEW_3D']
    max(others, key=lambda a: a.width * a.height).type = 'IMAGE_EDITOR'


def open_tab():
    """Open the sidebar's BSP Lab tab (for the panel's screenshot): the third
    while no object is active (an active one adds the Item tab)."""
    window, area = area_of('VIEW_3D')
    bpy.context.view_layer.objects.active = None
    ui = next(r for r in area.regions if r.type == 'UI')
    gui_utils.click(window, ui.x + ui.width - 8,
                    ui.y + ui.height - int(120 * bpy.context.preferences.view.ui_scale))


def preview_target(addon):
    """A preview pixel on the cube (x, y from the bottom), its window point
    in the Image Editor, and the preview's hit there."""
    build = addon.state.STATE.shown_build
    width, height = build.render_size
    x, row = width // 2, height // 2 + 5
    y = build.image_size[1] - 1 - row
    cam = addon.jobs.scene_reader.make_camera(__import__("bsplab"), build.camera)
    origins, directions = cam.rays(width, height)
    hits = build.tree().intersect(origins, directions, cull=build.cull, counters=False)
    window, area = area_of('IMAGE_EDITOR')
    region = main_region(area)
    rx, ry = region.view2d.view_to_region((x + 0.5) / build.image_size[0],
                                          (y + 0.5) / build.image_size[1], clip=False)
    return (x, y), (region.x + rx, region.y + ry), int(hits["prim"][row * width + x])


def side_view():
    """Look at the cube from the +x side: the camera's rays are lines there."""
    from mathutils import Euler, Vector
    _, area = area_of('VIEW_3D')
    rv3d = main_region(area).data
    rv3d.view_perspective = 'PERSP'
    rv3d.view_location = Vector((0.0, -4.0, 1.5))
    rv3d.view_rotation = Euler((math.radians(80), 0.0, math.radians(90))).to_quaternion()
    rv3d.view_distance = 16.0
    area.tag_redraw()


def check_drawing(addon):
    pixels, _ = screenshot("inspector")
    inspection = addon.state.STATE.inspection
    window, area = area_of('VIEW_3D')
    region = main_region(area)
    data = inspection["draw"]
    hit = to_window(region, data["ray"][1])
    report["green_near_hit"] = colour_near(pixels, window, hit, greenish) if hit else 0
    report["green_at_hit"] = report["green_near_hit"] >= 10
    yellow = []
    for f in (0.55, 0.7, 0.85):
        point = to_window(region, data["ray"][0] + f * (data["ray"][1] - data["ray"][0]))
        yellow.append(colour_near(pixels, window, point, yellowish) if point else 0)
    report["yellow_on_ray"] = yellow
    report["yellow_on_ray"] = all(n >= 5 for n in yellow) and yellow


def step():
    addon = utils.load_addon()
    phase = state["phase"]
    if phase == "start":
        setup()
        gui_utils.redraw_window()  # the sidebar laid out: its tabs have their places
        # For the panel's screenshot only, nothing asserted: the click is
        # handled before the eyedropper of the next step starts.
        open_tab()
        state["phase"] = "pick"
        return POLL
    if phase == "pick":
        assert bpy.ops.bsplab.build_render() == {'FINISHED'}
        # The Image Editor drawn with the preview: its view is set up.
        gui_utils.redraw_window()
        # Four screen pixels a preview pixel: a click at a pixel's centre
        # cannot land on its neighbour by a rounding of the click.
        window, area = area_of('IMAGE_EDITOR')
        with bpy.context.temp_override(window=window, area=area, region=main_region(area)):
            bpy.ops.image.view_zoom_ratio(ratio=4.0)
        gui_utils.redraw_window()
        state["pixel"], point, state["prim"] = preview_target(addon)
        pick_at(point)
        state["phase"] = "picked"
        return POLL
    if phase == "picked":
        if not picked("the click on the preview pixel to be inspected"):
            return POLL
        inspection = addon.state.STATE.inspection
        report["pixel"] = list(state["pixel"])
        report["source"] = inspection and inspection["source"]
        report["pixel_pick_ok"] = bool(inspection) and inspection["source"] == \
            "pixel ({}, {})".format(*state["pixel"])
        report["hit_prim"] = inspection and inspection["counts"]["hit_prim"]
        report["hit_matches_preview"] = bool(inspection) and report["hit_prim"] == state["prim"]
        if inspection:
            report["pick_ms"] = round(1000 * inspection["seconds"], 2)
        side_view()
        state["phase"] = "look"
        return POLL
    if phase == "look":
        if report["pixel_pick_ok"]:
            check_drawing(addon)
        # Scroll the sidebar down to the Ray Inspector panel, for its picture.
        window, area = area_of('VIEW_3D')
        ui = next(r for r in area.regions if r.type == 'UI')
        with bpy.context.temp_override(window=window, area=area, region=ui):
            for _ in range(3):
                bpy.ops.view2d.scroll_down(page=True)
        screenshot("inspector_panel")
        # A click on the cube in the 3D view: the view's ray.
        pick_at(to_window(main_region(area), (0.0, 0.0, 1.0)))
        state["phase"] = "viewport picked"
        return POLL
    if phase == "viewport picked":
        if not picked("the click in the 3D view to be inspected"):
            return POLL
        inspection = addon.state.STATE.inspection
        report["viewport_pick_ok"] = bool(inspection) and inspection["source"] == "viewport" \
            and inspection["counts"]["hit_prim"] is not None
        screenshot("inspector_viewport")
        # A ray above the tree's box: no cell, no triangle, no hit; the ray
        # alone is drawn (the layers left empty make no batch).
        ray = ((0.0, -8.0, 6.0), (0.0, 1.0, 0.0))
        result = bpy.ops.bsplab.inspect_ray(origin=ray[0], direction=ray[1])
        report["events"].append("ray above the box -> {}".format(sorted(result)))
        inspection = addon.state.STATE.inspection
        report["missed_box"] = bool(inspection) and inspection["missed_box"]
        pixels, _ = screenshot("inspector_missed")
        window, area = area_of('VIEW_3D')
        point = to_window(main_region(area), (0.0, -6.0, 6.0))
        report["yellow_on_missed_ray"] = colour_near(pixels, window, point, yellowish) if point else 0
        finish()
        return None
    return None


def main():
    if shutil.which("xdotool") is None or shutil.which("import") is None:
        print("gui_check_inspector: needs xdotool and ImageMagick's import")
        os._exit(1)
    utils.start_gui_check(utils.reporting_failures(step, report, finish), report)


main()

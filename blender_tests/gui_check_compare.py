"""The A/B comparison in a real Blender window (Xvfb).

    xvfb-run -a -s "-screen 0 1600x900x24" blender --factory-startup -noaudio \\
        --python blender_tests/gui_check_compare.py -- OUT_DIR [DOCS_DIR]

Presses Build & Render through INVOKE_DEFAULT (the modal path: worker
thread, timer) with "Compare with B" on, twice: once with the split view
(heat steps, so the halves differ) and once with the difference map of the
steps. Each time the preview is shown in the big area switched to an Image
Editor, and ImageMagick's `import` screenshots the screen. Asserted:

- on the image block: the split column holds the split line's colour
  everywhere and the two trees' steps differ; the difference map is white
  in part of the image, not all of it;
- on the screenshot (what the Image Editor really drew): a vertical run of
  the split line's magenta at least half as tall as the image is shown, and
  in the difference map both ends of the diverging colours and white.

Writes OUT_DIR/gui_check_compare.json and the screenshots; with DOCS_DIR,
also the cropped Image Editor pictures for docs/addon.md
(compare_split.png, compare_diff.png). Exits 0 when every check passed.
"""

import json
import os
import pathlib
import shutil
import subprocess
import sys
import time

import bpy
import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import bsplab_test_utils as utils  # noqa: E402
import gui_utils  # noqa: E402
from gui_utils import areas  # noqa: E402

OUT, EXTRA, report = utils.gui_check_output("/tmp/bsplab_gui_compare")
WAITS = gui_utils.Waits()
POLL = gui_utils.POLL_SECONDS
DOCS = pathlib.Path(EXTRA[0]) if EXTRA else None

B_METHOD, B_K = "bsp_wn+kd", 4


def big_area():
    """The largest area of the window: the 3D view of the factory layout."""
    window = bpy.context.window_manager.windows[0]
    return window, max(window.screen.areas, key=lambda a: a.width * a.height)


def invoke():
    window, area = areas('VIEW_3D')[0]
    region = next(r for r in area.regions if r.type == 'WINDOW')
    with bpy.context.temp_override(window=window, area=area, region=region):
        return bpy.ops.bsplab.build_render('INVOKE_DEFAULT')


def show_preview():
    """Switch the big area to an Image Editor showing the preview, fitted."""
    window, area = big_area()
    area.type = 'IMAGE_EDITOR'
    area.spaces.active.image = bpy.data.images["BSP Lab Preview"]
    gui_utils.redraw_window()  # the new editor's regions laid out, for view_all
    region = next(r for r in area.regions if r.type == 'WINDOW')
    with bpy.context.temp_override(window=window, area=area, region=region):
        bpy.ops.image.view_all(fit_view=True)


def screenshot(name):
    """The Image Editor's part of the screen as (H, W, 3) floats in [0, 1]
    (row 0 at the top), or None without ImageMagick."""
    if shutil.which("import") is None:
        report["events"].append("no ImageMagick import: screenshot skipped")
        return None
    window, area = big_area()
    path = OUT / (name + ".png")
    gui_utils.grab_screen(path)
    # Screen rows grow downwards, Blender's area.y upwards.
    top = window.height - (area.y + area.height)
    crop = "{}x{}+{}+{}".format(area.width, area.height, area.x, top)
    cropped = OUT / (name + "_editor.png")
    subprocess.run(["convert", str(path), "-crop", crop, "+repage", str(cropped)], check=True)
    if DOCS is not None:
        DOCS.mkdir(parents=True, exist_ok=True)
        subprocess.run(["convert", str(cropped), "-resize", "50%", "-colors", "128",
                        str(DOCS / (name + ".png"))], check=True)
    image = bpy.data.images.load(str(cropped))
    width, height = image.size
    pixels = np.empty(width * height * 4, np.float32)
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    report["events"].append("screenshot " + str(path))
    return pixels.reshape(height, width, 4)[::-1, :, :3]


def colour_mask(rgb, colour, tolerance=0.08):
    return np.all(np.abs(rgb - np.asarray(colour, np.float32)) <= tolerance, axis=-1)


def check_split(addon):
    """The split preview's block pixels and its screenshot."""
    scene = bpy.context.scene
    preview = utils.image_pixels_top_down(bpy.data.images["BSP Lab Preview"])
    width, height = scene.render.resolution_x, scene.render.resolution_y
    start, stop = addon.compare.images.split_columns(width)
    line = preview[:height, start:stop, :3]
    report["block_line_present"] = bool(np.all(line == addon.compare.images.SPLIT_LINE))
    # Two different trees: their steps differ (the Blender tests check that
    # each half holds its own tree's pixels).
    stats = scene.bsplab.stats
    report["trees_differ"] = bool(stats["b"]["render"]["mean_steps"]
                                  != stats["render"]["mean_steps"])
    shot = screenshot("compare_split")
    if shot is None:
        return
    magenta = colour_mask(shot, addon.compare.images.SPLIT_LINE)
    run = magenta.sum(axis=0)  # magenta pixels per screen column
    report["screen_line_column_pixels"] = int(run.max())
    # The image is shown fitted: at least a third of the editor's height.
    report["screen_line_present"] = bool(run.max() >= shot.shape[0] // 3)


def check_difference(addon):
    preview = utils.image_pixels_top_down(bpy.data.images["BSP Lab Preview"])
    scene = bpy.context.scene
    width, height = scene.render.resolution_x, scene.render.resolution_y
    rgb = preview[:height, :width, :3]
    report["block_white_fraction"] = round(float(np.all(rgb == 1.0, axis=-1).mean()), 3)
    shot = screenshot("compare_diff")
    if shot is None:
        return
    # The editor shows the values through the display transform (sRGB), so
    # the two ends are matched by hue: blue over red, red over blue.
    red, blue = shot[..., 0], shot[..., 2]
    seen = {"fewer": int((blue - red > 0.3).sum()), "more": int((red - blue > 0.3).sum()),
            "white": int(colour_mask(shot, (1.0, 1.0, 1.0), 0.01).sum())}
    report["screen_diff_colours"] = seen
    report["screen_diff_ok"] = all(count > 0 for count in seen.values())


def finish():
    screen_ok = report.get("screen_line_present", True) and report.get("screen_diff_ok", True)
    report["ok"] = "error" not in report and bool(report.get("block_line_present") and report.get("trees_differ")
                        and 0.0 < report.get("block_white_fraction", 0.0) < 1.0
                        and screen_ok and report.get("presses") == 2)
    (OUT / "gui_check_compare.json").write_text(json.dumps(report, indent=1))
    sys.stdout.flush()
    os._exit(0 if report["ok"] else 1)


state = {"phase": "start", "t0": 0.0, "presses": 0}


def step():
    addon = utils.load_addon()
    job = addon.state.STATE.job
    phase = state["phase"]
    scene = bpy.context.scene
    if phase == "start":
        for obj in list(scene.objects):
            bpy.data.objects.remove(obj)
        utils.build_test_scene(scene)
        scene.render.resolution_x, scene.render.resolution_y = 480, 270
        scene.bsplab.preview_percentage = 100
        # The Image Editor shows the preview's values as they are: "Standard",
        # not Filmic, so the split line is magenta on the screen too.
        scene.view_settings.view_transform = 'Standard'
        scene.bsplab.render_mode = "heat_steps"
        compare = scene.bsplab_compare
        compare.enabled, compare.method = True, B_METHOD
        compare.k, compare.view = B_K, "split"
        state["phase"] = "press"
        return POLL
    if phase == "press":
        report["events"].append("invoke -> {}".format(sorted(invoke())))
        state.update(phase="running", t0=time.time())
        return POLL
    if phase == "running":
        if not WAITS.until("Build & Render press {} to end".format(state["presses"] + 1),
                           lambda: addon.state.STATE.job is None):
            return POLL
        state["presses"] += 1
        report["presses"] = state["presses"]
        report["stats_b_method"] = scene.bsplab.stats.get("b", {}).get("build", {}).get("method")
        report.setdefault("grids", []).append(addon.build_render.statistics.compare_table(scene.bsplab.stats))
        show_preview()
        if scene.bsplab_compare.view == "split":
            check_split(addon)
            # Back to the 3D view for the second press: the difference map.
            big_area()[1].type = 'VIEW_3D'
            scene.bsplab_compare.view = "diff_steps"
            state["phase"] = "press"
            return POLL
        check_difference(addon)
        finish()
        return None
    return None


def main():
    utils.start_gui_check(utils.reporting_failures(step, report, finish), report)


main()

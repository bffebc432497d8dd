"""Drive the modal Build & Render in a real Blender window (manual check).

    xvfb-run -a -s "-screen 0 1600x900x24" blender --factory-startup -noaudio \\
        --python blender_tests/gui_check.py -- OUT_DIR

Needs a display (Xvfb is fine), xdotool (to press Esc) and optionally
ImageMagick's `import` for screenshots. run_all.sh runs it when
BSPLAB_GUI_CHECK=1. Exits 0 when every check passed. Registers the
add-on from the source tree, adds a heavy mesh so the job runs for a few
seconds, presses Build & Render through INVOKE_DEFAULT (the modal path with
the worker thread and the timer), screenshots the window while it runs,
presses it again with only the shading mode changed (the kept tree is
re-used: a quick render), then starts a job that must build (a build
option changed) and cancels it with a real Esc key press. Writes
OUT_DIR/gui_check.json and screenshots, then quits Blender.
"""

import json
import os
import pathlib
import shutil
import subprocess
import sys
import time

import bpy

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import bsplab_test_utils as utils  # noqa: E402
import gui_utils  # noqa: E402
from gui_utils import areas  # noqa: E402

OUT, _, report = utils.gui_check_output("/tmp/bsplab_gui", progress=True)


def screenshot(name):
    if shutil.which("import") is None:  # ImageMagick
        return
    path = str(OUT / (name + ".png"))
    subprocess.run(["import", "-window", "root", path], check=False)
    report["events"].append("screenshot " + path)


def invoke(operator="build_render"):
    window, area = areas('VIEW_3D')[0]
    region = next(r for r in area.regions if r.type == 'WINDOW')
    with bpy.context.temp_override(window=window, area=area, region=region):
        return getattr(bpy.ops.bsplab, operator)('INVOKE_DEFAULT')


def press_escape():
    window, area = areas('VIEW_3D')[0]
    # xdotool: move into the 3D view (screen y grows downwards) and press Esc.
    x = area.x + area.width // 2
    y = window.height - (area.y + area.height // 2)
    subprocess.run(["xdotool", "mousemove", str(x), str(y), "key", "Escape"], check=False)


def click(window, x, y):
    gui_utils.click(window, x, y)
    time.sleep(0.2)


def finish():
    report["ok"] = bool(
        report.get("image_size") and report.get("image_editor_shows_preview")
        and report.get("stats_unchanged_after_cancel") and not report.get("is_running_after")
        and "Esc pressed" in report["events"] and report.get("reused_after_shading_change")
        and report.get("sweep_trees", 0) > 0 and report.get("sweep_plot_shown"))
    (OUT / "gui_check.json").write_text(json.dumps(report, indent=1))
    sys.stdout.flush()
    os._exit(0 if report["ok"] else 1)


state = {"phase": "start", "t0": 0.0}


def tick():
    addon = utils.load_addon()
    job = addon.state.STATE.job
    phase = state["phase"]
    if phase == "start":
        scene = bpy.context.scene
        for obj in list(scene.objects):
            bpy.data.objects.remove(obj)
        utils.build_test_scene(scene)
        scene.render.resolution_x, scene.render.resolution_y = 960, 540
        scene.bsplab.preview_percentage = 100
        # Heavy enough that building takes seconds.
        import bmesh
        mesh = bpy.data.meshes.new("Heavy")
        bm = bmesh.new()
        bmesh.ops.create_grid(bm, x_segments=600, y_segments=600, size=3.0)
        bm.to_mesh(mesh)
        bm.free()
        utils.link(scene, "Heavy", mesh, (0, -2, 1.5)).rotation_euler = (1.2, 0.3, 0.0)
        window, area = areas('VIEW_3D')[0]
        area.spaces.active.show_region_ui = True
        # Another area shows images: the preview must appear there.
        others = [a for a in window.screen.areas if a.type not in ('VIEW_3D',)]
        others[0].type = 'IMAGE_EDITOR'
        state["phase"] = "tab"
        return 1.0
    if phase == "tab":
        # Close the splash screen, then open the sidebar's "BSP Lab" tab
        # (the third one, after Tool and View).
        window, area = areas('VIEW_3D')[0]
        click(window, area.x + 200, area.y + 200)
        ui = next(r for r in area.regions if r.type == 'UI')
        tab_x = ui.x + ui.width - 8
        click(window, tab_x, ui.y + ui.height - int(120 * bpy.context.preferences.view.ui_scale))
        state["phase"] = "run"
        # Let the viewport build its draw cache of the heavy mesh first: that
        # first draw blocks the main thread for seconds, job or no job.
        return 10.0
    if phase == "run":
        result = invoke()
        report["events"].append("invoke -> {}".format(sorted(result)))
        state.update(phase="running", t0=time.time(), shot=False)
        return 0.2
    if phase == "running":
        report["progress"].append((round(time.time() - state["t0"], 2),
                                   round(job.fraction(), 3) if job else None))
        if job is not None:
            if not state["shot"] and time.time() - state["t0"] > 4.0:
                screenshot("running")
                state["shot"] = True
            return 0.2
        image = bpy.data.images.get("BSP Lab Preview")
        report["image_size"] = list(image.size) if image else None
        report["stats_triangles"] = bpy.context.scene.bsplab.stats.get("scene", {}).get("triangles")
        editors = areas('IMAGE_EDITOR')
        report["image_editor_shows_preview"] = bool(editors) and editors[0][1].spaces.active.image == image
        report["seconds"] = round(time.time() - state["t0"], 2)
        state["stats_before_cancel"] = bpy.context.scene.bsplab.stats_json
        state["phase"] = "done"
        return 1.5  # let the editors redraw before the screenshot
    if phase == "done":
        screenshot("done")
        state["phase"] = "reuse"
        return 0.5
    if phase == "reuse":
        # Only the shading changes: the modal path renders with the kept tree.
        bpy.context.scene.bsplab.render_mode = "normal"
        result = invoke()
        report["events"].append("invoke after a shading change -> {}".format(sorted(result)))
        state.update(phase="reusing", t0=time.time())
        return 0.2
    if phase == "reusing":
        if job is not None:
            return 0.2
        stats = bpy.context.scene.bsplab.stats
        report["reused_after_shading_change"] = (stats["build"].get("reused") is True
                                                 and stats["render"]["mode"] == "normal")
        report["reuse_seconds"] = round(time.time() - state["t0"], 2)
        state["stats_before_cancel"] = bpy.context.scene.bsplab.stats_json
        state["phase"] = "cancel"
        return 0.5
    if phase == "cancel":
        # A build option changed: this job must build, long enough for Esc.
        bpy.context.scene.bsplab.leaf_size = 2
        result = invoke()
        report["events"].append("second invoke -> {}".format(sorted(result)))
        state.update(phase="cancelling", t0=time.time(), escaped=False)
        return 0.5
    if phase == "cancelling":
        if job is not None:
            if not state["escaped"]:
                press_escape()
                state["escaped"] = True
                state["escape_time"] = time.time()
                report["events"].append("Esc pressed")
                report["escape_after_seconds"] = round(time.time() - state["t0"], 2)
            elif time.time() - state["t0"] > 60:
                report["events"].append("still running 60 s after Esc")
                finish()
                return None
            return 0.2
        report["cancel_seconds"] = round(time.time() - state["t0"], 2)
        report["stopped_after_escape_seconds"] = round(time.time() - state.get("escape_time", 0), 2)
        report["stats_unchanged_after_cancel"] = (
            bpy.context.scene.bsplab.stats_json == state["stats_before_cancel"])
        report["is_running_after"] = bpy.context.window_manager.bsplab_job.is_running
        state["phase"] = "cancelled"
        return 1.5
    if phase == "cancelled":
        screenshot("cancelled")
        # Sweep K through the modal path, on the light scene.
        scene = bpy.context.scene
        bpy.data.objects.remove(scene.objects["Heavy"])
        s = scene.bsplab
        s.sweep_methods, s.sweep_k_min, s.sweep_k_max, s.sweep_repetitions = (
            "bsp_wn+kd bsp_cn+kd", 3, 6, 2)
        result = invoke("sweep_k")
        report["events"].append("sweep invoke -> {}".format(sorted(result)))
        state.update(phase="sweeping", t0=time.time())
        return 0.2
    if phase == "sweeping":
        if job is not None:
            report["progress"].append(("sweep", round(time.time() - state["t0"], 2),
                                       round(job.fraction(), 3)))
            return 0.2
        table = bpy.context.scene.bsplab.k_sweep_table
        report["sweep_trees"] = sum(len(m["points"]) for m in table.get("methods", []))
        report["sweep_seconds"] = round(time.time() - state["t0"], 2)
        image = bpy.data.images.get("BSP Lab Sweep K")
        editors = areas('IMAGE_EDITOR')
        report["sweep_plot_shown"] = bool(editors) and editors[0][1].spaces.active.image == image
        state["phase"] = "swept"
        return 1.5
    if phase == "swept":
        screenshot("sweep")
        finish()
        return None
    return None


def main():
    utils.start_gui_check(tick)


main()

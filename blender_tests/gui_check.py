"""Drive the modal Build & Render in a real Blender window (Xvfb).

    xvfb-run -a -s "-screen 0 1600x900x24" blender --factory-startup -noaudio \\
        --python blender_tests/gui_check.py -- OUT_DIR

Needs a display (Xvfb is fine), xdotool (to press Esc) and ImageMagick's
`import` (screenshots); run_all.sh runs it (unless BSPLAB_GUI_CHECK=0).
Exits 0 when every check passed. Registers the add-on from the source
tree, presses Build & Render through INVOKE_DEFAULT (the modal path with the
worker thread and the timer), presses it again with only the shading mode
changed (the kept tree is re-used: a quick render), then starts a job that
must build (a build option changed) and cancels it with a real Esc key
press: that build waits at its second cancel check until a cancel comes
(the core's Progress.hold_at_check, armed before the job's thread starts),
so the Esc provably lands mid-build on any machine, and the check asserts
it did. Last, Sweep K through the modal path. Writes
OUT_DIR/gui_check.json and screenshots, then quits Blender.
"""

import json
import os
import pathlib
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
WAITS = gui_utils.Waits()
# The cancelled build waits at this cancel check (Progress.hold_at_check):
# the second, so that the build has begun its work when the Esc comes.
HOLD_AT_CHECK = 2


def screenshot(name):
    path = OUT / (name + ".png")
    gui_utils.grab_screen(path)
    report["events"].append("screenshot " + str(path))


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
    subprocess.run(["xdotool", "mousemove", str(x), str(y), "key", "Escape"], check=True)


def hold_next_build(addon):
    """Make the next job's build wait at its HOLD_AT_CHECK-th cancel check
    until it is cancelled: armed in the job's start(), before its thread
    runs, so no build can finish before the Esc however fast the machine."""
    worker = addon.jobs.worker
    start = worker.WorkerJob.start

    def held_start(job):
        worker.WorkerJob.start = start  # this job only
        job.build_progress.hold_at_check(HOLD_AT_CHECK)
        start(job)

    worker.WorkerJob.start = held_start


def finish():
    report["ok"] = bool(
        report.get("image_size") and report.get("image_editor_shows_preview")
        and report.get("escape_while_building") and report.get("cancelled_by_escape")
        and report.get("stats_unchanged_after_cancel") and not report.get("is_running_after")
        and report.get("reused_after_shading_change")
        and report.get("sweep_trees", 0) > 0 and report.get("sweep_plot_shown")
        and "error" not in report)
    (OUT / "gui_check.json").write_text(json.dumps(report, indent=1))
    sys.stdout.flush()
    os._exit(0 if report["ok"] else 1)


state = {"phase": "start", "t0": 0.0}
POLL = gui_utils.POLL_SECONDS


def step():
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
        window, area = areas('VIEW_3D')[0]
        area.spaces.active.show_region_ui = True
        # Another area shows images: the preview must appear there.
        others = [a for a in window.screen.areas if a.type not in ('VIEW_3D',)]
        others[0].type = 'IMAGE_EDITOR'
        # Open the sidebar's "BSP Lab" tab (the third one, after Tool and
        # View) for the screenshots; what the check asserts does not need it.
        ui = next(r for r in area.regions if r.type == 'UI')
        gui_utils.click(window, ui.x + ui.width - 8,
                        ui.y + ui.height - int(120 * bpy.context.preferences.view.ui_scale))
        state["phase"] = "run"
        return POLL
    if phase == "run":
        result = invoke()
        report["events"].append("invoke -> {}".format(sorted(result)))
        state.update(phase="running", t0=time.time())
        return POLL
    if phase == "running":
        if job is not None:
            report["progress"].append((round(time.time() - state["t0"], 2),
                                       round(job.fraction(), 3)))
        if not WAITS.until("the first Build & Render to end", lambda: addon.state.STATE.job is None):
            return POLL
        image = bpy.data.images.get("BSP Lab Preview")
        report["image_size"] = list(image.size) if image else None
        report["stats_triangles"] = bpy.context.scene.bsplab.stats.get("scene", {}).get("triangles")
        editors = areas('IMAGE_EDITOR')
        report["image_editor_shows_preview"] = bool(editors) and editors[0][1].spaces.active.image == image
        report["seconds"] = round(time.time() - state["t0"], 2)
        screenshot("done")
        # Only the shading changes: the modal path renders with the kept tree.
        bpy.context.scene.bsplab.render_mode = "normal"
        result = invoke()
        report["events"].append("invoke after a shading change -> {}".format(sorted(result)))
        state.update(phase="reusing", t0=time.time())
        return POLL
    if phase == "reusing":
        if not WAITS.until("the re-using press to end", lambda: addon.state.STATE.job is None):
            return POLL
        stats = bpy.context.scene.bsplab.stats
        report["reused_after_shading_change"] = (stats["build"].get("reused") is True
                                                 and stats["render"]["mode"] == "normal")
        report["reuse_seconds"] = round(time.time() - state["t0"], 2)
        state["stats_before_cancel"] = bpy.context.scene.bsplab.stats_json
        # A build option changed: this job must build; held mid-build for Esc.
        bpy.context.scene.bsplab.leaf_size = 2
        hold_next_build(addon)
        result = invoke()
        report["events"].append("invoke that builds -> {}".format(sorted(result)))
        state.update(phase="holding", t0=time.time(), job=addon.state.STATE.job)
        return POLL
    if phase == "holding":
        held = state["job"]
        if not WAITS.until("the build to wait at its cancel check {}".format(HOLD_AT_CHECK),
                           lambda: held.build_progress.held):
            return POLL
        # The build is running and cannot finish before a cancel comes.
        report["escape_while_building"] = held.is_alive() and held.build_progress.held
        report["build_progress_at_escape"] = round(held.build_progress.value, 4)
        report["job_progress_at_escape"] = round(held.fraction(), 4)
        screenshot("running")  # the panel's progress, mid-build
        press_escape()
        report["events"].append("Esc pressed")
        state.update(phase="cancelling", escape_time=time.time())
        return POLL
    if phase == "cancelling":
        if not WAITS.until("the job to stop after Esc", lambda: addon.state.STATE.job is None):
            return POLL
        held = state["job"]
        report["stopped_after_escape_seconds"] = round(time.time() - state["escape_time"], 2)
        # Esc reached the modal operator, which cancelled the job: the build
        # threw Cancelled at its held check, short of its end.
        report["cancelled_by_escape"] = (held.cancelled and isinstance(held.error, held.bsplab.Cancelled)
                                         and held.build_progress.value < 1.0)
        report["stats_unchanged_after_cancel"] = (
            bpy.context.scene.bsplab.stats_json == state["stats_before_cancel"])
        report["is_running_after"] = bpy.context.window_manager.bsplab_job.is_running
        screenshot("cancelled")
        # Sweep K through the modal path.
        s = bpy.context.scene.bsplab
        s.sweep_methods, s.sweep_k_min, s.sweep_k_max, s.sweep_repetitions = (
            "bsp_wn+kd bsp_cn+kd", 3, 6, 2)
        result = invoke("sweep_k")
        report["events"].append("sweep invoke -> {}".format(sorted(result)))
        state.update(phase="sweeping", t0=time.time())
        return POLL
    if phase == "sweeping":
        if job is not None:
            report["progress"].append(("sweep", round(time.time() - state["t0"], 2),
                                       round(job.fraction(), 3)))
        if not WAITS.until("Sweep K to end", lambda: addon.state.STATE.job is None):
            return POLL
        table = bpy.context.scene.bsplab.k_sweep_table
        report["sweep_trees"] = sum(len(m["points"]) for m in table.get("methods", []))
        report["sweep_seconds"] = round(time.time() - state["t0"], 2)
        image = bpy.data.images.get("BSP Lab Sweep K")
        editors = areas('IMAGE_EDITOR')
        report["sweep_plot_shown"] = bool(editors) and editors[0][1].spaces.active.image == image
        screenshot("sweep")
        finish()
        return None
    return None


def main():
    utils.start_gui_check(utils.reporting_failures(step, report, finish), report)


main()

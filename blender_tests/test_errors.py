"""Every error a user can hit: a clear report, and the scene left as it was."""

import json
import sys

import bpy
import numpy as np
import pytest

import bsplab_test_utils as utils


def with_previous_result(addon, scene):
    """A preview and statistics from an earlier run, which must survive."""
    rgba = np.full((6, 8, 4), 0.25, dtype=np.float32)
    addon.jobs.preview.write_preview(rgba)
    scene.bsplab.stats_json = json.dumps({"scene": {"triangles": 1}})


def assert_fails_cleanly(addon, scene, message):
    with_previous_result(addon, scene)
    before = utils.scene_snapshot(scene)
    # bpy.ops turns an ERROR report of a cancelled operator into RuntimeError.
    with pytest.raises(RuntimeError) as excinfo:
        bpy.ops.bsplab.build_render()
    assert message in str(excinfo.value)
    assert utils.scene_snapshot(scene) == before
    assert bpy.context.window_manager.bsplab_job.is_running is False
    return str(excinfo.value)


def assert_cancelled_quietly(addon, scene, message, capfd):
    """A cancel is what the user asked for: an INFO report (no RuntimeError,
    which bpy.ops raises for an ERROR report) and the scene left as it was."""
    with_previous_result(addon, scene)
    before = utils.scene_snapshot(scene)
    assert bpy.ops.bsplab.build_render() == {'CANCELLED'}
    assert utils.scene_snapshot(scene) == before
    assert bpy.context.window_manager.bsplab_job.is_running is False
    out, err = capfd.readouterr()
    assert message in out + err
    assert "Error" not in out + err


def test_no_camera(addon, core, test_scene):
    test_scene["scene"].camera = None
    assert_fails_cleanly(addon, test_scene["scene"], "The scene has no active camera")


def test_camera_not_perspective(addon, core, test_scene):
    test_scene["camera"].data.type = 'PANO'
    assert_fails_cleanly(addon, test_scene["scene"], "perspective cameras only")


def test_no_mesh(addon, core, empty_scene):
    utils.add_camera(empty_scene)
    assert_fails_cleanly(addon, empty_scene, "No visible mesh in the scene")


def test_only_hidden_meshes(addon, core, test_scene):
    for obj in test_scene["scene"].objects:
        if obj.type == 'MESH' or obj.instance_type == 'COLLECTION':
            obj.hide_set(True)
    assert_fails_cleanly(addon, test_scene["scene"], "No visible mesh in the scene")


def test_empty_mesh(addon, core, empty_scene):
    utils.add_camera(empty_scene)
    utils.link(empty_scene, "Empty Mesh", bpy.data.meshes.new("Empty"))
    utils.link(empty_scene, "Loose Points", utils.make_mesh("Pts", [(0, 0, 0), (1, 1, 1)], []))
    assert_fails_cleanly(addon, empty_scene, "have no faces")


def test_nan_mesh(addon, core, test_scene):
    utils.put_nan_vertex(test_scene["ground"].data)
    message = assert_fails_cleanly(addon, test_scene["scene"], "BSP Lab cannot build the tree")
    assert "nan" in message.lower()


def test_nothing_in_view(addon, core, test_scene):
    utils.look_at(test_scene["camera"], (0.0, -100.0, 3.0))  # facing away
    bpy.context.view_layer.update()
    assert_fails_cleanly(addon, test_scene["scene"], "No mesh in the camera's view")


def test_cancelled(addon, core, test_scene, monkeypatch, capfd):
    """Esc half-way: the core raises Cancelled out of the worker."""
    original_run = addon.build_render.job.Job.run

    def cancelled_run(job):
        job.cancel()  # as the modal operator does on Esc
        original_run(job)

    monkeypatch.setattr(addon.build_render.job.Job, "run", cancelled_run)
    assert_cancelled_quietly(addon, test_scene["scene"], "Build & Render cancelled", capfd)


def test_cancelled_during_build(addon, core, test_scene, monkeypatch, capfd):
    """The core's own cancellation: its progress object cancelled mid-build."""
    real_build = core.build

    def build_then_cancel(*args, progress=None, **kwargs):
        progress.cancel()
        return real_build(*args, progress=progress, **kwargs)

    monkeypatch.setattr(core, "build", build_then_cancel)
    assert_cancelled_quietly(addon, test_scene["scene"], "Build & Render cancelled", capfd)


def test_core_missing(addon, test_scene, monkeypatch):
    monkeypatch.setitem(sys.modules, "bsplab", None)
    assert_fails_cleanly(addon, test_scene["scene"], "core module 'bsplab' is not available")


def test_core_failure_is_reported(addon, core, test_scene, monkeypatch):
    def broken_render(*args, **kwargs):
        raise MemoryError("over the 1 MB budget")

    monkeypatch.setattr(core, "render", broken_render)
    assert_fails_cleanly(addon, test_scene["scene"], "memory budget")


def test_k_out_of_range(addon, core, test_scene):
    methods = core.methods()
    name = next((m for m, info in methods.items() if info.get("min_k", 0) and info["min_k"] > 1), None)
    if name is None:
        pytest.skip("the core has no method with a lower bound on K above 1")
    settings = test_scene["scene"].bsplab
    settings.method = name
    settings.k = methods[name]["min_k"] - 1
    assert_fails_cleanly(addon, test_scene["scene"], "K must be in")


def test_option_rejected_by_the_core(addon, core, test_scene):
    if "rbsp" not in core.methods():
        pytest.skip("the core has no RBSP method")
    settings = test_scene["scene"].bsplab
    settings.method = "rbsp"
    settings.rbsp_set = 'dop'
    settings.k = 6  # k-DOPs exist for K = 3, 7, 9, 13 only
    assert_fails_cleanly(addon, test_scene["scene"], "BSP Lab cannot build the tree")


def test_unexpected_failure_reading_the_scene(addon, core, test_scene, monkeypatch):
    def broken(_depsgraph):
        raise RuntimeError("mesh data went away")

    monkeypatch.setattr(addon.jobs.scene_reader, "scene_triangles", broken)
    assert_fails_cleanly(addon, test_scene["scene"], "could not read the scene: RuntimeError")

"""The add-on's Build & Render job (addon/jobs.py) without Blender.

addon/jobs.py touches no bpy: it is imported here as a submodule of a package
whose path is the addon folder, without running the add-on's __init__ (which
registers with Blender), and run with the real core and the real Embree on a
generated scene.
"""

import dataclasses
import importlib
import json
import re
import sys
import threading
import types
from pathlib import Path

import numpy as np
import pytest

import bsplab
from bsplab import scenes
from bsplab.blender.camera import CameraSpec

ADDON_DIR = Path(__file__).resolve().parents[2] / "addon"
PACKAGE = "bsplab_addon_without_blender"


def _addon_module(name):
    """addon/<name>.py imported as PACKAGE.<name>; the package's __init__ is not run."""
    if PACKAGE not in sys.modules:
        package = types.ModuleType(PACKAGE)
        package.__path__ = [str(ADDON_DIR)]
        sys.modules[PACKAGE] = package
    return importlib.import_module(f"{PACKAGE}.{name}")


jobs = _addon_module("jobs")


def _spec(camera: bsplab.Camera, width: int, height: int):
    """The CameraSpec the add-on reads from a scene camera, of a core camera."""
    fields = {f.name: getattr(camera, f.name) for f in dataclasses.fields(bsplab.Camera)}
    return CameraSpec(width=width, height=height, name="TestCam", **fields)


def _input(triangles, camera, *, width=48, height=32, **changes):
    values = dict(triangles=triangles, objects=1, instances=1,
                  camera=_spec(camera, width, height), method="kd", options={},
                  mode="shaded", threads=2, cull=False, compare_with_embree=True,
                  count_steps=True, scene_name="Scene")
    values.update(changes)
    return jobs.JobInput(**values)


def _run(inp):
    job = jobs.Job(bsplab, inp)
    job.start()
    job.join(60.0)
    assert not job.is_alive(), "the job did not end within 60 s"
    return job


def test_job_builds_renders_and_agrees_with_embree():
    pytest.importorskip("embreex")
    tris = scenes.generate("spheres")
    job = _run(_input(tris, scenes.default_camera("spheres")))
    assert job.error is None, job.error
    image, stats = job.result["image"], job.result["stats"]
    assert image.shape == (32, 48, 4) and image.dtype == np.float32
    assert np.all(np.isfinite(image)) and image[..., :3].max() > 0.0
    assert set(stats) == {"scene", "build", "render", "embree"}
    assert stats["scene"] == {"triangles": len(tris), "objects": 1, "instances": 1}
    assert stats["build"]["nodes"] >= 1
    render = stats["render"]
    assert (render["width"], render["height"], render["mode"], render["camera"]) == \
        (48, 32, "shaded", "TestCam")
    assert 0 < render["hits"] <= 48 * 32
    embree = stats["embree"]
    assert embree["available"] is True, embree
    compare = embree["compare"]
    assert compare["rays"] == 48 * 32
    # The tree finds Embree's closest hit on every camera ray, but for those
    # the oracle explains (grazing an edge, at the ends, degenerate triangles).
    explained = compare["grazing"] + compare["at_ends"] + compare["degenerate"]
    assert compare["agree"] + explained == compare["rays"], compare
    assert compare["agree"] >= 0.99 * compare["rays"], compare
    assert embree["bsplab_seconds"] > 0 and embree["embree_seconds"] > 0
    jobs.check_result(job.result)  # hits > 0: no UserError
    assert job.fraction() == pytest.approx(1.0)


@pytest.mark.parametrize("mode", ["shaded", "depth", "heat_steps"])
def test_count_steps_off_renders_in_packets_the_same_image(mode):
    # Off, the hits-only modes take render()'s packets: the same pixels, no
    # counts for the panel; the heat maps count regardless (they are counts).
    tris = scenes.generate("spheres")
    cam = scenes.default_camera("spheres")
    counted = _run(_input(tris, cam, mode=mode, compare_with_embree=False))
    fast = _run(_input(tris, cam, mode=mode, compare_with_embree=False, count_steps=False))
    assert counted.error is None and fast.error is None, (counted.error, fast.error)
    assert np.array_equal(counted.result["image"], fast.result["image"])
    on, off = counted.result["stats"]["render"], fast.result["stats"]["render"]
    assert on["counters"] is True and on["packets"] is False and on["mean_steps"] > 1
    heat = mode.startswith("heat")
    assert off["counters"] is heat and off["packets"] is not heat
    assert (off["mean_steps"] is None) is not heat
    assert on["kernel"] == off["kernel"] == bsplab.cpu_features()["selected"]


def test_every_ray_missing_is_a_user_error():
    tris = scenes.generate("spheres")
    # High above the scene, turned over (a camera looks along its -z): up at the sky.
    up = np.diag([1.0, -1.0, -1.0, 1.0])
    up[2, 3] = 500.0
    away = bsplab.Camera(matrix_world=up)
    job = _run(_input(tris, away, compare_with_embree=False))
    assert job.error is None, job.error
    assert job.result["stats"]["render"]["hits"] == 0
    assert "embree" not in job.result["stats"]
    with pytest.raises(jobs.UserError, match="every camera ray missed"):
        jobs.check_result(job.result)


def test_cancel_mid_way_ends_the_job_cancelled():
    tris = scenes.generate("spheres")
    job = jobs.Job(bsplab, _input(tris, scenes.default_camera("spheres"), width=1600,
                                  height=1200, mode="heat_tests", threads=1,
                                  compare_with_embree=False))
    # Cancel once the tree is built, while the (large) render runs.
    built = threading.Event()

    def cancel_after_build():
        while job.is_alive() and job.build_progress.value < 1.0:
            threading.Event().wait(0.001)
        built.set()
        job.cancel()

    job.start()
    canceller = threading.Thread(target=cancel_after_build)
    canceller.start()
    job.join(60.0)
    canceller.join(60.0)
    assert built.is_set() and not job.is_alive(), "the job did not stop after cancel()"
    assert job.result is None and job.render_progress.value < 1.0  # the render was cut short
    assert isinstance(job.error, bsplab.Cancelled), job.error
    assert "cancelled" in jobs.error_message(bsplab, job.error)


def test_cancel_before_start_stops_at_once():
    job = jobs.Job(bsplab, _input(scenes.generate("fan"), scenes.default_camera("fan")))
    job.cancel()
    job.run()  # on this thread: no thread to leak
    assert isinstance(job.error, bsplab.Cancelled) and job.result is None


@pytest.mark.parametrize("change, message", [
    ({"triangles": np.full((4, 3, 3), np.nan, np.float32)}, "cannot build the tree: .*NaN"),
    ({"method": "no_such_method"}, "cannot build the tree: .*no_such_method"),
    ({"options": {"max_depth": -3}}, "cannot build the tree: .*max_depth"),
    ({"mode": "sepia"}, "cannot build the tree: .*sepia"),
])
def test_bad_input_becomes_the_jobs_error_message(change, message):
    values = {"triangles": scenes.generate("fan"), **change}
    job = _run(_input(camera=scenes.default_camera("fan"), compare_with_embree=False, **values))
    assert job.result is None and job.error is not None
    assert isinstance(job.error, (ValueError, TypeError))
    assert re.search(message, jobs.error_message(bsplab, job.error)), \
        jobs.error_message(bsplab, job.error)


def test_error_messages_for_each_kind_of_failure():
    assert jobs.error_message(bsplab, jobs.UserError("look here")) == "look here"
    assert "memory budget: over 1 MB" in jobs.error_message(bsplab, MemoryError("over 1 MB"))
    assert jobs.error_message(None, RuntimeError("boom")) == "BSP Lab failed: RuntimeError: boom"


def test_plain_makes_results_json_friendly():
    value = {1: np.float32(0.5), "a": np.arange(3), "big": np.zeros(100), "t": (np.int64(2),)}
    out = jobs.plain(value)
    assert out == {"1": 0.5, "a": [0, 1, 2], "big": "array(100,)", "t": [2]}
    json.dumps(out)


def test_the_addon_reads_the_scene_with_the_core_packages_modules():
    """addon/camera.py and addon/extract.py hold no copy of the scene reading:
    their names are bsplab.blender's (bpy-free to import)."""
    from bsplab.blender import camera, extract
    addon_camera, addon_extract = _addon_module("camera"), _addon_module("extract")
    assert addon_camera.CameraSpec is camera.CameraSpec
    assert addon_camera.scene_camera is camera.scene_camera
    assert addon_extract.scene_triangles is extract.scene_triangles
    render = types.SimpleNamespace(resolution_x=1920, resolution_y=1080,
                                   resolution_percentage=50)
    for percent in (1, 25, 100):
        assert addon_camera.preview_size(render, percent) == camera.preview_size(render, percent)

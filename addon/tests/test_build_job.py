"""The add-on's Build & Render job (addon/build_render/job.py) without Blender.

The job touches no bpy: it is imported here as a submodule of a package
whose path is the addon folder, without running the add-on's __init__ files
(which register with Blender), and run with the real bsplab and the real
Embree on a generated scene.
"""

import dataclasses
import json
import re
import threading
import types

import numpy as np
import pytest

import bsplab
from bsplab import scenes
from bsplab.blender.scene_camera import CameraSpec

from addon_without_blender import addon_module as _addon_module


jobs = _addon_module("build_render.job")
worker = _addon_module("jobs.worker")
messages = _addon_module("jobs.messages")
statistics = _addon_module("build_render.statistics")


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
    # the oracle explains (Embree exactly wrong, grazing an edge, at the
    # ends, degenerate triangles): none ours exactly wrong or undecided.
    explained = compare["embree_wrong"] + compare["grazing"] + compare["at_ends"] + \
        compare["degenerate"]
    assert compare["agree"] + explained == compare["rays"], compare
    assert compare["bsplab_wrong"] == compare["undecided"] == 0, compare
    # The panel counts Embree's own errors apart from ours.
    rows = dict(statistics.embree_rows(embree))
    assert rows["Embree Wrong"] == "{:,}".format(compare["embree_wrong"])
    assert rows["BSP Lab Wrong"] == rows["Undecided"] == "0"
    assert rows["At Edges"] == "{:,}".format(compare["grazing"])
    assert compare["agree"] >= 0.99 * compare["rays"], compare
    assert embree["bsplab_seconds"] > 0 and embree["embree_seconds"] > 0
    messages.check_result(job.result)  # hits > 0: no UserError
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
    with pytest.raises(worker.UserError, match="every camera ray missed"):
        messages.check_result(job.result)


def _cancel_once_rendering(job):
    """Starts `job` and, from another thread, cancels it while its render
    runs: the render's third chunk of rays waits for the cancel (the core's
    Progress.hold_at_check), so the job cannot have finished first, however
    fast or loaded the machine. Returns (build, render) progress seen at
    the cancel, or None when the job ended without reaching that chunk."""
    job.render_progress.hold_at_check(3)
    seen = []

    def cancel():
        while job.is_alive() and not job.render_progress.held:
            threading.Event().wait(0.001)
        if job.render_progress.held:
            seen.append((job.build_progress.value, job.render_progress.value))
        job.cancel()

    job.start()
    canceller = threading.Thread(target=cancel)
    canceller.start()
    job.join(60.0)
    canceller.join(60.0)
    assert not job.is_alive() and not canceller.is_alive(), "the job did not stop after cancel()"
    return seen[0] if seen else None


def test_cancel_mid_way_ends_the_job_cancelled():
    tris = scenes.generate("spheres")
    job = jobs.Job(bsplab, _input(tris, scenes.default_camera("spheres"), width=160,
                                  height=120, mode="heat_tests", threads=1,
                                  compare_with_embree=False))
    # Cancelled once the tree is built, while the render runs.
    seen = _cancel_once_rendering(job)
    assert seen is not None, job.error
    built, rendered = seen
    assert built == 1.0 and 0.0 < rendered < 1.0
    assert job.result is None and job.render_progress.value < 1.0  # the render was cut short
    assert isinstance(job.error, bsplab.Cancelled), job.error
    assert "cancelled" in worker.error_message(bsplab, job.error)


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
    assert re.search(message, worker.error_message(bsplab, job.error)), \
        worker.error_message(bsplab, job.error)


def test_error_messages_for_each_kind_of_failure():
    assert worker.error_message(bsplab, worker.UserError("look here")) == "look here"
    assert "memory budget: over 1 MB" in worker.error_message(bsplab, MemoryError("over 1 MB"))
    assert worker.error_message(None, RuntimeError("boom")) == "BSP Lab failed: RuntimeError: boom"


def test_plain_makes_results_json_friendly():
    value = {1: np.float32(0.5), "a": np.arange(3), "big": np.zeros(100), "t": (np.int64(2),)}
    out = worker.plain(value)
    assert out == {"1": 0.5, "a": [0, 1, 2], "big": "array(100,)", "t": [2]}
    json.dumps(out)


def test_the_addon_reads_the_scene_with_the_bsplab_packages_modules():
    """addon/jobs/scene_reader.py holds no copy of the scene reading:
    its readers are bsplab.blender's (bpy-free to import)."""
    from bsplab.blender import extract, scene_camera as camera
    reader = _addon_module("jobs.scene_reader")
    assert reader.CameraSpec is camera.CameraSpec
    assert reader.scene_camera is camera.scene_camera
    assert reader.CameraError is camera.CameraError
    assert reader.scene_triangles is extract.scene_triangles
    assert reader.SceneGeometry is extract.SceneGeometry
    render = types.SimpleNamespace(resolution_x=1920, resolution_y=1080,
                                   resolution_percentage=50)
    for percent in (1, 25, 100):
        assert reader.preview_size(render, percent) == camera.preview_size(render, percent)


# -----------------------------------------------------------------------------
# Re-using the tree of the previous press (addon/jobs/tree_cache.py)

tree_cache = _addon_module("jobs.tree_cache")

# What the add-on passes: every option of the method, threads included.
KD_OPTIONS = {"threads": 2, "leaf_size": 1, "max_depth": 0, "leaf_boxes": "triangle"}


def _run_cached(cache, inp):
    job = jobs.Job(bsplab, inp, cache=cache)
    job.start()
    job.join(60.0)
    assert not job.is_alive(), "the job did not end within 60 s"
    assert job.error is None, job.error
    return job


@pytest.fixture
def scene():
    return scenes.generate("fan"), scenes.default_camera("fan")


def test_same_triangles_and_options_reuse_the_tree(scene):
    tris, cam = scene
    cache = tree_cache.TreeCache()
    first = _run_cached(cache, _input(tris, cam, options=KD_OPTIONS, compare_with_embree=False))
    # A fresh copy of the same triangles, as the next press extracts them.
    second = _run_cached(cache, _input(tris.copy(), cam, options=dict(KD_OPTIONS),
                                       compare_with_embree=False))
    assert (first.reused, second.reused) == (False, True)
    one, two = first.result["stats"]["build"], second.result["stats"]["build"]
    assert (one["reused"], two["reused"]) == (False, True)
    # The re-used tree's own statistics: its build time is the first press's.
    assert {k: v for k, v in two.items() if k not in ("reused", "fingerprint_seconds")} == \
        {k: v for k, v in one.items() if k not in ("reused", "fingerprint_seconds")}
    assert two["fingerprint_seconds"] > 0
    assert second.build_progress.value == 0.0  # no build ran
    assert second.fraction() == pytest.approx(1.0)
    assert np.array_equal(first.result["image"], second.result["image"])
    assert len(cache) == 1


def _moved(cam):
    """The camera half a unit to its right."""
    matrix = np.array(cam.matrix_world, dtype=np.float64)
    matrix[:3, 3] += 0.5 * matrix[:3, 0]
    return dataclasses.replace(cam, matrix_world=matrix)


# (what changes between two presses, whether the picture changes with it)
RENDER_ONLY_CHANGES = [
    ({"mode": "depth"}, True),
    ({"width": 24, "height": 16}, True),
    ({"camera": _moved}, True),
    ({"threads": 1}, False),
    ({"cull": True}, False),
    ({"count_steps": False}, False),
    ({"options": dict(KD_OPTIONS, threads=1)}, False),
    ({"options": dict(KD_OPTIONS, memory_limit_mb=2048.0)}, False),
]


@pytest.mark.parametrize("change, new_picture", RENDER_ONLY_CHANGES,
                         ids=[next(iter(c)) for c, _ in RENDER_ONLY_CHANGES])
def test_what_does_not_change_the_tree_reuses_it_and_renders_anew(scene, change,
                                                                   new_picture):
    tris, cam = scene
    cache = tree_cache.TreeCache()
    base = dict(options=KD_OPTIONS, compare_with_embree=False)
    first = _run_cached(cache, _input(tris, cam, **base))
    change = dict(change)
    second_cam = change.pop("camera")(cam) if "camera" in change else cam
    second = _run_cached(cache, _input(tris, second_cam, **{**base, **change}))
    assert second.reused and second.result["stats"]["build"]["reused"] is True
    # Rendered anew with the new settings: the very image a fresh build gives.
    fresh = _run(second.input)
    assert fresh.error is None, fresh.error
    assert np.array_equal(second.result["image"], fresh.result["image"])
    before, after = first.result["image"], second.result["image"]
    same = before.shape == after.shape and np.array_equal(before, after)
    assert same is not new_picture


def _one_vertex_moved(tris):
    moved = tris.copy()
    moved[7, 1, 2] += np.float32(0.25)
    return moved


# (what changes between two presses): each builds a new tree.
TREE_CHANGES = [
    {"triangles": _one_vertex_moved},
    {"triangles": lambda tris: tris[:-1].copy()},  # a triangle fewer
    {"method": "bsp_wn+kd", "options": {"threads": 2, "k": 4, "seed": 1}},
    {"options": dict(KD_OPTIONS, leaf_size=4)},
    {"options": dict(KD_OPTIONS, leaf_boxes="clipped")},
]


@pytest.mark.parametrize("change", TREE_CHANGES,
                         ids=["vertex", "triangle_count", "method", "leaf_size", "leaf_boxes"])
def test_what_changes_the_tree_rebuilds_it(scene, change):
    tris, cam = scene
    cache = tree_cache.TreeCache()
    base = dict(options=KD_OPTIONS, compare_with_embree=False)
    _run_cached(cache, _input(tris, cam, **base))
    change = dict(change)
    second_tris = change.pop("triangles")(tris) if "triangles" in change else tris
    second = _run_cached(cache, _input(second_tris, cam, **{**base, **change}))
    assert not second.reused and second.result["stats"]["build"]["reused"] is False
    assert second.build_progress.value == 1.0
    # The new tree is the one kept now: a third press re-uses it.
    third = _run_cached(cache, second.input)
    assert third.reused
    assert third.result["stats"]["build"]["nodes"] == second.result["stats"]["build"]["nodes"]


def test_every_option_but_threads_and_memory_limit_is_in_the_key(scene):
    """A new build option of the core's registry changes the key unless it is
    named in not_tree_options(): no option is forgotten by a list of our own."""
    tris, _ = scene
    schema = bsplab.option_schema()
    defaults = {name: spec["default"] for name, spec in schema.items()}
    base = tree_cache.tree_key(tris, "kd", defaults)
    for name, spec in schema.items():
        if spec["type"] == "enum":
            other = next(c["name"] for c in spec["choices"] if c["name"] != spec["default"])
        else:
            other = spec["default"] + 1
        changed = tree_cache.tree_key(tris, "kd", dict(defaults, **{name: other}))
        assert (changed == base) is (name in tree_cache.not_tree_options()), name
    assert tree_cache.not_tree_options() <= set(schema)


@pytest.mark.parametrize("method", ["kd", "bsp_cn+kd"])
def test_threads_and_memory_limit_do_not_change_the_tree(method):
    """Why not_tree_options() may leave them out of the key."""
    tris = scenes.generate("room")
    one = bsplab.build(tris, method, threads=1)
    for options in ({"threads": 2}, {"threads": 0}, {"memory_limit_mb": 512.0}):
        assert bsplab.build(tris, method, **options).node_bytes() == one.node_bytes(), options


def test_geometry_digest_sees_every_byte_shape_and_type():
    tris = scenes.generate("fan")
    digest = tree_cache.geometry_digest(tris)
    assert digest == tree_cache.geometry_digest(tris.copy())
    assert len(digest) == tree_cache.DIGEST_BYTES
    flipped = tris.copy()
    flipped.view(np.uint32)[-1, -1, -1] ^= 1  # the lowest bit of the last float
    assert tree_cache.geometry_digest(flipped) != digest
    assert tree_cache.geometry_digest(tris.reshape(-1, 9)) != digest
    assert tree_cache.geometry_digest(tris.astype(np.float64)) != digest
    # Not C-contiguous (a strided view) is read the same as its copy.
    assert tree_cache.geometry_digest(tris[::2]) == tree_cache.geometry_digest(tris[::2].copy())


def test_a_miss_forgets_the_kept_tree_before_building(scene):
    """One tree at a time: asking for another key drops the kept one."""
    tris, cam = scene
    cache = tree_cache.TreeCache()
    first = _run_cached(cache, _input(tris, cam, options=KD_OPTIONS, compare_with_embree=False))
    key = first.a.key
    assert cache.tree(key) is not None and len(cache) == 1
    other = tree_cache.tree_key(tris, "kd", dict(KD_OPTIONS, leaf_size=2))
    assert cache.tree(other) is None
    assert len(cache) == 0 and cache.tree(key) is None


def test_cancel_during_a_reused_render_keeps_the_tree(scene):
    tris, cam = scene
    cache = tree_cache.TreeCache()
    small = _run_cached(cache, _input(tris, cam, options=KD_OPTIONS, compare_with_embree=False))
    big = jobs.Job(bsplab, _input(tris, cam, width=160, height=120, mode="heat_tests",
                                  threads=1, options=KD_OPTIONS, compare_with_embree=False),
                   cache=cache)
    seen = _cancel_once_rendering(big)
    assert seen is not None, big.error
    assert big.reused and seen[0] == 0.0  # no build ran
    assert isinstance(big.error, bsplab.Cancelled), big.error
    assert big.result is None and big.render_progress.value < 1.0
    # Still kept, and the next press re-uses it.
    assert cache.tree(small.a.key) is not None
    again = _run_cached(cache, small.input)
    assert again.reused and np.array_equal(again.result["image"], small.result["image"])


def test_cancel_during_the_build_keeps_nothing(scene):
    tris, cam = scene
    cache = tree_cache.TreeCache()
    job = jobs.Job(bsplab, _input(tris, cam, options=KD_OPTIONS), cache=cache)
    job.cancel()
    job.run()
    assert isinstance(job.error, bsplab.Cancelled)
    assert len(cache) == 0


def test_clear_forgets_and_refuses_what_running_jobs_would_keep(scene):
    tris, cam = scene
    cache = tree_cache.TreeCache()
    inp = _input(tris, cam, options=KD_OPTIONS)
    _run_cached(cache, inp)
    assert len(cache) == 2  # the tree and the Embree scene (compare_with_embree)
    cache.clear()  # a file loaded
    assert len(cache) == 0
    # A job made before a clear (a file loaded while it ran) keeps nothing.
    job = jobs.Job(bsplab, inp, cache=cache)
    cache.clear()
    job.run()
    assert job.error is None, job.error
    assert not job.reused and len(cache) == 0
    # A job made after it builds and keeps its tree again.
    assert not _run_cached(cache, inp).reused and len(cache) == 2


def test_embree_scene_is_reused_with_the_triangles(scene):
    pytest.importorskip("embreex")
    tris, cam = scene
    cache = tree_cache.TreeCache()
    runs = [_run_cached(cache, _input(t, cam, method=method, options=options))
            for t, method, options in [
                (tris, "kd", KD_OPTIONS),
                (tris, "kd", dict(KD_OPTIONS, leaf_size=3)),  # a new tree, the same triangles
                (_one_vertex_moved(tris), "kd", KD_OPTIONS)]]
    embree = [run.result["stats"]["embree"] for run in runs]
    assert [e["embree_reused"] for e in embree] == [False, True, False]
    assert [run.reused for run in runs] == [False, False, False]
    assert embree[1]["embree_build_seconds"] == embree[0]["embree_build_seconds"]
    for e in embree:  # the re-used scene still gives Embree's hits
        c = e["compare"]
        assert c["agree"] + c["embree_wrong"] + c["grazing"] + c["at_ends"] + \
            c["degenerate"] == c["rays"], c

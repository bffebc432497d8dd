"""Sweep K: the experiment runner on the current scene, from the panel."""

import json
import re
import os
import sys

import bpy
import numpy as np
import pytest

import bsplab_test_utils as utils
from conftest import in_bpy_module


def set_sweep(scene, methods="bsp_wn+kd bsp_ize+kd", k_min=3, k_max=5, repetitions=2,
              workload="primary"):
    s = scene.bsplab
    s.sweep_methods, s.sweep_k_min, s.sweep_k_max = methods, k_min, k_max
    s.sweep_repetitions, s.sweep_workload = repetitions, workload


def colour_pixels(image, rgb, tol=0.02):
    px = utils.image_pixels_top_down(image)[..., :3]
    return int(np.all(np.abs(px - np.array(rgb)) < tol, axis=-1).sum())


def test_sweep_fills_the_table_and_the_plot(addon, core, test_scene):
    scene = test_scene["scene"]
    set_sweep(scene)
    assert bpy.ops.bsplab.sweep_k() == {'FINISHED'}
    table = scene.bsplab.k_sweep_table
    names = [m["name"] for m in table["methods"]]
    assert names == ["kd", "bsp_wn+kd", "bsp_ize+kd"]  # kd added as the reference
    points = {m["name"]: m["points"] for m in table["methods"]}
    assert [p["k"] for p in points["bsp_wn+kd"]] == [3, 4, 5]
    assert [p["k"] for p in points["kd"]] == [None] == [p["k"] for p in points["bsp_ize+kd"]]
    assert points["kd"][0]["pct_kd"] == pytest.approx(100.0)
    for m in table["methods"]:
        for p in m["points"]:
            assert p["tests"] > 0 and p["steps"] > 0 and p["pct_kd"] > 0
            assert p["wrong"] == 0  # 0 also when Embree cannot run here (nothing compared)
    assert table["scene"]["triangles"] == utils.EXPECTED_TRIANGLES
    assert table["scene"]["rays"] == 80 * 60  # the preview size

    image = bpy.data.images[addon.k_sweep.experiment.PLOT_NAME]
    assert tuple(image.size) == addon.k_sweep.experiment.PLOT_SIZE
    colours = dict(addon.k_sweep.plot.COLOURS)
    assert colour_pixels(image, colours["orange"]) > 50  # bsp_wn+kd's line
    assert colour_pixels(image, colours["green"]) > 10   # bsp_ize+kd's dotted level

    rows = addon.k_sweep.panel.table_rows(table)
    assert rows[0][0].startswith("method") and len(rows) == 1 + 5
    assert rows[2][0] == "bsp_wn+kd K=3 (orange)"


def test_sweep_panel_draws_the_table(addon, core, test_scene):
    from test_ui import draw
    scene = test_scene["scene"]
    log = draw(addon.k_sweep.panel.BSPLAB_PT_sweep)
    assert ("operator", "bsplab.sweep_k") in log
    assert not any(kind == "label" and "% of kd" in text for kind, text in log)
    set_sweep(scene, methods="bsp_cn+kd", k_min=4, k_max=4, repetitions=1)
    assert bpy.ops.bsplab.sweep_k() == {'FINISHED'}
    labels = [text for kind, text in draw(addon.k_sweep.panel.BSPLAB_PT_sweep) if kind == "label"]
    assert "bsp_cn+kd K=4 (orange)" in labels and "kd (blue)" in labels
    assert any(text.startswith("Time as % of kd") for text in labels)


@pytest.mark.parametrize("settings, message", [
    ({"methods": "bsp_wn+kd bsp_sparkle"}, "Unknown method(s) bsp_sparkle"),
    ({"methods": "  "}, "at least one method"),
    ({"k_min": 6, "k_max": 4}, "K range is empty"),
    ({"methods": "bsp_wn+kd", "k_min": 1, "k_max": 2}, "bsp_wn+kd takes K from 3"),
    ({"methods": "rbsp bsp_random bsp_wn bsp_cn", "k_min": 1, "k_max": 64},
     "would build"),
])
def test_bad_sweeps_are_reported(addon, test_scene, settings, message):
    scene = test_scene["scene"]
    scene.bsplab.sweep_json = '{"methods": [], "keep": 1}'
    set_sweep(scene, **settings)
    with pytest.raises(RuntimeError, match=re.escape(message)):
        bpy.ops.bsplab.sweep_k()
    assert json.loads(scene.bsplab.sweep_json)["keep"] == 1  # untouched


def test_sweep_without_camera_or_meshes(addon, empty_scene):
    set_sweep(empty_scene)
    with pytest.raises(RuntimeError, match="no active camera"):
        bpy.ops.bsplab.sweep_k()
    utils.add_camera(empty_scene)
    with pytest.raises(RuntimeError, match="No visible mesh"):
        bpy.ops.bsplab.sweep_k()


def test_sweep_rejects_nan_vertices(addon, test_scene):
    scene = test_scene["scene"]
    utils.put_nan_vertex(test_scene["ground"].data)
    set_sweep(scene)
    with pytest.raises(RuntimeError, match="(?i)cannot build the tree.*nan"):
        bpy.ops.bsplab.sweep_k()


def test_cancel_stops_the_sweep(addon, core, test_scene):
    scene = test_scene["scene"]
    set_sweep(scene, methods="bsp_wn+kd", k_min=3, k_max=12)
    inp = addon.k_sweep.operator.read_sweep(bpy.context, core)
    job = addon.k_sweep.experiment.KSweepJob(core, inp)
    job.cancel()  # before it starts: the first build stops at once
    job.start()
    job.join(60)
    assert not job.is_alive()
    assert isinstance(job.error, core.Cancelled)
    assert "cancelled" in addon.jobs.worker.error_message(core, job.error)


def test_experiment_reads_a_blend_file(addon, core, test_scene, tmp_path, monkeypatch):
    """The headless runner takes a .blend: Blender (this Blender binary, or a
    Python with this bpy module) exports its evaluated triangles and camera
    in another process with the add-on's own extraction."""
    from bsplab import io, lab
    path = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    blender = sys.executable if in_bpy_module() else bpy.app.binary_path
    # The exporting process needs the bpy package itself, not this process's paths.
    monkeypatch.setenv("PYTHONPATH", os.path.dirname(os.path.dirname(core.__file__)))
    monkeypatch.setenv("BSPLAB_BLENDER", blender)
    tris, cam = io.load_blend(path)
    assert len(tris) == utils.EXPECTED_TRIANGLES
    assert cam is not None and cam.lens == pytest.approx(test_scene["camera"].data.lens)
    spec = lab.make_spec({"scenes": [str(path)], "methods": ["kd"], "repetitions": 1,
                                 "width": 16, "height": 12, "workloads": ["primary"],
                                 "executor": "inline"})
    rows = lab.run(spec, tmp_path / "res", quiet=True)
    assert len(rows) == 1 and int(rows[0]["hits"]) > 0
    assert int(rows[0]["triangles"]) == utils.EXPECTED_TRIANGLES
    with pytest.raises(RuntimeError, match="could not export"):
        (tmp_path / "broken.blend").write_bytes(b"not a blend file")
        io.load_blend(tmp_path / "broken.blend")


def test_sweep_plot_has_a_legend_in_each_methods_colour(addon, core, test_scene):
    scene = test_scene["scene"]
    set_sweep(scene, k_max=4, repetitions=1)
    assert bpy.ops.bsplab.sweep_k() == {'FINISHED'}
    table = scene.bsplab.k_sweep_table
    pixels = utils.image_pixels_top_down(bpy.data.images[addon.k_sweep.experiment.PLOT_NAME])[..., :3]
    width = addon.k_sweep.experiment.PLOT_SIZE[0]
    names = [m["name"] for m in table["methods"]]
    legend_w, legend_h = addon.drawing.legend.legend_size(names)
    x0, y0 = width - addon.k_sweep.plot.MARGIN_RIGHT - legend_w, addon.k_sweep.plot.MARGIN_TOP
    box = pixels[y0:y0 + legend_h, x0:x0 + legend_w]
    colours = dict(addon.k_sweep.plot.COLOURS)
    for m in table["methods"]:
        rgb = np.array(colours[m["colour"]])
        ink = np.all(np.abs(box - rgb) < 0.02, axis=-1)
        # the sample line and the name (at least one glyph column per letter)
        assert ink.sum() > 10 + 3 * len(m["name"]), m["name"]
    # The title and the axis labels are dark ink outside the plot area.
    dark = np.all(pixels < 0.15, axis=-1)
    assert dark[:addon.k_sweep.plot.MARGIN_TOP].sum() > 100
    assert dark[-addon.k_sweep.plot.MARGIN_BOTTOM + 2:].sum() > 20


def test_cancelled_sweep_is_reported_as_information(addon, core, test_scene, monkeypatch,
                                                     capfd):
    scene = test_scene["scene"]
    set_sweep(scene, methods="bsp_wn+kd", k_min=3, k_max=12)
    scene.bsplab.sweep_json = json.dumps({"methods": [], "previous": True})
    original_run = addon.k_sweep.experiment.KSweepJob.run

    def cancelled_run(job):
        job.cancel()  # as the modal operator does on Esc
        original_run(job)

    monkeypatch.setattr(addon.k_sweep.experiment.KSweepJob, "run", cancelled_run)
    # No RuntimeError: bpy.ops raises one only for an ERROR report.
    assert bpy.ops.bsplab.sweep_k() == {'CANCELLED'}
    assert json.loads(scene.bsplab.sweep_json)["previous"] is True
    out, err = capfd.readouterr()
    assert "Sweep K cancelled" in out + err
    assert "Error" not in out + err

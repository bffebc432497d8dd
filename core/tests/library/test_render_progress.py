"""Rendering modes, camera framing, progress and cancellation."""

from __future__ import annotations

import numpy as np
import pytest

import bsplab
from bsplab import scenes, workloads
from conftest import cancelled_once_held


@pytest.fixture(scope="module")
def room():
    tris = scenes.generate("room")
    return tris, bsplab.build(tris), scenes.default_camera("room")


@pytest.mark.parametrize("mode", bsplab.RENDER_MODES)
def test_every_mode_renders(room, mode):
    tris, tree, cam = room
    image, stats = bsplab.render(tree, cam, 64, 48, mode)
    assert image.shape == (48, 64, 4) and image.dtype == np.float32
    assert np.isfinite(image).all() and image.min() >= 0 and image.max() <= 1
    assert (image[..., 3] == 1).all()
    assert image[..., :3].std() > 0.01  # not a flat colour
    assert stats["rays"] == 64 * 48 and stats["hits"] > 0 and stats["rays_per_second"] > 0
    # Shaded, normal and depth trace on the hits-only path unless asked to
    # count (test_hits_only.py compares the two paths).
    assert stats["counters"] == (mode in bsplab.render.__globals__["HEAT_COUNTERS"])
    if stats["counters"]:
        assert stats["mean_steps"] > 0 and stats["mean_tests"] > 0
    else:
        assert stats["mean_steps"] is None and stats["mean_tests"] is None


def test_render_matches_intersect(room):
    tris, tree, cam = room
    image, _ = bsplab.render(tree, cam, 40, 30, "normal")
    o, d = cam.rays(40, 30)
    hits = tree.intersect(o, d)
    hit = (hits["prim"] >= 0).reshape(30, 40)
    bg = np.all(np.isclose(image[..., :3], bsplab.render.__globals__["BACKGROUND"]), axis=-1)
    np.testing.assert_array_equal(~hit, bg)


def test_row_zero_is_the_top(room):
    # A camera looking at a floor from above and tilted: the bottom rows see
    # the floor close by (small t), the top rows see further away.
    tris, tree, _ = room
    lo, hi = workloads.bounds(tris)
    c = (lo + hi) / 2
    cam = bsplab.Camera.look_at((c[0], c[1] - 2.0, hi[2] - 0.3), (c[0], c[1] + 2.0, lo[2]),
                                up=(0, 0, 1), fov_deg=40)
    o, d = cam.rays(16, 16)
    t = tree.intersect(o, d)["t"].reshape(16, 16)
    assert np.nanmedian(t[0]) > np.nanmedian(t[-1])


def test_progress_reaches_one_and_cancel_stops_a_build():
    tris = scenes.generate("spheres")
    p = bsplab.Progress()
    bsplab.build(tris, progress=p)
    assert p.value == pytest.approx(1.0, abs=1e-6)
    p2 = bsplab.Progress()
    p2.cancel()
    with pytest.raises(bsplab.Cancelled):
        bsplab.build(tris, progress=p2)


def test_cancel_from_another_thread_stops_a_render():
    tris = scenes.generate("spheres")
    tree = bsplab.build(tris)
    cam = scenes.default_camera("spheres")
    p = bsplab.Progress()
    p.hold_at_check(3)  # the render's third chunk of rays waits for the cancel
    with cancelled_once_held(p) as seen, pytest.raises(bsplab.Cancelled):
        bsplab.render(tree, cam, 128, 128, threads=1, progress=p)
    assert len(seen) == 1 and 0 < seen[0] < 1  # two chunks traced, the rest not


def test_gil_is_released_during_a_build():
    """A Python thread runs while a build is under way: the build waits at
    one of its checks until that thread cancels it. Were the GIL held, the
    thread could not run; the build would go on after the hold's limit and
    end without being cancelled."""
    tris = scenes.generate("spheres")
    p = bsplab.Progress()
    p.hold_at_check(5)
    with cancelled_once_held(p) as seen, pytest.raises(bsplab.Cancelled):
        bsplab.build(tris, threads=1, progress=p)
    assert len(seen) == 1 and seen[0] < 1


def test_methods_table():
    table = bsplab.methods()
    assert "kd" in table
    for name, info in table.items():
        assert info["label"] and info["description"] and info["params"]
        bsplab.build(np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], np.float32), method=name)

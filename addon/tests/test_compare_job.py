"""The A/B comparison's images (addon/compare/images.py) and its job
(addon/build_render/job.py) without Blender, with the real core."""

import dataclasses

import numpy as np
import pytest

import bsplab
from bsplab import scenes
from bsplab.blender.scene_camera import CameraSpec
from bsplab.render import heat_ramp

from addon_without_blender import addon_module

compare = addon_module("compare.images")
jobs = addon_module("build_render.job")
stats = addon_module("build_render.statistics")


def _image(rng, height=6, width=9):
    image = np.ones((height, width, 4), np.float32)
    image[..., :3] = rng.random((height, width, 3), dtype=np.float32) * 0.5
    return image


def test_split_keeps_each_half_and_draws_the_line():
    rng = np.random.default_rng(1)
    a, b = _image(rng), _image(rng)
    out = compare.split_image(a, b)
    start, stop = compare.split_columns(a.shape[1])
    assert (start, stop) == (3, 5)
    np.testing.assert_array_equal(out[:, :start], a[:, :start])
    np.testing.assert_array_equal(out[:, stop:], b[:, stop:])
    assert np.all(out[:, start:stop, :3] == compare.SPLIT_LINE)
    # The line's colour is found nowhere in A or B.
    assert not np.any(np.all(a[..., :3] == compare.SPLIT_LINE, axis=-1))


def test_split_refuses_images_of_different_sizes():
    rng = np.random.default_rng(2)
    with pytest.raises(ValueError, match="differ in shape"):
        compare.split_image(_image(rng), _image(rng, width=8))
    with pytest.raises(ValueError, match="at least 4 px wide"):
        compare.split_image(_image(rng, width=3), _image(rng, width=3))


def test_diverging_is_white_at_zero_and_saturates_at_the_ends():
    colours = compare.diverging(np.array([-2.0, -1.0, 0.0, 0.5, 1.0]))
    np.testing.assert_array_equal(colours[2], [1.0, 1.0, 1.0])
    np.testing.assert_allclose(colours[0], compare.FEWER, atol=1e-6)
    np.testing.assert_allclose(colours[1], compare.FEWER, atol=1e-6)
    np.testing.assert_allclose(colours[4], compare.MORE, atol=1e-6)
    np.testing.assert_allclose(colours[3], (1.0 + compare.MORE) / 2, atol=1e-6)


def test_difference_map_signs_follow_b_minus_a():
    a = np.array([[3, 5, 7], [1, 1, 9]], np.uint32)
    b = np.array([[3, 9, 2], [1, 0, 9]], np.uint32)
    image, top, clipped = compare.difference_image(a, b)
    assert top == 5 and clipped == 0 and image.shape == (2, 3, 4)
    diff = b.astype(int) - a.astype(int)
    white = np.all(image[..., :3] == 1.0, axis=-1)
    redder = image[..., 0] > image[..., 2]
    bluer = image[..., 2] > image[..., 0]
    np.testing.assert_array_equal(white, diff == 0)
    np.testing.assert_array_equal(redder, diff > 0)
    np.testing.assert_array_equal(bluer, diff < 0)
    np.testing.assert_allclose(image[0, 2, :3], compare.FEWER, atol=1e-6)  # -5: the end


def test_equal_counts_give_an_all_white_map_and_say_so():
    counts = np.arange(12, dtype=np.uint32).reshape(3, 4)
    image, top, clipped = compare.difference_image(counts, counts.copy())
    assert top == 0 and clipped == 0 and np.all(image == 1.0)
    with_bar = compare.with_difference_bar(image, top, "steps")
    assert with_bar.shape[0] > 3 and with_bar.shape[1] >= 4
    np.testing.assert_array_equal(with_bar[:3, :4], image)


def test_the_difference_bar_runs_from_minus_max_to_plus_max():
    a = np.zeros((40, 200), np.uint32)
    b = a.copy()
    b[0, 0] = 7
    image, top, clipped = compare.difference_image(a, b)
    out = compare.with_difference_bar(image, top, "tests", clipped)
    strip = out[40:]
    # The bar's row holds both ends of the map and white between them.
    rows = np.where(np.any(np.all(np.isclose(strip[..., :3], compare.MORE, atol=0.02), -1), 1))[0]
    assert rows.size > 0
    bar = strip[rows[0], :, :3]
    assert np.any(np.all(np.isclose(bar, compare.FEWER, atol=0.02), -1))
    # (near white: on the square-root scale only the bar's very middle is white)
    assert np.any(np.all(bar > 0.9, -1))


def test_one_outlier_does_not_wash_out_the_difference_map():
    # 999 pixels differ by 2 or -2, one by 50: the range follows the many.
    a = np.full((10, 100), 10, np.uint32)
    b = a.copy()
    b[:5] += 2
    b[5:] -= 2
    b[0, 0] = 60
    image, scale, clipped = compare.difference_image(a, b)
    assert scale == 2 and clipped == 1 / 1000
    np.testing.assert_allclose(image[1, 0, :3], compare.MORE, atol=1e-6)   # +2: full colour
    np.testing.assert_allclose(image[9, 0, :3], compare.FEWER, atol=1e-6)  # -2: full colour
    np.testing.assert_allclose(image[0, 0, :3], compare.MORE, atol=1e-6)   # +50: clipped to the end
    assert compare.difference_scale(np.array([0, 0])) == 0


def test_the_bar_shows_each_difference_in_the_maps_colour():
    # A value's colour on the map is the bar's colour at its position.
    scale = 20
    values = np.arange(-scale, scale + 1)
    image, s, _ = compare.difference_image(np.full((1, values.size), scale, np.uint32),
                                           (values + scale).astype(np.uint32)[None])
    assert s == scale
    on_bar = compare.diverging_ramp((values + scale) / (2 * scale))
    np.testing.assert_allclose(image[0, :, :3], on_bar, atol=1e-6)
    # and a small difference is visibly coloured: 1 of 20 is 22 % of the way.
    assert image[0, scale + 1, 2] < 0.85


def test_a_heat_split_puts_both_halves_on_one_scale():
    a = np.full((4, 8), 2, np.uint32)
    b = np.full((4, 8), 8, np.uint32)
    left, right, top = compare.heat_split(a, b, "heat_steps", heat_ramp)
    assert top == 8
    np.testing.assert_allclose(left[0, 0, :3], heat_ramp(np.float32(0.25)))
    np.testing.assert_allclose(right[0, 0, :3], heat_ramp(np.float32(1.0)))


def test_preview_rejects_an_unknown_view():
    rng = np.random.default_rng(3)
    with pytest.raises(ValueError, match="unknown comparison view 'sideways'"):
        compare.preview(_image(rng), _image(rng), None, "shaded", "sideways", heat_ramp)


# -----------------------------------------------------------------------------
# The job with a tree B


def _input(triangles, camera, b, view="split", mode="shaded", width=40, height=30):
    fields = {f.name: getattr(camera, f.name) for f in dataclasses.fields(bsplab.Camera)}
    spec = CameraSpec(width=width, height=height, name="TestCam", **fields)
    return jobs.JobInput(triangles=triangles, objects=1, instances=1, camera=spec,
                         method="kd", options={}, mode=mode, threads=2, cull=False,
                         compare_with_embree=False, count_steps=True, scene_name="Scene",
                         b=b, compare_view=view)


@pytest.fixture(scope="module")
def scene():
    return scenes.generate("spheres"), scenes.default_camera("spheres")


def _run(inp, **caches):
    job = jobs.Job(bsplab, inp, **caches)
    job.run()
    assert job.error is None, job.error
    return job


def test_b_equal_to_a_reuses_a_tree_and_compares_equal(scene):
    tris, cam = scene
    job = _run(_input(tris, cam, jobs.TreeChoice("kd", {}), view="diff_steps"))
    result = job.result
    assert job.b.reused
    np.testing.assert_array_equal(result["counts"]["a"]["steps"], result["counts"]["b"]["steps"])
    names, rows = stats.compare_grid(result["stats"])
    ratios = {label: ratio for label, _, _, ratio in rows}
    for label in ("Build", "Nodes", "Memory", "Steps/Ray", "Tests/Ray"):
        assert ratios[label] == "1.00", (label, ratios)
    image = compare.preview(result["image"], result["b_image"], result["counts"], "shaded",
                            "diff_steps", heat_ramp)
    assert np.all(image[:30, :40] == 1.0)


def test_b_different_gives_b_own_render_and_counts(scene):
    tris, cam = scene
    choice = jobs.TreeChoice("bsp_wn+kd", {"k": 4})
    job = _run(_input(tris, cam, choice, view="diff_tests"))
    result = job.result
    assert not job.b.reused
    tree_b = bsplab.build(tris, method="bsp_wn+kd", k=4)
    image_b, render_b = bsplab.render(tree_b, cam, 40, 30, mode="shaded", counters=True)
    np.testing.assert_array_equal(result["b_image"], image_b)
    assert result["stats"]["b"]["render"]["mean_tests"] == render_b["mean_tests"]
    origins, directions = cam.rays(40, 30)
    hits = tree_b.intersect(origins, directions, counters=True)
    np.testing.assert_array_equal(result["counts"]["b"]["tests"].ravel(), hits["tests"])
    assert result["stats"]["b"]["build"]["nodes"] == tree_b.stats["nodes"]


def test_cancel_stops_both_trees(scene):
    tris, cam = scene
    job = jobs.Job(bsplab, _input(tris, cam, jobs.TreeChoice("bsp_wn+kd", {"k": 4})))
    job.cancel()
    job.run()
    assert isinstance(job.error, bsplab.Cancelled) and job.result is None
    assert job.a.build_progress.cancelled and job.b.build_progress.cancelled
    assert job.b.render_progress.cancelled


def test_the_progress_covers_both_trees(scene):
    tris, cam = scene
    job = _run(_input(tris, cam, jobs.TreeChoice("bsp_wn+kd", {"k": 3})))
    assert job.fraction() == pytest.approx(1.0)
    job.b.render_progress = bsplab.Progress()  # as if B had not rendered yet
    assert job.fraction() == pytest.approx(0.8)

"""A/B comparison: Build & Render with "Compare with B" on builds and renders
tree B too; the preview is a split image or a difference map, the Statistics
panel shows A, B and B/A (addon/compare.py)."""

import bpy
import numpy as np
import pytest

import bsplab_test_utils as utils
from test_errors import assert_cancelled_quietly, assert_fails_cleanly
from test_ui import RecordingLayout, draw

# A second method with a K, which gives another tree than kd's on the test scene.
B_METHOD, B_K = "bsp_wn+kd", 4
WIDTH, HEIGHT = 80, 60  # the test scene at the default 50 % preview


class GridLayout(RecordingLayout):
    """RecordingLayout with the grid the A/B statistics are drawn in."""

    def _child(self, *_args, **_kwargs):
        return GridLayout(self.log, self.icons)

    column = row = box = split = grid_flow = _child


def press():
    assert bpy.ops.bsplab.build_render() == {'FINISHED'}


def preview_pixels(addon):
    return utils.image_pixels_top_down(bpy.data.images[addon.jobs.preview.IMAGE_NAME]).copy()


def set_b(scene, method=B_METHOD, k=B_K, view="split"):
    compare = scene.bsplab_compare
    compare.enabled = True
    compare.method = method
    if k is not None:
        compare.k = k
    compare.view = view
    return compare


def own_render(addon, scene, method, k=None):
    """The preview of a press with A = (method, k) and no B."""
    enabled = scene.bsplab_compare.enabled
    scene.bsplab_compare.enabled = False
    scene.bsplab.method = method
    if k is not None:
        scene.bsplab.k = k
    press()
    pixels = preview_pixels(addon)
    scene.bsplab_compare.enabled = enabled
    scene.bsplab.method = "kd"
    return pixels


def ratios(scene, addon):
    (_, _), rows = addon.build_render.statistics.compare_grid(scene.bsplab.stats)
    return {label: ratio for label, _, _, ratio in rows}


@pytest.mark.parametrize("view", ["diff_steps", "diff_tests"])
def test_b_equal_to_a_gives_a_white_map_and_ratios_of_one(addon, core, test_scene, view):
    scene = test_scene["scene"]
    scene.bsplab.method = "kd"
    set_b(scene, method="kd", k=None, view=view)
    press()
    image = preview_pixels(addon)
    assert np.all(image[:HEIGHT, :WIDTH] == 1.0), "B = A must differ nowhere"
    assert image.shape[0] > HEIGHT  # the colour bar below
    stats = scene.bsplab.stats
    assert stats["b"]["build"]["reused"] is True  # A's own tree
    got = ratios(scene, addon)
    for label in ("Build", "Nodes", "Memory", "Steps/Ray", "Tests/Ray"):
        assert got[label] == "1.00", (label, got)
    # Times are measured for each tree: a ratio, not necessarily 1.
    assert float(got["Mray/s"]) > 0


def test_split_shows_a_left_and_b_right_with_the_line(addon, core, test_scene):
    scene = test_scene["scene"]
    a_own = own_render(addon, scene, "kd")
    b_own = own_render(addon, scene, B_METHOD, B_K)
    assert a_own.shape == (HEIGHT, WIDTH, 4)
    set_b(scene, view="split")
    press()
    split = preview_pixels(addon)
    start, stop = addon.compare.images.split_columns(WIDTH)
    np.testing.assert_array_equal(split[:, :start], a_own[:, :start])
    np.testing.assert_array_equal(split[:, stop:], b_own[:, stop:])
    assert np.all(split[:, start:stop, :3] == addon.compare.images.SPLIT_LINE)
    stats = scene.bsplab.stats
    assert stats["build"]["method"] == "kd" and stats["b"]["build"]["method"] == B_METHOD
    assert stats["b"]["build"]["nodes"] != stats["build"]["nodes"]


def test_difference_signs_match_the_per_pixel_counters(addon, core, test_scene):
    scene = test_scene["scene"]
    set_b(scene, view="diff_tests")
    press()
    image = preview_pixels(addon)[:HEIGHT, :WIDTH]
    # The counters of both trees, traced here without the add-on's job.
    inp = addon.build_render.scene_input.read_scene(bpy.context, core)
    cam = addon.jobs.scene_reader.make_camera(core, inp.camera)
    origins, directions = cam.rays(WIDTH, HEIGHT)
    counts = []
    for method, options in ((inp.method, inp.options), (inp.b.method, inp.b.options)):
        tree = core.build(inp.triangles, method=method, **options)
        counts.append(tree.intersect(origins, directions, counters=True)["tests"])
    diff = (counts[1].astype(np.int64) - counts[0]).reshape(HEIGHT, WIDTH)
    assert np.any(diff != 0), "the test needs two trees that differ somewhere"
    np.testing.assert_array_equal(np.all(image[..., :3] == 1.0, axis=-1), diff == 0)
    np.testing.assert_array_equal(image[..., 0] > image[..., 2], diff > 0)
    np.testing.assert_array_equal(image[..., 2] > image[..., 0], diff < 0)
    assert scene.bsplab.stats["render"]["mean_tests"] is not None  # counted for the grid


def test_b_k_out_of_range_is_refused(addon, core, test_scene):
    methods = core.methods()
    name = next((m for m, info in methods.items() if info.get("min_k", 0) and info["min_k"] > 1),
                None)
    if name is None:
        pytest.skip("the core has no method with a lower bound on K above 1")
    set_b(test_scene["scene"], method=name, k=methods[name]["min_k"] - 1)
    message = assert_fails_cleanly(addon, test_scene["scene"], "Tree B: K must be in")
    assert name in message or methods[name].get("label", name) in message


def test_b_that_the_core_refuses_is_reported_as_b(addon, core, test_scene, monkeypatch):
    real_build = core.build

    def refuse_b(triangles, method=None, **kwargs):
        if method == B_METHOD:
            raise ValueError("leaf_size out of range")
        return real_build(triangles, method=method, **kwargs)

    monkeypatch.setattr(core, "build", refuse_b)
    set_b(test_scene["scene"])
    assert_fails_cleanly(addon, test_scene["scene"], "Tree B cannot be built: leaf_size")


@pytest.mark.parametrize("cancel_in", ["kd", B_METHOD])
def test_cancel_stops_both(addon, core, test_scene, monkeypatch, capfd, cancel_in):
    """Esc during A's build stops the job before B is built; during B's, no
    render follows."""
    real_build, real_render = core.build, core.render
    built, rendered = [], []

    def build(triangles, method=None, progress=None, **kwargs):
        built.append(method)
        if method == cancel_in:
            progress.cancel()
        return real_build(triangles, method=method, progress=progress, **kwargs)

    def render(*args, **kwargs):
        rendered.append(1)
        return real_render(*args, **kwargs)

    monkeypatch.setattr(core, "build", build)
    monkeypatch.setattr(core, "render", render)
    addon.state.STATE.forget_trees()
    set_b(test_scene["scene"])
    assert_cancelled_quietly(addon, test_scene["scene"], "Build & Render cancelled", capfd)
    assert built == (["kd"] if cancel_in == "kd" else ["kd", B_METHOD])
    assert len(rendered) == (0 if cancel_in == "kd" else 1)


def test_panels_show_b_and_the_grid(addon, core, test_scene):
    scene = test_scene["scene"]
    set_b(scene, view="diff_steps")
    log = draw(addon.compare.panel.BSPLAB_PT_compare, GridLayout())
    props = [name for kind, name in log if kind == "prop"]
    assert props[0] == "method" and "view" in props
    assert ("k" in props) == ("k" in core.methods()[B_METHOD]["params"])
    assert "threads" not in props  # B uses A's
    press()
    labels = [text for kind, text in draw(addon.build_render.panel.BSPLAB_PT_stats, GridLayout())
              if kind == "label"]
    assert "A: kd" in labels and "B: {} K={}".format(B_METHOD, B_K) in labels
    row = labels.index("Nodes")
    nodes_a, nodes_b = scene.bsplab.stats["build"]["nodes"], scene.bsplab.stats["b"]["build"]["nodes"]
    assert labels[row + 1:row + 4] == ["{:,}".format(nodes_a), "{:,}".format(nodes_b),
                                       "{:.2f}".format(nodes_b / nodes_a)]


def test_turning_b_off_forgets_its_tree(addon, core, test_scene):
    scene = test_scene["scene"]
    set_b(scene)
    press()
    assert len(addon.state.STATE.tree_cache_b) == 1
    scene.bsplab_compare.enabled = False
    press()
    assert len(addon.state.STATE.tree_cache_b) == 0
    assert "b" not in scene.bsplab.stats


def test_a_heat_split_shares_one_scale(addon, core, test_scene):
    scene = test_scene["scene"]
    scene.bsplab.render_mode = "heat_steps"
    set_b(scene, view="split")
    press()
    image = preview_pixels(addon)
    inp = addon.build_render.scene_input.read_scene(bpy.context, core)
    cam = addon.jobs.scene_reader.make_camera(core, inp.camera)
    origins, directions = cam.rays(WIDTH, HEIGHT)
    steps = [core.build(inp.triangles, method=m, **o).intersect(
        origins, directions, counters=True)["steps"].reshape(HEIGHT, WIDTH)
        for m, o in ((inp.method, inp.options), (inp.b.method, inp.b.options))]
    top = max(int(steps[0].max()), int(steps[1].max()))
    assert int(steps[0].max()) != int(steps[1].max()), "the test needs different maxima"
    ramp = addon.backend.heat_ramp()
    start, stop = addon.compare.images.split_columns(WIDTH)
    expected_a = ramp(steps[0].astype(np.float32) / top)
    expected_b = ramp(steps[1].astype(np.float32) / top)
    np.testing.assert_allclose(image[:HEIGHT, :start, :3], expected_a[:, :start], atol=1e-6)
    np.testing.assert_allclose(image[:HEIGHT, stop:WIDTH, :3], expected_b[:, stop:], atol=1e-6)
    assert image.shape[0] > HEIGHT  # one colour bar for both halves


def test_b_is_compared_with_embree_too(addon, core, test_scene):
    scene = test_scene["scene"]
    scene.bsplab.compare_with_embree = True
    set_b(scene)
    press()
    stats = scene.bsplab.stats
    assert stats["b"]["embree"]["available"] == stats["embree"]["available"]
    row = {label: (a, b) for label, a, b, _ in addon.build_render.statistics.compare_grid(stats)[1]}["x Embree"]
    if stats["embree"]["available"]:
        assert row == ("{:.2f}".format(stats["embree"]["time_ratio"]),
                       "{:.2f}".format(stats["b"]["embree"]["time_ratio"]))
    else:  # Blender 3.4 declines Embree (a clashing library): no ratio
        assert row == ("-", "-")


def test_a_preview_too_narrow_to_split_is_refused(addon, core, test_scene):
    scene = test_scene["scene"]
    # Blender's smallest resolution, 4 x 4, at 75 %: a 3 x 3 preview.
    scene.render.resolution_x, scene.render.resolution_y = 4, 4
    scene.bsplab.preview_percentage = 75
    set_b(scene)
    with pytest.raises(RuntimeError, match="cannot show the preview: a split needs"):
        bpy.ops.bsplab.build_render()


def test_choosing_b_method_loads_its_defaults_and_leaves_a_alone(addon, core, test_scene):
    scene = test_scene["scene"]
    scene.bsplab.k = 7
    compare = scene.bsplab_compare
    compare.method = "kd"
    compare.k = 20
    compare.method = B_METHOD
    assert compare.k == core.methods()[B_METHOD]["defaults"]["k"]
    assert scene.bsplab.k == 7 and scene.bsplab.method == "kd"

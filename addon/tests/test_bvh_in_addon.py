"""The add-on with a BVH, without Blender: the overlay's boxes by depth
(overlay/geometry.py, drawing/boxes.py), the statistics rows that apply to a
BVH (build_render/statistics.py), the ray inspector's entered boxes
(inspector/trace.py), and the job's heat map and A/B difference of box
tests (build_render/job.py, compare/images.py), all against the core's own
node_boxes / trace_path / intersect."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest

import bsplab
from bsplab import scenes
from bsplab.blender.scene_camera import CameraSpec

from addon_without_blender import addon_module

boxes = addon_module("drawing.boxes")
geometry = addon_module("overlay.geometry")
statistics = addon_module("build_render.statistics")
trace = addon_module("inspector.trace")
jobs = addon_module("build_render.job")
compare = addon_module("compare.images")
legend = addon_module("drawing.legend")


@functools.lru_cache(maxsize=None)
def tree_of(method: str, scene: str = "room") -> bsplab.Tree:
    return bsplab.build(scenes.generate(scene), method=method)


# -----------------------------------------------------------------------------
# Boxes as lines


def test_a_box_has_its_eight_corners_and_twelve_axis_parallel_edges():
    lo, hi = np.array([[0.0, 1.0, 2.0]]), np.array([[1.0, 3.0, 6.0]])
    corners = boxes.corners(lo, hi)[0]
    assert {tuple(c) for c in corners} == {(x, y, z) for x in (0, 1) for y in (1, 3)
                                           for z in (2, 6)}
    assert len(boxes.EDGES) == 12 and len({tuple(sorted(e)) for e in boxes.EDGES}) == 12
    for a, b in boxes.EDGES:  # each edge changes one coordinate
        assert np.count_nonzero(corners[a] != corners[b]) == 1
    positions, indices = boxes.wireframe(np.vstack([lo, lo + 10]), np.vstack([hi, hi + 10]))
    assert positions.shape == (16, 3) and indices.shape == (24, 2)
    assert indices[:12].max() < 8 <= indices[12:].min()  # box 2's edges use its own corners
    segments = boxes.segments(lo, hi)
    assert segments.shape == (24, 3)
    assert np.array_equal(segments.reshape(12, 2, 3), corners[boxes.EDGES])


# -----------------------------------------------------------------------------
# The overlay


def test_overlay_of_a_bvh_is_its_node_boxes_coloured_by_depth():
    tree = tree_of("bvh")
    settings = geometry.OverlaySettings(max_depth=4, colour_by="kind", cells=True)
    out = geometry.overlay_geometry(tree, settings)
    found = tree.node_boxes(4)
    n = len(found["node"])
    assert n > 1 and out["polygons"] == n and not out["cut"]
    assert np.array_equal(out["node"], found["node"])
    # Eight corners and twelve edges per box, no faces and no cells.
    assert out["face_positions"].shape == (8 * n, 3) and len(out["line_indices"]) == 12 * n
    assert len(out["face_indices"]) == 0 and len(out["cell_indices"]) == 0
    assert np.array_equal(out["face_positions"].reshape(n, 8, 3),
                          boxes.corners(found["lo"], found["hi"]))
    # Coloured by depth even when the settings say "kind": a box has no kind.
    expected = np.repeat(geometry.depth_colours(found["depth"], 4), 8, axis=0)
    assert np.allclose(out["line_colours"][:, :3], expected)
    assert np.allclose(out["line_colours"][:, 3], geometry.OUTLINE_ALPHA)
    assert out["notes"] == [f"{n:,} node boxes", geometry.BVH_NOTE]


def test_overlay_of_a_bvh_is_cut_at_the_cap_and_says_of_how_many():
    tree = tree_of("bvh", "spheres")
    out = geometry.overlay_geometry(tree, geometry.OverlaySettings(max_depth=12, cap=50))
    assert out["cut"] and out["polygons"] <= 50 < out["polygon_total"]
    assert out["notes"][0].startswith(f"showing {out['polygons']:,} of")


def test_overlay_cursor_scope_on_a_bvh_draws_the_subtree_under_the_cursor():
    tree = tree_of("bvh")
    # A point on a triangle lies in the box of the leaf that holds it.
    cursor = tuple(float(c) for c in scenes.generate("room")[0].mean(axis=0))
    node, depth = tree.node_at(cursor, max_depth=2)
    settings = geometry.OverlaySettings(max_depth=3, scope="cursor", subtree_depth=2)
    out = geometry.overlay_geometry(tree, settings, cursor)
    assert out["root"] == node and out["root_depth"] == depth
    assert np.array_equal(out["node"], tree.node_boxes(3, root=node)["node"])
    # A cursor in no box: nothing drawn, and the note says why.
    far = geometry.overlay_geometry(tree, settings, (1e6, 1e6, 1e6))
    assert far["polygons"] == 0 and far["notes"] == ["3D cursor is in no leaf's box"]


def test_overlay_of_a_kd_tree_is_still_its_split_polygons():
    out = geometry.overlay_geometry(tree_of("kd"), geometry.OverlaySettings(max_depth=3))
    assert len(out["face_indices"]) > 0 and geometry.BVH_NOTE not in out["notes"]


# -----------------------------------------------------------------------------
# The statistics panel


def _labels(stats, title):
    return [label for t, rows in statistics.sections(stats) if t == title
            for label, _ in rows]


def _stats(tree, render=None):
    return {"scene": {"triangles": 1}, "build": dict(tree.stats, method=tree.method),
            "render": render or {}}


def test_statistics_of_a_bvh_leave_out_the_rows_of_split_planes():
    cam = scenes.default_camera("room")
    tree = tree_of("bvh")
    _, render = bsplab.render(tree, cam, 24, 16, "shaded", counters=True)
    stats = _stats(tree, render)
    build = _labels(stats, "Build")
    for meaningless in ("Kd / General", "Duplication", "Empty Leaves", "Leaf Boxes"):
        assert meaningless not in build
    assert {"Structure", "SAH Cost", "Node Bytes"} <= set(build)
    rows = dict(r for t, rs in statistics.sections(stats) for r in rs)
    assert rows["Structure"] == "BVH (boxes)"
    assert rows["Build Quality"] == "binned"  # whatever it was asked
    assert rows["Box Tests / Ray"] == "{:.2f}".format(render["mean_box_tests"])
    assert render["mean_box_tests"] > 0


def test_statistics_of_a_kd_tree_keep_theirs_and_show_no_box_tests():
    tree = tree_of("kd")
    _, render = bsplab.render(tree, scenes.default_camera("room"), 24, 16, counters=True)
    stats = _stats(tree, render)
    assert {"Kd / General", "Duplication", "Leaf Boxes"} <= set(_labels(stats, "Build"))
    rows = dict(r for _, rs in statistics.sections(stats) for r in rs)
    assert rows["Build Quality"] == "exact"  # the registry's default, which tree_of builds
    assert "Box Tests / Ray" not in _labels(stats, "Render")
    assert dict(r for _, rs in statistics.sections(stats) for r in rs)["Structure"] == \
        "split planes"


# -----------------------------------------------------------------------------
# The ray inspector


def test_inspector_lists_the_boxes_a_bvh_ray_entered():
    tree = tree_of("bvh")
    origin, direction = np.float32([0.1, 0.2, 0.3]), np.float32([0.3, 0.5, 0.8])
    inspection = trace.inspect(tree, origin, direction, False, "viewport")
    path = tree.trace_path(origin, direction)
    assert inspection["structure"] == "bvh"
    assert inspection["counts"]["box_tests"] == int(path["box_tests"]) > 0
    kinds = {row[1] for row in inspection["rows"]}
    assert kinds == {"box", "leaf"}
    assert all(row[2] == "" for row in inspection["rows"])  # no planes to show
    lo, hi = trace.entered_boxes(inspection["path"])
    assert len(lo) == len(path["node"]) == inspection["counts"]["steps"]
    assert np.array_equal(lo, path["box_lo"]) and np.array_equal(hi, path["box_hi"])
    # The ray's t range in each entered box lies in that box.
    for (t0, t1), a, b in zip(path["t_range"], lo, hi):
        p = origin.astype(np.float64) + 0.5 * (t0 + t1) * direction
        assert np.all(p >= a - 1e-4) and np.all(p <= b + 1e-4)


def test_inspector_of_a_kd_tree_enters_no_boxes():
    tree = tree_of("kd")
    inspection = trace.inspect(tree, np.float32([0.1, 0.2, 0.3]), np.float32([0.3, 0.5, 0.8]),
                               False, "viewport")
    assert inspection["structure"] == "bsp" and inspection["counts"]["box_tests"] == 0
    assert len(trace.entered_boxes(inspection["path"])[0]) == 0


def test_inspector_kinds_are_the_cores():
    assert trace.KINDS == bsplab.tree.KINDS


# -----------------------------------------------------------------------------
# The job: heat map and A/B difference of box tests


def _input(triangles, camera, *, method="kd", mode="shaded", b=None, view="split"):
    fields = {f.name: getattr(camera, f.name) for f in dataclasses.fields(bsplab.Camera)}
    spec = CameraSpec(width=40, height=30, name="TestCam", **fields)
    return jobs.JobInput(triangles=triangles, objects=1, instances=1, camera=spec,
                         method=method, options={}, mode=mode, threads=2, cull=False,
                         compare_with_embree=True, count_steps=True, scene_name="Scene",
                         b=b, compare_view=view)


def _run(inp):
    job = jobs.Job(bsplab, inp)
    job.run()
    assert job.error is None, job.error
    return job.result


@pytest.fixture(scope="module")
def spheres():
    return scenes.generate("spheres"), scenes.default_camera("spheres")


def test_bvh_job_renders_the_box_test_heat_map_and_agrees_with_embree(spheres):
    tris, cam = spheres
    result = _run(_input(tris, cam, method="bvh", mode="heat_box_tests"))
    tree = bsplab.build(tris, method="bvh")
    image, render = bsplab.render(tree, cam, 40, 30, mode="heat_box_tests")
    np.testing.assert_array_equal(result["image"], image)
    stats = result["stats"]
    assert stats["build"]["structure"] == "bvh"
    assert stats["render"]["max_box_tests"] == render["max_box_tests"] > 0
    assert legend.heat_scale_top("heat_box_tests", stats["render"]) == render["max_box_tests"]
    compared = stats["embree"]["compare"]
    assert compared["agree"] + compared["embree_wrong"] + compared["grazing"] >= \
        compared["rays"]


def test_ab_kd_against_bvh_shows_the_box_test_difference(spheres):
    tris, cam = spheres
    result = _run(_input(tris, cam, b=jobs.TreeChoice("bvh", {}), view="diff_box_tests"))
    counts = result["counts"]
    assert counts["a"]["box_tests"].max() == 0  # a kd-tree tests no boxes
    bvh = bsplab.build(tris, method="bvh")
    origins, directions = cam.rays(40, 30)
    hits = bvh.intersect(origins, directions, counters=True)
    np.testing.assert_array_equal(counts["b"]["box_tests"].ravel(), hits["box_tests"])
    image = compare.preview(result["image"], result["b_image"], counts, "shaded",
                            "diff_box_tests", bsplab.render.__globals__["heat_ramp"])
    # B - A per pixel at the top left, over the bar: every pixel B tests more.
    diff, scale, _ = compare.difference_image(counts["a"]["box_tests"], counts["b"]["box_tests"])
    assert scale > 0 and np.array_equal(image[:30, :40], diff)
    names, rows = statistics.compare_grid(result["stats"])
    assert names == ("kd", "bvh")
    boxes_row = next(r for r in rows if r[0] == "Boxes/Ray")
    assert boxes_row[1] == "0.00" and float(boxes_row[2]) > 0
    # Between two kd-trees the row would say nothing: it is left out.
    kd_kd = _run(_input(tris, cam, b=jobs.TreeChoice("kd", {"leaf_size": 2})))
    assert "Boxes/Ray" not in [r[0] for r in statistics.compare_grid(kd_kd["stats"])[1]]

"""Every bad input raises a clear Python exception, never a crash."""

from __future__ import annotations

import numpy as np
import pytest

import bsplab
from bsplab import scenes

TRI = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], np.float32)


@pytest.fixture(scope="module")
def tree():
    return bsplab.build(scenes.generate("room"))


@pytest.mark.parametrize("bad, exc, words", [
    (np.zeros((0, 3, 3), np.float32), ValueError, "no triangles"),
    (np.zeros((4, 3), np.float32), ValueError, "shape"),
    (np.zeros((4, 3, 2), np.float32), ValueError, "shape"),
    (np.array([["a", "b", "c"]] * 3, dtype=object)[None], TypeError, "dtype"),
    (np.full((2, 3, 3), np.nan, np.float32), ValueError, "NaN"),
    (np.where(np.arange(18).reshape(2, 3, 3) == 4, np.inf, 1.0), ValueError, "infinite"),
    ("triangles", TypeError, "dtype"),
])
def test_bad_triangles(bad, exc, words):
    with pytest.raises(exc, match=words):
        bsplab.build(bad)


def test_bad_indices():
    v = np.zeros((3, 3), np.float32)
    with pytest.raises(ValueError, match="out of range"):
        bsplab.build((v, np.array([[0, 1, 3]])))
    with pytest.raises(TypeError, match="integer"):
        bsplab.build((v, np.array([[0.0, 1.0, 2.0]])))


@pytest.mark.parametrize("options, exc, words", [
    ({"method": "octree"}, ValueError, "unknown method"),
    ({"method": 3}, TypeError, "string"),
    ({"colour": 1}, TypeError, "unknown build option"),
    ({"traversal_cost": -1.0}, ValueError, "traversal_cost"),
    ({"intersect_cost": 0.0}, ValueError, "intersect_cost"),
    ({"intersect_cost": float("nan")}, ValueError, "finite"),
    ({"empty_bonus": 1.0}, ValueError, "empty_bonus"),
    ({"max_depth": 200}, ValueError, "max_depth"),
    ({"max_depth": 2.5}, ValueError, "whole"),
    ({"leaf_size": 0}, ValueError, "leaf_size"),
    ({"max_duplication": 0.5}, ValueError, "max_duplication"),
    ({"threads": -2}, ValueError, "threads"),
    ({"threads": "many"}, TypeError, "threads"),
])
def test_bad_options(options, exc, words):
    with pytest.raises(exc, match=words):
        bsplab.build(TRI, **options)


@pytest.mark.parametrize("o, d, exc, words", [
    (np.zeros((2, 3)), np.zeros((2, 3)), ValueError, "zero length"),
    (np.zeros((2, 3)), np.ones((3, 3)), ValueError, "differ"),
    (np.zeros((2, 2)), np.ones((2, 2)), ValueError, "shape"),
    (np.full((2, 3), np.nan), np.ones((2, 3)), ValueError, "NaN"),
    (np.zeros((2, 3)), np.full((2, 3), np.inf), ValueError, "infinite"),
])
def test_bad_rays(tree, o, d, exc, words):
    with pytest.raises(exc, match=words):
        tree.intersect(o, d)


def test_bad_ray_ranges(tree):
    o, d = np.zeros((2, 3)), np.ones((2, 3))
    with pytest.raises(ValueError, match="tmin"):
        tree.intersect(o, d, tmin=np.zeros(3))
    with pytest.raises(ValueError, match="NaN"):
        tree.intersect(o, d, tmax=np.nan)
    with pytest.raises(ValueError, match=">= 0"):
        tree.intersect(o, d, tmin=-1.0)


@pytest.mark.parametrize("w, h, mode, exc, words", [
    (0, 10, "shaded", ValueError, "width"),
    (10, -1, "shaded", ValueError, "height"),
    (10.5, 10, "shaded", TypeError, "width"),
    (10, 10, "xray", ValueError, "unknown render mode"),
    (100000, 10, "shaded", ValueError, "width"),
])
def test_bad_render_arguments(tree, w, h, mode, exc, words):
    cam = bsplab.Camera.look_at((5, 5, 5), (0, 0, 0))
    with pytest.raises(exc, match=words):
        bsplab.render(tree, cam, w, h, mode)


def test_render_wrong_types(tree):
    with pytest.raises(TypeError, match="Camera"):
        bsplab.render(tree, "camera", 10, 10)
    with pytest.raises(TypeError, match="Tree"):
        bsplab.render("tree", bsplab.Camera(), 10, 10)


# -- progress, tmin/tmax -----------------------------------------------------------


@pytest.mark.parametrize("bad", [5, "p", object()])
def test_progress_must_be_a_progress(tree, bad):
    o, d = np.zeros((2, 3)), np.ones((2, 3))
    name = type(bad).__name__
    with pytest.raises(TypeError, match=f"^progress must be a bsplab.Progress or None, "
                                        f"got {name}$"):
        tree.intersect(o, d, progress=bad)
    with pytest.raises(TypeError, match="progress must be a bsplab.Progress"):
        bsplab.build(TRI, progress=bad)
    with pytest.raises(TypeError, match="progress must be a bsplab.Progress"):
        bsplab.render(tree, bsplab.Camera.look_at((5, 5, 5), (0, 0, 0)), 4, 4, progress=bad)


def test_none_ray_range_means_the_default(tree):
    o = np.tile([[1.0, 1.0, 1.0]], (4, 1))
    d = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, -1, -1]], float)
    ref = tree.intersect(o, d)
    for kw in ({"tmax": None}, {"tmin": None}, {"tmin": None, "tmax": None}):
        got = tree.intersect(o, d, **kw)
        np.testing.assert_array_equal(got["t"], ref["t"])
        np.testing.assert_array_equal(got["prim"], ref["prim"])
    assert (ref["prim"] >= 0).all()  # the rays hit, so an accidental tmax=0 would show
    with pytest.raises(TypeError, match="tmax must be a real number, an array of real numbers "
                                        "or None, got str 'far'"):
        tree.intersect(o, d, tmax="far")


def test_progress_reset_clears_a_cancel():
    p = bsplab.Progress()
    p.cancel()
    with pytest.raises(bsplab.Cancelled):
        bsplab.build(TRI, progress=p)
    p.reset()
    assert not p.cancelled and p.value == 0.0
    bsplab.build(TRI, progress=p)  # usable again
    assert p.value == pytest.approx(1.0)


# -- cameras -----------------------------------------------------------------------


@pytest.mark.parametrize("kwargs, exc, message", [
    ({"lens": 1e-300}, ValueError, r"Camera: lens must be in 0.001..1e6 mm, got 1e-300"),
    ({"lens": 1e7}, ValueError, r"lens must be in 0.001..1e6 mm"),
    ({"shift_x": 1e300}, ValueError, r"Camera: shift_x must be in -100..100, got 1e\+300"),
    ({"shift_y": -101.0}, ValueError, r"shift_y must be in -100..100"),
    ({"sensor_width": 1e-9}, ValueError, r"sensor_width must be in 0.001..1e6 mm"),
    ({"sensor_height": 1e9}, ValueError, r"sensor_height must be in 0.001..1e6 mm"),
    ({"pixel_aspect": 1e-6}, ValueError, r"pixel_aspect must be in 0.001..1000"),
    ({"clip_start": 0.0}, ValueError, r"clip_start must be in 1e-9..1e30"),
    ({"lens": "50"}, TypeError, r"Camera: lens must be a number, got str '50'"),
    ({"lens": True}, TypeError, r"lens must be a number, got bool"),
    ({"shift_x": None}, TypeError, r"shift_x must be a number, got NoneType"),
    ({"clip_end": "far"}, TypeError, r"clip_end must be a number"),
    ({"matrix_world": "abc"}, TypeError, r"matrix_world must be a 4x4 array of numbers"),
    ({"matrix_world": np.eye(4) * 1e200}, ValueError, r"zero-length \(or overflowing\) axis"),
    ({"matrix_world": [[1, 0, 0, 1e31], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]},
     ValueError, r"position .* is beyond \+-1e30"),
])
def test_absurd_cameras_are_refused(kwargs, exc, message):
    with pytest.raises(exc, match=message):
        bsplab.Camera(**kwargs)


@pytest.mark.parametrize("kwargs, exc, message", [
    ({"fov_deg": "50"}, TypeError, "Camera.look_at: fov_deg must be a number, got str '50'"),
    ({"fov_deg": 0.0}, ValueError, r"fov_deg must be in 0.01..179.9 degrees, got 0.0"),
    ({"fov_deg": 180}, ValueError, r"fov_deg must be in 0.01..179.9 degrees"),
    ({"fov_deg": float("nan")}, ValueError, r"fov_deg must be in 0.01..179.9 degrees"),
    ({"sensor_width": "36"}, TypeError, r"sensor_width must be a number"),
    ({"eye": "abc"}, TypeError, r"Camera.look_at: eye must be 3 numbers, got 'abc'"),
    ({"target": (1, 2)}, ValueError, r"target must be 3 numbers, got shape \(2,\)"),
    ({"up": (np.nan, 0, 0)}, ValueError, r"up must be finite"),
    ({"up": (0, 0, 0)}, ValueError, r"up must not be the zero vector"),
])
def test_bad_look_at(kwargs, exc, message):
    args = {"eye": (5, 5, 5), "target": (0, 0, 0), **kwargs}
    with pytest.raises(exc, match=message):
        bsplab.Camera.look_at(args.pop("eye"), args.pop("target"), **args)


@pytest.mark.parametrize("kwargs", [
    # The ends of Blender's own fields: lens 1..5000 mm, sensor 1..100 mm,
    # shift -10..10 (older versions' limit), pixel aspect 1..200 each.
    {"lens": 1.0, "sensor_width": 100.0, "shift_x": 10.0, "shift_y": -10.0},
    {"lens": 5000.0, "sensor_width": 1.0, "sensor_height": 1.0, "pixel_aspect": 200.0},
    {"lens": 1.0, "sensor_height": 100.0, "sensor_fit": "VERTICAL", "pixel_aspect": 1 / 200},
    {"clip_start": 1e-6, "clip_end": 3.4e38},
])
def test_every_blender_camera_is_accepted(kwargs):
    o, d = bsplab.Camera(**kwargs).rays(16, 9)
    assert np.isfinite(o).all() and np.isfinite(d).all()
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-5)
    extreme = bsplab.Camera.look_at((1, 2, 3), (0, 0, 0), fov_deg=179.9)
    assert np.isfinite(extreme.rays(8, 8)[1]).all()


# -- the command line ----------------------------------------------------------------


def run_cli(capsys, *argv):
    """(exit code, stderr) of `python -m bsplab ...`, run in-process."""
    from bsplab.__main__ import main
    try:
        code = main([str(a) for a in argv])
    except SystemExit as e:  # argparse
        code = e.code
    err = capsys.readouterr().err
    return code, err


@pytest.mark.parametrize("argv, message", [
    (["demo", "--scene", "{d}"], "error: {d}: is a directory, not a mesh file (.ply, .obj, .glb, .gltf, .stl, .off)"),
    (["demo", "--scene", "{d}/dir.ply"], "error: {d}/dir.ply: is a directory, not a mesh file"),
    (["demo", "--scene", "{d}/empty.obj"], "error: {d}/empty.obj: the file is empty: no "
                                           "triangles"),
    (["demo", "--scene", "{d}/nope.ply"], "error: no scene '{d}/nope.ply'"),
    (["demo", "--out", "{d}"], "error: --out {d} is a directory; give a file name such as "
                               "{d}/demo.png"),
    (["demo", "--out", "{d}/empty.obj/x.png"], "error: --out {d}/empty.obj/x.png: "
                                               "{d}/empty.obj is a file, not a directory"),
    (["demo", "--width", "0"], "error: argument --width: must be >= 1, got 0"),
    (["demo", "--threads", "many"], "error: argument --threads: expected a whole number, "
                                    "got 'many'"),
    (["bench", "--out", "{d}"], "error: --out {d} is a directory"),
    (["bench-family", "--out", "{d}"], "error: --out {d} is a directory"),
    (["bench-family", "--kmin", "10", "--kmax", "3"], "error: --kmin 10 is more than --kmax 3"),
    (["bench-cull", "--out", "{d}"], "error: --out {d} is a directory"),
    (["report", "{d}/foreign.csv", "--out", "{d}"], "error: --out {d} is a directory"),
    (["report", "{d}", "--out", "{d}/r.md"], "error: {d} is a directory, not a results file"),
    (["results", "--out", "{d}"], "error: --out {d} is a directory"),
    (["scenes", "--out", "{d}/empty.obj"], "error: --out {d}/empty.obj is a file; give a "
                                           "directory"),
    (["experiment", "{d}"], "error: spec file {d} is a directory"),
    (["experiment", "{d}/spec.toml", "--out", "{d}"], "error: --out {d} is a directory; give "
                                                      "a results path"),
    (["experiment", "{d}/spec.toml", "--report", "{d}"], "error: --report {d} is a directory"),
])
def test_cli_refuses_bad_paths_in_one_line(tmp_path, capsys, argv, message):
    d = tmp_path
    (d / "dir.ply").mkdir()
    (d / "empty.obj").write_text("")
    (d / "spec.toml").write_text('scenes = ["room"]\nmethods = ["kd"]\n')
    code, err = run_cli(capsys, *[a.format(d=d) for a in argv])
    assert code == 2
    assert err.startswith(message.format(d=d)), err
    assert err.count("\n") == 1 and "Traceback" not in err


# Every subcommand's --out (and experiment's --report) in a folder that does
# not exist: refused before any work, and nothing created.
MISSING_FOLDER_CASES = [
    ["demo", "--out", "{m}/x.png"],
    ["bench", "--out", "{m}/b.md"],
    ["bench-family", "--out", "{m}/b.md"],
    ["bench-cull", "--out", "{m}/b.md"],
    ["bench-build", "--out", "{m}/b.md"],
    ["bench-instanced", "--out", "{m}/b.md"],
    ["experiment", "{d}/spec.toml", "--out", "{m}/run"],
    ["experiment", "{d}/spec.toml", "--report", "{m}/r.md"],
    ["report", "{d}/foreign.csv", "--out", "{m}/r.md"],
    ["results", "--out", "{m}/results.md"],
    ["verdict", "--out", "{m}/verdict.md"],
    ["scenes", "--out", "{m}/scenes"],
]


@pytest.mark.parametrize("argv", MISSING_FOLDER_CASES, ids=lambda a: " ".join(a[:1] + a[-2:-1]))
def test_cli_refuses_an_out_in_a_missing_folder(tmp_path, capsys, argv):
    d, missing = tmp_path, tmp_path / "no" / "such"
    (d / "spec.toml").write_text('scenes = ["room"]\nmethods = ["kd"]\n')
    (d / "foreign.csv").write_text("")
    code, err = run_cli(capsys, *[a.format(d=d, m=missing) for a in argv])
    flag = argv[-2]
    assert code == 2, err
    assert err.startswith(f"error: {flag} {missing}/") and \
        f"the folder {missing} does not exist; create it first" in err, err
    assert err.count("\n") == 1
    assert not (d / "no").exists()


def test_a_default_out_gets_its_folder_and_a_given_one_must_exist(tmp_path):
    from bsplab.__main__ import DefaultPath, output_dir, output_file
    new = tmp_path / "new" / "x.png"
    assert output_file(DefaultPath(str(new)), "--out", "x.png") == new  # created on writing
    with pytest.raises(ValueError, match="does not exist"):
        output_file(str(new), "--out", "x.png")
    assert output_file(str(tmp_path / "x.png"), "--out", "x.png") == tmp_path / "x.png"
    assert output_dir(str(tmp_path / "scenes"), "--out") == tmp_path / "scenes"
    with pytest.raises(ValueError, match="does not exist"):
        output_dir(str(tmp_path / "new" / "scenes"), "--out")


def test_cli_error_is_one_line_without_traceback(tmp_path):
    import subprocess
    import sys
    r = subprocess.run([sys.executable, "-m", "bsplab", "demo", "--scene", str(tmp_path),
                        "--out", str(tmp_path / "x.png")], capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr == f"error: {tmp_path}: is a directory, not a mesh file (.ply, .obj, .glb, .gltf, .stl, .off)\n"


def test_the_cores_ray_check_agrees_with_numpy():
    # checks.rays trusts _core.rays_are_valid's one pass and only then looks
    # for the bad rays with numpy: the two must agree on every kind of value.
    from bsplab import _core
    rng = np.random.default_rng(4)
    specials = np.array([np.nan, np.inf, -np.inf, 0.0, -0.0, 1e-45, -1e-45, 3e38, 1.0],
                        np.float32)
    for trial in range(300):
        n = int(rng.integers(1, 40))
        o = rng.normal(size=(n, 3)).astype(np.float32)
        d = rng.normal(size=(n, 3)).astype(np.float32)
        for arr in (o, d):
            k = int(rng.integers(0, 3))
            idx = rng.integers(0, n, k), rng.integers(0, 3, k)
            arr[idx] = rng.choice(specials, k)
        if trial % 3 == 0:
            d[rng.integers(0, n)] = rng.choice(specials[3:5], 3)  # +-0 only
        expected = bool(np.isfinite(o).all() and np.isfinite(d).all()
                        and (d != 0).any(axis=1).all())
        assert _core.rays_are_valid(o, d) is expected, (o, d)

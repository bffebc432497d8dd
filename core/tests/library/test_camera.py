"""Camera: Blender's framing (sensor fit, shift, pixel aspect), orientation, validation.

Expected values are derived here from Blender's documented model: the fitted
image axis spans `sensor / lens` on the unit-distance image plane, the other
axis follows the (pixel-aspect corrected) image aspect, shifts are in units
of the fitted axis.
"""

import json
import math

import numpy as np
import pytest

from bsplab.camera import Camera


def _rotation(seed=0):
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    return q


def _matrix(seed=0, scale=1.0):
    m = np.eye(4)
    m[:3, :3] = _rotation(seed) * scale
    m[:3, 3] = (1.0, -2.0, 3.0)
    return m


def _local(cam, d):
    """World directions -> camera frame, as (x/-z, y/-z) image-plane coordinates."""
    axes = cam.matrix_world[:3, :3] / np.linalg.norm(cam.matrix_world[:3, :3], axis=0)
    loc = np.asarray(d, np.float64) @ axes
    return loc[..., 0] / -loc[..., 2], loc[..., 1] / -loc[..., 2]


@pytest.mark.parametrize("scale", [1.0, 2.5])
def test_centre_ray_is_minus_z_and_origins_are_the_eye(scale):
    cam = Camera(matrix_world=_matrix(1, scale), lens=35.0)
    o, d = cam.rays(101, 61)
    assert o.shape == d.shape == (101 * 61, 3) and o.dtype == d.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-6)
    np.testing.assert_allclose(o, np.broadcast_to([1.0, -2.0, 3.0], o.shape))
    centre = d[30 * 101 + 50]
    np.testing.assert_allclose(centre, -_rotation(1)[:, 2], atol=1e-6)


def _expected_half_tangents(fit, w, h, lens, sw, sh, aspect=1.0):
    """(tan of half width, tan of half height) of the whole frame."""
    landscape = w * aspect >= h
    horizontal = fit == "HORIZONTAL" or (fit == "AUTO" and landscape)
    sensor = sh if fit == "VERTICAL" else sw
    ratio = (w * aspect) / h  # displayed width / height
    if horizontal:
        return sensor / (2 * lens), sensor / (2 * lens) / ratio
    return sensor / (2 * lens) * ratio, sensor / (2 * lens)


@pytest.mark.parametrize("fit", ["AUTO", "HORIZONTAL", "VERTICAL"])
@pytest.mark.parametrize("size", [(160, 90), (90, 160)])
def test_corner_rays_match_the_fov(fit, size):
    w, h = size
    cam = Camera(matrix_world=_matrix(2), lens=28.0, sensor_width=36.0, sensor_height=24.0,
                 sensor_fit=fit)
    _, d = cam.rays(w, h)
    tx, ty = _expected_half_tangents(fit, w, h, 28.0, 36.0, 24.0)
    # Pixel centres sit half a pixel inside the frame edges.
    ex, ey = tx * (w - 1) / w, ty * (h - 1) / h
    corners = {0: (-ex, ey), w - 1: (ex, ey), (h - 1) * w: (-ex, -ey), h * w - 1: (ex, -ey)}
    axis = -_rotation(2)[:, 2]
    for index, (x, y) in corners.items():
        angle = math.degrees(math.acos(np.clip(d[index] @ axis, -1, 1)))
        assert angle == pytest.approx(math.degrees(math.atan(math.hypot(x, y))), abs=1e-3)
        lx, ly = _local(cam, d[index])
        assert (lx, ly) == (pytest.approx(x, abs=1e-5), pytest.approx(y, abs=1e-5))


def test_blender_default_camera_numbers():
    # Blender's default camera: 50 mm lens, 36 mm sensor -> 39.6 deg across the larger side.
    cam = Camera()
    xmin, xmax, ymin, ymax = cam.viewplane(1920, 1080)
    assert math.degrees(2 * math.atan(xmax)) == pytest.approx(39.5978, abs=1e-3)
    assert math.degrees(2 * math.atan(ymax)) == pytest.approx(22.8952, abs=1e-3)
    xmin, xmax, ymin, ymax = cam.viewplane(1080, 1920)  # portrait: sensor width spans height
    assert math.degrees(2 * math.atan(ymax)) == pytest.approx(39.5978, abs=1e-3)
    assert (xmin, ymin) == (pytest.approx(-xmax), pytest.approx(-ymax))


def test_row_zero_is_top_and_column_zero_is_left():
    cam = Camera(matrix_world=_matrix(3))
    _, d = cam.rays(8, 6)
    up, right = _rotation(3)[:, 1], _rotation(3)[:, 0]
    grid = d.reshape(6, 8, 3)
    assert np.all(grid[0] @ up > 0) and np.all(grid[-1] @ up < 0)
    assert np.all(grid[:, 0] @ right < 0) and np.all(grid[:, -1] @ right > 0)


@pytest.mark.parametrize("size", [(201, 101), (101, 201)])
def test_shift_moves_the_frame_in_units_of_the_larger_side(size):
    w, h = size
    base = Camera(lens=50.0)
    shifted = Camera(lens=50.0, shift_x=0.25, shift_y=-0.1)
    _, d0 = base.rays(w, h)
    _, d1 = shifted.rays(w, h)
    x0, y0 = _local(base, d0)
    x1, y1 = _local(shifted, d1)
    # Every ray moves by the same image-plane offset: shift * (sensor / lens).
    np.testing.assert_allclose(x1 - x0, 0.25 * 36 / 50, atol=1e-5)
    np.testing.assert_allclose(y1 - y0, -0.1 * 36 / 50, atol=1e-5)


def test_shift_with_explicit_horizontal_fit_on_portrait_uses_width():
    cam = Camera(sensor_fit="HORIZONTAL", shift_y=0.5)
    xmin, xmax, ymin, ymax = cam.viewplane(100, 300)
    assert xmax - xmin == pytest.approx(36 / 50)
    assert (ymin + ymax) / 2 == pytest.approx(0.5 * 36 / 50)
    assert ymax - ymin == pytest.approx(3 * 36 / 50)


@pytest.mark.parametrize("aspect", [2.0, 0.5])
def test_pixel_aspect(aspect):
    cam = Camera(pixel_aspect=aspect)
    xmin, xmax, ymin, ymax = cam.viewplane(100, 100)
    tx, ty = _expected_half_tangents("AUTO", 100, 100, 50.0, 36.0, 24.0, aspect)
    assert (xmax, ymax) == (pytest.approx(tx), pytest.approx(ty))
    assert max(xmax, ymax) == pytest.approx(18 / 50)


def test_look_at():
    eye, target = np.array([1.0, 2.0, 3.0]), np.array([4.0, -1.0, 0.5])
    cam = Camera.look_at(eye, target, fov_deg=60.0)
    r = cam.matrix_world[:3, :3]
    np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0)
    assert r[2, 1] > 0  # image up leans towards world +Z
    o, d = cam.rays(31, 21)
    forward = (target - eye) / np.linalg.norm(target - eye)
    np.testing.assert_allclose(d[10 * 31 + 15], forward, atol=1e-6)
    np.testing.assert_allclose(o[0], eye)
    xmin, xmax, _, _ = cam.viewplane(640, 480)
    assert math.degrees(2 * math.atan(xmax)) == pytest.approx(60.0)
    # Looking straight down the up vector still gives a valid camera.
    down = Camera.look_at((0, 0, 5), (0, 0, 0))
    np.testing.assert_allclose(down.matrix_world[:3, 2], [0, 0, 1], atol=1e-12)


@pytest.mark.parametrize("w, h", [(0, 10), (10, -1), (2.5, 10), (10, 10.0), ("10", 10),
                                  (True, 10), (None, 10)])
def test_bad_image_sizes(w, h):
    with pytest.raises(ValueError):
        Camera().rays(w, h)


@pytest.mark.parametrize("kwargs", [
    {"lens": 0.0}, {"lens": -5.0}, {"lens": float("nan")}, {"sensor_fit": "auto"},
    {"sensor_fit": "DIAGONAL"}, {"sensor_width": 0.0}, {"clip_end": 0.05},
    {"pixel_aspect": 0.0}, {"shift_x": float("inf")},
])
def test_bad_parameters(kwargs):
    with pytest.raises(ValueError):
        Camera(**kwargs)


def test_bad_matrices():
    m = np.eye(4)
    m[0, 3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        Camera(matrix_world=m)
    with pytest.raises(ValueError):
        Camera(matrix_world=np.eye(3))
    cam = Camera()
    cam.matrix_world[1, 1] = np.inf  # mutated after construction: caught by rays()
    with pytest.raises(ValueError):
        cam.rays(4, 4)
    with pytest.raises(ValueError):
        Camera.look_at((1, 1, 1), (1, 1, 1))


def test_dict_round_trip_through_json():
    cam = Camera(matrix_world=_matrix(4), lens=42.0, sensor_fit="VERTICAL", shift_x=0.1,
                 shift_y=-0.2, clip_start=0.5, clip_end=50.0, pixel_aspect=1.5)
    back = Camera.from_dict(json.loads(json.dumps(cam.to_dict())))
    np.testing.assert_array_equal(back.matrix_world, cam.matrix_world)
    assert back.to_dict() == cam.to_dict()
    np.testing.assert_array_equal(back.rays(7, 5)[1], cam.rays(7, 5)[1])
    with pytest.raises(ValueError, match="unknown"):
        Camera.from_dict({"focal": 3})

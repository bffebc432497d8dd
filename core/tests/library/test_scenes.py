"""Generated scenes: fixed counts, determinism, shipped copies, sensible cameras."""

from pathlib import Path

import numpy as np
import pytest

from bsplab import io, scenes

SHIPPED = Path(__file__).resolve().parents[3] / "scenes"
COUNTS = {"room": (2076, 1594), "spheres": (48480, 24361), "fan": (9264, 9366)}  # (tris, verts)


def _areas(tris):
    return 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)


def _first_hits(origins, directions, tris):
    """Brute-force nearest hit distance per ray (Moller-Trumbore), inf on a miss."""
    v0, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    p = np.cross(directions[:, None, :], e2[None])
    det = np.einsum("rtk,tk->rt", p, e1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = origins[:, None, :] - v0[None]
        u = np.einsum("rtk,rtk->rt", s, p) * inv
        q = np.cross(s, e1[None])
        v = np.einsum("rk,rtk->rt", directions, q) * inv
        t = np.einsum("tk,rtk->rt", e2, q) * inv
    ok = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-6)
    return np.where(ok, t, np.inf).min(axis=1)


def test_names():
    assert scenes.NAMES == ("room", "spheres", "fan")
    with pytest.raises(ValueError, match="unknown scene"):
        scenes.generate("castle")


@pytest.mark.parametrize("name", scenes.NAMES)
def test_counts_types_and_determinism(name):
    v, f = scenes.generate_mesh(name)
    assert v.dtype == np.float32 and f.dtype == np.int32
    assert (len(f), len(v)) == COUNTS[name]
    assert f.min() == 0 and f.max() == len(v) - 1
    tris = scenes.generate(name)
    assert tris.shape == (len(f), 3, 3) and tris.dtype == np.float32
    np.testing.assert_array_equal(tris, v[f])
    np.testing.assert_array_equal(tris, scenes.generate(name))
    assert np.all(np.isfinite(tris)) and np.all(_areas(tris.astype(np.float64)) > 0)


def test_room_is_closed_and_furnished():
    tris = scenes.generate("room").astype(np.float64)
    assert 2000 <= len(tris) <= 5000
    np.testing.assert_allclose(tris.reshape(-1, 3).min(0), [-4, -3, 0])
    np.testing.assert_allclose(tris.reshape(-1, 3).max(0), [4, 3, 3])
    # Rays from a point inside the room must all hit something inside the room.
    rng = np.random.default_rng(0)
    d = rng.normal(size=(300, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t = _first_hits(np.tile([0.3, -0.7, 2.0], (300, 1)), d, tris)
    assert np.all(np.isfinite(t)) and t.max() < np.linalg.norm([8, 6, 3])
    # Furniture: geometry strictly inside the shell, off the walls.
    inner = tris.reshape(-1, 3)[1440 * 3:]
    assert np.all(np.abs(inner[:, 0]) < 4) and np.all(np.abs(inner[:, 1]) < 3)


def test_spheres_rest_on_the_ground():
    v, f = scenes.generate_mesh("spheres")
    assert 30000 <= len(f) <= 60000
    assert v[:, 2].min() == pytest.approx(0.0, abs=1e-6)
    ground = v[:441]  # the 21 x 21 ground grid comes first
    assert np.all(ground[:, 2] == 0)


def test_fan_is_full_of_slivers():
    tris = scenes.generate("fan").astype(np.float64)
    assert 5000 <= len(tris) <= 20000
    edges = np.linalg.norm(tris - np.roll(tris, 1, axis=1), axis=2)
    # Longest edge^2 / area: 2/sqrt(3) * 2 ~ 2.3 for an equilateral triangle.
    thinness = edges.max(axis=1) ** 2 / _areas(tris)
    assert np.mean(thinness > 100) > 0.9
    assert np.sum(edges.max(axis=1) > 9.9) >= 40  # the long needles


@pytest.mark.parametrize("name", scenes.NAMES)
def test_shipped_copy_matches_generator(name):
    path = SHIPPED / f"{name}.ply"
    assert path.is_file(), f"{path} missing: run `python -m bsplab scenes --out scenes`"
    assert path.stat().st_size < 1.5e6
    v, f = io.read_ply(path)
    v0, f0 = scenes.generate_mesh(name)
    np.testing.assert_array_equal(v, v0)
    np.testing.assert_array_equal(f, f0)


def test_main_write(tmp_path):
    paths = scenes.main_write(tmp_path / "out")
    assert sorted(p.name for p in paths) == ["fan.ply", "room.ply", "spheres.ply"]
    for p in paths:
        np.testing.assert_array_equal(io.load_mesh(p), scenes.generate(p.stem))


@pytest.mark.parametrize("name, min_inside", [("room", 0.5), ("spheres", 0.95), ("fan", 0.85)])
def test_default_camera_frames_the_scene(name, min_inside):
    v, _ = scenes.generate_mesh(name)
    cam = scenes.default_camera(name)
    m = cam.matrix_world
    local = (v.astype(np.float64) - m[:3, 3]) @ m[:3, :3]
    depth = -local[:, 2]
    x, y = local[:, 0] / depth, local[:, 1] / depth
    xmin, xmax, ymin, ymax = cam.viewplane(640, 360)
    inside = (depth > 0) & (x > xmin) & (x < xmax) & (y > ymin) & (y < ymax)
    assert inside.mean() >= min_inside
    if name == "room":  # the camera stands inside the room and sees only walls and furniture
        assert np.all(np.abs(m[:3, 3]) < [4, 3, 3])
        o, d = cam.rays(16, 9)
        assert np.all(np.isfinite(_first_hits(o.astype(np.float64), d.astype(np.float64),
                                              scenes.generate(name).astype(np.float64))))

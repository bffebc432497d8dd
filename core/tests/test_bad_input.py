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

"""Index arrays for drawing flat polygon lists (vertices + offsets, as
Tree.split_polygons and Tree.leaf_cells return them) with a GPU batch:
triangle fans for filled polygons, edge pairs for wireframes."""

from __future__ import annotations

import numpy as np


def _sizes(offsets) -> tuple[np.ndarray, np.ndarray]:
    off = np.asarray(offsets, dtype=np.int64)
    if off.ndim != 1 or len(off) == 0 or (np.diff(off) < 0).any():
        raise ValueError("offsets must be a non-decreasing 1-D array starting each polygon")
    return off[:-1], np.diff(off)


def fan_triangles(offsets) -> np.ndarray:
    """(T, 3) uint32 vertex indices: each convex polygon of n vertices as the
    n - 2 triangles (v0, v_i, v_i+1)."""
    first, size = _sizes(offsets)
    fans = np.maximum(size - 2, 0)
    start = np.repeat(first, fans)
    # i runs 1 .. n-2 within each polygon.
    i = np.arange(fans.sum()) - np.repeat(np.cumsum(fans) - fans, fans) + 1
    return np.stack([start, start + i, start + i + 1], axis=1).astype(np.uint32)


def edge_pairs(offsets) -> np.ndarray:
    """(E, 2) uint32 vertex indices: every polygon's closed outline, for
    drawing as lines."""
    first, size = _sizes(offsets)
    start = np.repeat(first, size)
    i = np.arange(size.sum()) - np.repeat(np.cumsum(size) - size, size)
    nxt = (i + 1) % np.repeat(np.maximum(size, 1), size)
    return np.stack([start + i, start + nxt], axis=1).astype(np.uint32)

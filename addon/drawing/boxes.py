# SPDX-License-Identifier: GPL-3.0-or-later
"""Axis-aligned boxes as line lists, for a BVH's node boxes (the tree
overlay, overlay/geometry.py) and the boxes a ray entered (the ray inspector,
inspector/draw.py). Pure numpy: no bpy, no gpu."""

import numpy as np

# A box's eight corners, corner c taking hi on axis a where bit a of c is set
# (0 = lo, lo, lo ... 7 = hi, hi, hi), and its twelve edges: the corner pairs
# that differ in one bit.
CORNER_BITS = np.array([[(c >> axis) & 1 for axis in range(3)] for c in range(8)], bool)
EDGES = np.array([(c, c | (1 << axis)) for c in range(8) for axis in range(3)
                  if not c & (1 << axis)], np.uint32)


def corners(lo, hi):
    """(B, 8, 3) float32 corners of B boxes given by their (B, 3) lo and hi."""
    lo = np.asarray(lo, np.float32).reshape(-1, 1, 3)
    hi = np.asarray(hi, np.float32).reshape(-1, 1, 3)
    return np.where(CORNER_BITS[None], hi, lo).astype(np.float32)


def wireframe(lo, hi):
    """(8B, 3) positions and (12B, 2) uint32 indices of B boxes' edges: a
    "LINES" batch (indexed), box b's corners at rows 8b .. 8b + 7."""
    return corner_wireframe(corners(lo, hi))


def corner_wireframe(box_corners):
    """wireframe() of B boxes given by their (B, 8, 3) corners in CORNER_BITS
    order: an instance's box carried to the world by a rotation or a shear
    is no longer axis-aligned, but its edges still join the same corners."""
    positions = np.ascontiguousarray(np.asarray(box_corners, np.float32).reshape(-1, 3))
    base = (np.arange(len(positions) // 8, dtype=np.uint32) * 8)[:, None, None]
    return positions, (EDGES[None] + base).reshape(-1, 2).astype(np.uint32)


def segments(lo, hi):
    """(24B, 3) float32 line-list vertices of B boxes' edges (a "LINES"
    batch without indices): box b's 12 edges at rows 24b .. 24b + 23."""
    return corner_segments(corners(lo, hi))


def corner_segments(box_corners):
    """segments() of B boxes given by their (B, 8, 3) corners (CORNER_BITS order)."""
    c = np.asarray(box_corners, np.float32).reshape(-1, 8, 3)
    return c[:, EDGES.reshape(-1)].reshape(-1, 3)

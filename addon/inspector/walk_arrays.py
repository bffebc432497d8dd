# SPDX-License-Identifier: GPL-3.0-or-later
"""What the viewport draws of an inspected ray, as plain numpy arrays (no
bpy, no gpu): the ray, the leaf cells it visits (wireframes coloured by
visit order; on a BVH, the boxes of every node it entered) and the
triangles it tests (the hit in green, the missed in red, those skipped by
culling in grey). draw.py makes the GPU batches of them; two_level.py
builds the same arrays for a two-level build's walk. Free of bpy so that
the tests without Blender can check them on the real core.
"""

import numpy as np

from ..drawing import boxes
from . import trace

RAY_COLOUR = (1.0, 0.85, 0.1, 1.0)  # yellow
HIT_POINT_SIZE = 9.0
RAY_WIDTH = 3.0
CELL_WIDTH = 1.5
# The visited cells run from the first's colour to the last's (blue to
# magenta): none of the triangles' colours, so the two never read alike.
FIRST_CELL = np.array((0.15, 0.45, 1.0, 0.9), dtype=np.float32)
LAST_CELL = np.array((0.95, 0.2, 0.95, 0.9), dtype=np.float32)
# Tested triangles, drawn translucent over the model.
HIT_COLOUR = (0.1, 0.95, 0.2, 0.6)  # the closest hit: the ray's answer
SUPERSEDED_COLOUR = (1.0, 0.55, 0.0, 0.5)  # hit, but a closer hit was found later
MISS_COLOUR = (0.95, 0.1, 0.1, 0.4)
CULLED_COLOUR = (0.6, 0.6, 0.6, 0.4)


def visit_colours(count):
    """(count, 4) colours from FIRST_CELL to LAST_CELL."""
    f = np.linspace(0.0, 1.0, count, dtype=np.float32)[:, None]  # [0] for one cell
    return (1 - f) * FIRST_CELL + f * LAST_CELL


def cell_lines(tree, leaves):
    """Line-list vertices (2E, 3) of the leaves' cell edges and their colours
    (2E, 4), by the leaves' visit order. `leaf_cells(max_depth=0, root=n)`
    is node n's own cell."""
    colours = visit_colours(len(leaves))
    coords, cols = [], []
    for leaf, colour in zip(leaves, colours):
        cell = tree.leaf_cells(max_depth=0, root=int(leaf))
        segment_ends = cell["vertices"][cell["edges"].reshape(-1)]
        coords.append(segment_ends)
        cols.append(np.broadcast_to(colour, (len(segment_ends), 4)))
    if not coords:
        return np.zeros((0, 3), np.float32), np.zeros((0, 4), np.float32)
    return (np.concatenate(coords).astype(np.float32),
            np.ascontiguousarray(np.concatenate(cols), dtype=np.float32))


def box_lines(path):
    """Line-list vertices (24S, 3) and colours (24S, 4) of the boxes of the
    S nodes a BVH walk entered, by visit order: a BVH has no cells, and the
    boxes are what its steps test."""
    lo, hi = trace.entered_boxes(path)
    colours = np.repeat(visit_colours(len(lo)), 24, axis=0)
    return boxes.segments(lo, hi), np.ascontiguousarray(colours, dtype=np.float32)


def tested_triangle_colours(path, hit_prim):
    """Which references to draw (all but the repeats of a triangle this ray
    already tested) and the colour of each."""
    results, prims = path["test_result"], path["test_prim"]
    keep = np.flatnonzero(results != trace.SEEN)
    table = {trace.MISS: MISS_COLOUR, trace.HIT: SUPERSEDED_COLOUR,
             trace.CULLED: CULLED_COLOUR}
    colours = np.array([HIT_COLOUR if (r == trace.HIT and p == hit_prim) else table[r]
                        for r, p in zip(results[keep].tolist(), prims[keep].tolist())],
                       dtype=np.float32).reshape(-1, 4)
    return prims[keep], colours


def draw_data(tree, triangles, inspection):
    """The arrays the batches are made of (all float32): "ray" (2, 3) from
    the origin to the hit or the box exit; "hit" (0 or 1, 3) the hit point;
    "cell_coords" / "cell_colours" a line list of the visited leaves' cells
    (of a BVH: of every visited node's box);
    "tri_coords" / "tri_colours" (3T, 3) / (3T, 4) the tested triangles
    (taken from `triangles`, those `tree` was built of), one colour per
    corner."""
    path = inspection["path"]
    hit_prim = inspection["counts"]["hit_prim"]
    ray, hit = ray_segment(inspection, hit_prim is not None)
    if inspection.get("structure") == "bvh":
        cell_coords, cell_cols = box_lines(path)
    else:
        leaves = path["node"][path["kind"] == trace.LEAF]
        cell_coords, cell_cols = cell_lines(tree, leaves)
    prims, colours = tested_triangle_colours(path, hit_prim)
    tris = triangles[prims.astype(np.int64)].reshape(-1, 3)
    return {
        "ray": ray,
        "hit": hit,
        "cell_coords": cell_coords,
        "cell_colours": cell_cols,
        "tri_coords": np.ascontiguousarray(tris, dtype=np.float32),
        "tri_colours": np.repeat(colours, 3, axis=0),
    }


def ray_segment(inspection, hit):
    """The ray drawn from its origin to end_t (the hit, or where it leaves
    the box): (2, 3) float32, and the hit point (1, 3), or (0, 3) when it
    missed."""
    origin, direction = inspection["origin"], inspection["direction"]
    end = origin.astype(np.float64) + inspection["end_t"] * direction.astype(np.float64)
    ray = np.array([origin, end], dtype=np.float32)
    return ray, ray[1:] if hit else np.zeros((0, 3), np.float32)

# SPDX-License-Identifier: GPL-3.0-or-later
"""What the viewport draws of an inspected ray, as plain numpy arrays (no
bpy, no gpu): the ray, the leaf cells it visits (wireframes coloured by
visit order; on a BVH, the boxes of every node it entered) and the
triangles it tests (the hit in green, the missed in red, those skipped by
culling in grey), of one tree's walk (`draw_data`) or of a two-level
build's (`two_level_draw_data`: the top-level boxes entered, then what the
ray crossed inside each instance). draw.py makes the GPU batches of them.
Free of bpy so that the tests without Blender can check them on the real
core.
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
# The top-level boxes a two-level ray entered are drawn in one colour, apart
# from the visit ramp of the cells inside the instances (FIRST_CELL ..
# LAST_CELL), so the two levels never read alike.
TOP_BOX_COLOUR = np.array((1.0, 0.65, 0.2, 0.55), np.float32)


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


def _leaf_cell_lines(tree, path):
    return cell_lines(tree, path["node"][path["kind"] == trace.LEAF])


def _box_lines(_tree, path):
    return box_lines(path)


# What a flat walk crossed, by the tree's structure: the visited leaves'
# cells of a kd or BSP tree, every entered node's box of a BVH.
CROSSED = {"bsp": _leaf_cell_lines, "bvh": _box_lines}


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
    cell_coords, cell_cols = CROSSED[inspection["structure"]](tree, path)
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


# -- a two-level build's walk (trace.inspect_two_level) -------------------------


def instance_cells(tree, visit):
    """(2E, 3) world line-list vertices of what the ray crossed inside one
    instance entered (`visit`, a trace_path "instances" entry): the cells of
    the leaves it visited, or, in a BVH mesh tree, the boxes of the nodes it
    entered (carried to the world as 8 corners: a rotated box stays a box)."""
    instance, inner = int(visit["instance"]), visit["path"]
    return INSTANCE_CROSSED[tree.meshes[int(visit["mesh"])].structure](tree, instance, inner)


def _instance_boxes(tree, instance, inner):
    lo, hi = trace.entered_boxes(inner)
    return boxes.corner_segments(tree.to_world(instance, boxes.corners(lo, hi)))


def _instance_leaf_cells(tree, instance, inner):
    segments = []
    for leaf in inner["node"][inner["kind"] == trace.LEAF].tolist():
        cell = tree.instance_leaf_cells(instance, max_depth=0, root=int(leaf))
        segments.append(cell["vertices"][cell["edges"].reshape(-1)])
    if not segments:
        return np.zeros((0, 3), np.float32)
    return np.concatenate(segments).astype(np.float32)


# What a two-level ray crossed inside one instance, by its mesh tree's
# structure: a BVH's entered boxes, a kd or BSP tree's visited leaves' cells.
INSTANCE_CROSSED = {"bsp": _instance_leaf_cells, "bvh": _instance_boxes}


def two_level_draw_data(tree, inspection):
    """draw_data()'s arrays for a two-level walk: "ray", "hit";
    "cell_coords" / "cell_colours" the top-level boxes entered (first
    "top_vertices" rows, TOP_BOX_COLOUR) then, instance by instance, the
    cells (or boxes) crossed inside (one colour per instance, on the visit
    ramp);
    "tri_coords" / "tri_colours" the tested triangles in world units. Also
    "instance_cells": per instance entered, (instance, its cell vertices).
    """
    path = inspection["path"]
    hit_instance = inspection["counts"]["hit_instance"]
    ray, hit = ray_segment(inspection, hit_instance is not None)

    top = boxes.segments(path["top"]["box_lo"], path["top"]["box_hi"])
    per_instance = [(int(v["instance"]), instance_cells(tree, v)) for v in path["instances"]]
    inner = [coords for _, coords in per_instance]
    # One colour per instance entered, on the visit ramp in the order the
    # ray entered them: which cells belong to which instance reads at once.
    cell_counts = [len(c) for c in inner]
    ramp = visit_colours(len(inner))
    inner_colours = [np.broadcast_to(colour, (count, 4)) for colour, count in
                     zip(ramp, cell_counts)]
    cell_coords = np.concatenate([top] + inner) if inner else top
    cell_colours = np.concatenate([np.broadcast_to(TOP_BOX_COLOUR, (len(top), 4))]
                                  + inner_colours)

    tris, colours = [], []
    for visit in path["instances"]:
        instance = int(visit["instance"])
        hit_prim = int(path["prim"]) if instance == hit_instance else None
        prims, cols = tested_triangle_colours(visit["path"], hit_prim)
        mesh = tree.meshes[int(visit["mesh"])]
        local = mesh.triangles[prims.astype(np.int64)]
        tris.append(tree.to_world(instance, local).reshape(-1, 3))
        colours.append(np.repeat(cols, 3, axis=0))
    return {
        "ray": ray,
        "hit": hit,
        "cell_coords": np.ascontiguousarray(cell_coords, dtype=np.float32),
        "cell_colours": np.ascontiguousarray(cell_colours, dtype=np.float32),
        "tri_coords": np.ascontiguousarray(np.concatenate(tris) if tris else
                                           np.zeros((0, 3)), dtype=np.float32),
        "tri_colours": np.ascontiguousarray(np.concatenate(colours) if colours else
                                            np.zeros((0, 4)), dtype=np.float32),
        "top_vertices": len(top),
        "instance_cells": per_instance,
    }

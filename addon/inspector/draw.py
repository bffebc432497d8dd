# SPDX-License-Identifier: GPL-3.0-or-later
"""The inspected ray in the 3D Viewport: the ray, the leaf cells it visits
(wireframes coloured by visit order; on a BVH, the boxes of every node it
entered) and the triangles it tests (the hit in green, the missed in red,
those skipped by culling in grey).

`draw_data()` computes the arrays once per inspection, without bpy or gpu
(the Blender tests check them in background mode, where drawing raises);
the POST_VIEW handler draws the kept inspection's (`STATE.inspection`),
making the batches on the first frame after the inspection.
"""

import numpy as np

from ..drawing import boxes
from ..state import STATE
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
    origin, direction = inspection["origin"], inspection["direction"]
    hit_prim = inspection["counts"]["hit_prim"]
    end = origin.astype(np.float64) + inspection["end_t"] * direction.astype(np.float64)
    ray = np.array([origin, end], dtype=np.float32)
    hit = ray[1:] if hit_prim is not None else np.zeros((0, 3), np.float32)
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


# -----------------------------------------------------------------------------
# Drawing (main thread, with a GPU). The batches are made on the first frame
# after an inspection (building them needs the GPU) and kept with it in
# STATE.inspection_batches.

DRAW_HANDLER = "inspector"


def _batches(data):
    """(shader, batch, line width or None, uniform colour or None) per layer,
    drawn in this order: triangles, cells, the ray, the hit point on top."""
    from gpu_extras.batch import batch_for_shader

    from ..drawing.gpu_shaders import builtin
    smooth = builtin("SMOOTH_COLOR")
    try:
        # Blender 4.0+: points of a set size on every GPU backend.
        point = builtin("POINT_UNIFORM_COLOR")
    except ValueError:  # 3.x: the plain shader with gpu.state.point_size_set
        point = builtin("UNIFORM_COLOR")
    line, smooth_line = builtin("POLYLINE_UNIFORM_COLOR"), builtin("POLYLINE_SMOOTH_COLOR")
    layers = [
        (smooth, 'TRIS', {"pos": data["tri_coords"], "color": data["tri_colours"]}, None, None),
        (smooth_line, 'LINES', {"pos": data["cell_coords"], "color": data["cell_colours"]},
         CELL_WIDTH, None),
        (line, 'LINES', {"pos": data["ray"]}, RAY_WIDTH, RAY_COLOUR),
        (point, 'POINTS', {"pos": data["hit"]}, None, HIT_COLOUR[:3] + (1.0,)),
    ]
    # An empty layer (no hit, no cell: a ray that missed the box) is left
    # out rather than made into an empty batch.
    return [(shader, batch_for_shader(shader, kind, content), width, colour)
            for shader, kind, content, width, colour in layers if len(content["pos"])]


def _draw():
    inspection = STATE.inspection
    if inspection is None:
        STATE.inspection_batches = (None, None)
        return
    import gpu  # only here: gpu raises in background mode
    made_for, made = STATE.inspection_batches
    if inspection is not made_for:
        made = _batches(inspection["draw"])
        STATE.inspection_batches = (inspection, made)
    viewport = gpu.state.viewport_get()[2:]
    gpu.state.blend_set('ALPHA')
    # On top of the model: the triangles lie in its surfaces and the cells
    # run through it, so a depth test would hide half of what is inspected.
    gpu.state.depth_test_set('NONE')
    gpu.state.point_size_set(HIT_POINT_SIZE)
    for shader, batch, width, colour in made:
        shader.bind()
        if width is not None:
            shader.uniform_float("viewportSize", viewport)
            shader.uniform_float("lineWidth", width)
        if colour is not None:
            shader.uniform_float("color", colour)
        batch.draw(shader)
    gpu.state.blend_set('NONE')
    gpu.state.point_size_set(1.0)


def add_handler():
    STATE.add_draw_handler(DRAW_HANDLER, _draw)


def remove_handler():
    STATE.remove_draw_handler(DRAW_HANDLER)

# SPDX-License-Identifier: GPL-3.0-or-later
"""The inspected ray in the 3D Viewport: the ray, the leaf cells it visits
(wireframes coloured by visit order; on a BVH, the boxes of every node it
entered; on a two-level build, the top-level boxes it entered and the cells
inside each instance it entered) and the triangles it tests (the hit in
green, the missed in red, those skipped by culling in grey).

`draw_data()` (walk_arrays.py; `two_level_draw_data()` for a two-level
build) computes the arrays once per inspection, without bpy or gpu (the Blender
tests check them in background mode, where drawing raises); the POST_VIEW
handler draws the kept inspection's (`STATE.inspection`), making the
batches on the first frame after the inspection.
"""

from ..state import STATE
# The arrays and their colours live in the bpy-free walk_arrays.py; their
# names stay reachable here, where the drawing code and the tests read them.
from .walk_arrays import (  # noqa: F401
    CELL_WIDTH, CULLED_COLOUR, FIRST_CELL, HIT_COLOUR, HIT_POINT_SIZE, LAST_CELL, MISS_COLOUR,
    RAY_COLOUR, RAY_WIDTH, SUPERSEDED_COLOUR, box_lines, cell_lines, draw_data,
    tested_triangle_colours, visit_colours)


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

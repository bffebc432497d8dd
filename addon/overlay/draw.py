# SPDX-License-Identifier: GPL-3.0-or-later
"""The tree overlay in the 3D Viewport: the kept tree's split planes, drawn
translucent and clipped to their cells, and its cells as wireframes; a
BVH's node boxes as wireframes coloured by depth; for a two-level build,
the top level's boxes and the instance under the 3D cursor's own tree in
place (in_place.py).

A `SpaceView3D` draw handler ('WINDOW', 'POST_VIEW': world space, under the
viewport's own depth buffer) is added while the panel's "Tree Overlay" box
is ticked. What it draws is made at most once per change: the arrays by
`cache.GeometryCache` (bsplab walks the tree only when the tree, the
settings or, under the cursor, the cursor moved), the GPU batches from
those arrays when they are new. A frame then costs at most three draw
calls, whatever the tree's size. The tree is the one Build & Render kept
(STATE.kept_tree()); the cache, the batches and the handler are the
state's (state.py), which forgets them when a file is loaded.

`gpu` is imported inside the drawing functions only: it raises in
background mode, where the handler is added but never called.
"""

import time

import bpy

from ..sidebar import tag_redraw_viewports
from ..state import STATE
from . import geometry

DRAW_HANDLER = "overlay"


def kept_tree():
    """The tree the last Build & Render kept (a bsplab.Tree, or a
    bsplab.InstancedTree for a two-level build), or None."""
    return STATE.kept_tree()


def redraw_if_tree_changed(context):
    """Called by the panel's header, which redraws when a job ends: a new
    tree must replace the old one's planes now, not at the next orbit. (The
    job redraws only the sidebars, to spare heavy scenes.)"""
    props = context.scene.bsplab_overlay
    tree = kept_tree()
    if props.show and tree is not None and not STATE.overlay_geometry.made_from(tree):
        tag_redraw_viewports(context)


def current_geometry(scene):
    """The overlay's arrays for `scene`'s settings and the kept tree, or None
    when there is no tree."""
    cursor = tuple(scene.cursor.location)
    return STATE.overlay_geometry.get(kept_tree(), geometry.settings_of(scene.bsplab_overlay),
                                      cursor)


# -----------------------------------------------------------------------------
# Drawing (never called in background mode)


def _make_batches(arrays):
    from gpu_extras.batch import batch_for_shader

    from ..drawing import gpu_shaders
    shader = gpu_shaders.builtin("SMOOTH_COLOR")
    parts = (("TRIS", "face_positions", "face_colours", "face_indices"),
             ("LINES", "face_positions", "line_colours", "line_indices"),
             ("LINES", "cell_positions", "cell_colours", "cell_indices"))
    batches = []
    for kind, positions, colours, indices in parts:
        if len(arrays[indices]):
            batch = batch_for_shader(shader, kind, {"pos": arrays[positions],
                                                    "color": arrays[colours]},
                                     indices=arrays[indices])
            # Faces are translucent: they must not hide the lines behind them.
            batches.append((batch, kind == "TRIS"))
    return shader, batches


def draw_overlay():
    """The draw handler: the cached batches under the viewport's depth."""
    start = time.perf_counter()
    scene = bpy.context.scene
    props = getattr(scene, "bsplab_overlay", None)
    arrays = current_geometry(scene) if props is not None and props.show else None
    if arrays is None:
        STATE.overlay_draw_calls = 0
        return
    made_from, made = STATE.overlay_batches
    if made_from is not arrays:
        made = _make_batches(arrays)
        STATE.overlay_batches = (arrays, made)
    shader, batches = made

    import gpu
    gpu.state.blend_set('ALPHA')
    gpu.state.depth_test_set('LESS_EQUAL')
    for batch, translucent in batches:
        gpu.state.depth_mask_set(not translucent)
        batch.draw(shader)
    gpu.state.depth_mask_set(True)
    gpu.state.depth_test_set('NONE')
    gpu.state.blend_set('NONE')
    STATE.overlay_draw_calls = len(batches)
    STATE.overlay_draw_seconds.append(time.perf_counter() - start)


# -----------------------------------------------------------------------------
# The handler's life


def handler_installed():
    return STATE.has_draw_handler(DRAW_HANDLER)


def sync_handler(show):
    """Add the draw handler when `show`, remove it otherwise (idempotent)."""
    if show:
        STATE.add_draw_handler(DRAW_HANDLER, draw_overlay)
    else:
        STATE.remove_draw_handler(DRAW_HANDLER)


def sync_with_file():
    """After a file is loaded (a STATE.after_load listener): its own tick box
    decides; with no tree yet nothing is drawn and the panel says so."""
    props = getattr(bpy.context.scene, "bsplab_overlay", None)
    sync_handler(bool(props and props.show))


def start():
    """register(): follow the loaded files' tick boxes."""
    STATE.after_load.append(sync_with_file)


def stop():
    """unregister(): no handler, nothing made from the tree kept."""
    if sync_with_file in STATE.after_load:
        STATE.after_load.remove(sync_with_file)
    sync_handler(False)
    STATE.forget_overlay()

# SPDX-License-Identifier: GPL-3.0-or-later
"""The tree overlay in the 3D Viewport: the kept tree's split planes, drawn
translucent and clipped to their cells, and its cells as wireframes.

A `SpaceView3D` draw handler ('WINDOW', 'POST_VIEW': world space, under the
viewport's own depth buffer) is added while the panel's "Tree Overlay" box
is ticked. What it draws is made at most once per change: the arrays by
`overlay_geometry.GeometryCache` (the core walks the tree only when the
tree, the settings or, under the cursor, the cursor moved), the GPU batches
from those arrays when they are new. A frame then costs at most three draw
calls, whatever the tree's size.

`gpu` is imported inside the drawing functions only: it raises in
background mode, where the handler is added but never called.
"""

import collections
import time

import bpy

from . import operators, overlay_geometry

# The 3D view draws with 'POST_VIEW' handlers in world space.
HANDLER_ARGS = ('WINDOW', 'POST_VIEW')

_handle = None
_geometry_cache = overlay_geometry.GeometryCache()
# The GPU batches of the geometry they were made from.
_batches = {"geometry": None, "made": (None, ())}
# perf_counter seconds of the last draws and their draw calls, for the GUI
# check's per-frame figure (a deque append costs nothing next to a draw).
draw_seconds = collections.deque(maxlen=1000)
last_draw_calls = 0


# -----------------------------------------------------------------------------
# Settings


def _tag_redraw_viewports(context):
    for window in context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == 'VIEW_3D':
                area.tag_redraw()


def redraw_if_tree_changed(context):
    """Called by the panel's header, which redraws when a job ends: a new
    tree must replace the old one's planes now, not at the next orbit. (The
    job redraws only the sidebars, to spare heavy scenes.)"""
    props = context.scene.bsplab_overlay
    tree = kept_tree()
    if props.show and tree is not None and not _geometry_cache.made_from(tree):
        _tag_redraw_viewports(context)


def _show_changed(self, context):
    sync_handler(self.show)
    _tag_redraw_viewports(context)


def _changed(self, context):
    _tag_redraw_viewports(context)


def _kind_colour(name, index):
    return bpy.props.FloatVectorProperty(
        name=name, subtype='COLOR', size=3, min=0.0, max=1.0,
        default=overlay_geometry.DEFAULT_KIND_COLOURS[index], update=_changed,
        description="Colour of the {} split planes".format(name.lower()))


class BSPLabOverlaySettings(bpy.types.PropertyGroup):
    show: bpy.props.BoolProperty(
        name="Tree Overlay", default=False, update=_show_changed,
        description="Draw the last built tree's split planes in the 3D Viewport")
    max_depth: bpy.props.IntProperty(
        name="Depth", default=8, min=0, soft_max=20, max=64, update=_changed,
        description="Draw the split planes of depths 0 to this (below the subtree's root)")
    colour_by: bpy.props.EnumProperty(
        name="Colour", update=_changed,
        items=(("kind", "Kind", "x, y, z kd planes and general planes in their own colours"),
               ("depth", "Depth", "A ramp from the root (orange) to the deepest planes (blue)")))
    cells: bpy.props.BoolProperty(
        name="Cells", default=False, update=_changed,
        description="Also draw the cells the planes make (leaves, or nodes one level below "
                    "the depth) as wireframes")
    scope: bpy.props.EnumProperty(
        name="Scope", update=_changed,
        items=(("whole", "Whole Tree", "Draw from the tree's root"),
               ("cursor", "Under Cursor", "Draw only the subtree whose cell holds the 3D cursor")))
    subtree_depth: bpy.props.IntProperty(
        name="Subtree Depth", default=2, min=0, soft_max=30, max=64, update=_changed,
        description="Depth of the subtree's root on the 3D cursor's path (0: the whole tree)")
    alpha: bpy.props.FloatProperty(
        name="Opacity", default=0.25, min=0.0, max=1.0, subtype='FACTOR', update=_changed,
        description="Opacity of the filled split planes (the outlines stay opaque)")
    cap: bpy.props.IntProperty(
        name="Most Polygons", default=20_000, min=1, max=1_000_000, update=_changed,
        description="Draw at most this many split polygons (and cells); shallow levels first")
    colour_x: _kind_colour("X", 0)
    colour_y: _kind_colour("Y", 1)
    colour_z: _kind_colour("Z", 2)
    colour_general: _kind_colour("General", 3)


def settings_of(props):
    """The panel's properties as an OverlaySettings (the cache key)."""
    return overlay_geometry.OverlaySettings(
        max_depth=props.max_depth, colour_by=props.colour_by, cells=props.cells,
        scope=props.scope, subtree_depth=props.subtree_depth, alpha=round(props.alpha, 4),
        cap=props.cap,
        kind_colours=tuple(tuple(round(c, 4) for c in colour) for colour in (
            props.colour_x, props.colour_y, props.colour_z, props.colour_general)))


def kept_tree():
    """The tree the last Build & Render kept, or None."""
    return operators.kept_tree_cache().kept_tree()


def current_geometry(scene):
    """The overlay's arrays for `scene`'s settings and the kept tree, or None
    when there is no tree."""
    cursor = tuple(scene.cursor.location)
    return _geometry_cache.get(kept_tree(), settings_of(scene.bsplab_overlay), cursor)


# -----------------------------------------------------------------------------
# Drawing (never called in background mode)


def _make_batches(geometry):
    from gpu_extras.batch import batch_for_shader

    from . import gpu_shaders
    shader = gpu_shaders.builtin("SMOOTH_COLOR")
    parts = (("TRIS", "face_positions", "face_colours", "face_indices"),
             ("LINES", "face_positions", "line_colours", "line_indices"),
             ("LINES", "cell_positions", "cell_colours", "cell_indices"))
    batches = []
    for kind, positions, colours, indices in parts:
        if len(geometry[indices]):
            batch = batch_for_shader(shader, kind, {"pos": geometry[positions],
                                                    "color": geometry[colours]},
                                     indices=geometry[indices])
            # Faces are translucent: they must not hide the lines behind them.
            batches.append((batch, kind == "TRIS"))
    return shader, batches


def draw_overlay():
    """The draw handler: the cached batches under the viewport's depth."""
    global last_draw_calls
    start = time.perf_counter()
    scene = bpy.context.scene
    props = getattr(scene, "bsplab_overlay", None)
    geometry = current_geometry(scene) if props is not None and props.show else None
    if geometry is None:
        last_draw_calls = 0
        return
    if _batches["geometry"] is not geometry:
        _batches.update(geometry=geometry, made=_make_batches(geometry))
    shader, batches = _batches["made"]

    import gpu
    gpu.state.blend_set('ALPHA')
    gpu.state.depth_test_set('LESS_EQUAL')
    for batch, translucent in batches:
        gpu.state.depth_mask_set(not translucent)
        batch.draw(shader)
    gpu.state.depth_mask_set(True)
    gpu.state.depth_test_set('NONE')
    gpu.state.blend_set('NONE')
    last_draw_calls = len(batches)
    draw_seconds.append(time.perf_counter() - start)


# -----------------------------------------------------------------------------
# The handler's life


def handler_installed():
    return _handle is not None


def sync_handler(show):
    """Add the draw handler when `show`, remove it otherwise (idempotent)."""
    global _handle
    if show and _handle is None:
        _handle = bpy.types.SpaceView3D.draw_handler_add(draw_overlay, (), *HANDLER_ARGS)
    elif not show and _handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_handle, HANDLER_ARGS[0])
        _handle = None


def forget():
    """Drop the handler's geometry and batches (the tree is gone)."""
    _geometry_cache.clear()
    _batches.update(geometry=None, made=(None, ()))


@bpy.app.handlers.persistent
def _before_load(*_args):
    # The kept tree is forgotten on load (operators.forget_kept_tree): so is
    # what was made from it.
    sync_handler(False)
    forget()


@bpy.app.handlers.persistent
def _after_load(*_args):
    # The loaded file's own tick box decides; with no tree yet nothing is
    # drawn and the panel says so.
    props = getattr(bpy.context.scene, "bsplab_overlay", None)
    sync_handler(bool(props and props.show))


classes = (BSPLabOverlaySettings,)

_LOAD_HANDLERS = ((bpy.app.handlers.load_pre, _before_load),
                  (bpy.app.handlers.load_post, _after_load))


def register_props():
    bpy.types.Scene.bsplab_overlay = bpy.props.PointerProperty(type=BSPLabOverlaySettings)
    for handlers, function in _LOAD_HANDLERS:
        if function not in handlers:
            handlers.append(function)


def unregister_props():
    for handlers, function in _LOAD_HANDLERS:
        if function in handlers:
            handlers.remove(function)
    sync_handler(False)
    forget()
    del bpy.types.Scene.bsplab_overlay

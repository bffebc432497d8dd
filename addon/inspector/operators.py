# SPDX-License-Identifier: GPL-3.0-or-later
"""The ray inspector's operators: trace one ray with the kept tree and show
its walk (panel: panel.py; viewport: draw.py). The tree is the one the
last Build & Render's preview shows (`STATE.shown_build`, jobs/shown_build.py).

- `bsplab.inspect_pixel(x=, y=)`: the ray of a preview pixel (x from the
  left, y from the bottom row, as Blender counts image pixels); invoked in
  an Image Editor showing the preview, the pixel under the mouse.
- `bsplab.inspect_ray(origin=, direction=)`: any ray; invoked in a 3D
  Viewport, the view's ray through the mouse.
- `bsplab.inspect_pick`: the panel's eyedropper, a modal operator that
  waits for one click in either editor.
- `bsplab.inspect_clear`: forget the inspection.
"""

import math
import time
import traceback

import bpy
from bpy.props import FloatVectorProperty, IntProperty

from .. import backend
from ..compare import images as compare_images
from ..jobs import preview, shown_build
from ..jobs.scene_reader import make_camera
from ..jobs.worker import UserError
from ..sidebar import tag_redraw_viewports
from ..state import STATE
from . import trace, walk_arrays

PICK_HINT = ("BSP Lab: click a pixel of the preview (Image Editor) or a point in the "
             "3D Viewport; Esc or right-click cancels")


# -----------------------------------------------------------------------------
# Checks and tracing (main thread)


def kept_build(context):
    """The last Build & Render and its tree; UserError when there is none."""
    build = STATE.shown_build
    if build is None:
        raise UserError("No tree to inspect yet: press Build & Render first")
    tree = build.tree()
    if tree is None:
        raise UserError("The tree of the last Build & Render is no longer kept (a later build "
                        "replaced it or was cancelled): press Build & Render again")
    if build.scene_name != context.scene.name:
        raise UserError("The last Build & Render was of scene '{}', not of '{}': press Build & "
                        "Render in this scene first".format(build.scene_name, context.scene.name))
    return build, tree


def check_fresh(context, build):
    """UserError if the scene changed since `build`."""
    if shown_build.is_stale(build, context.view_layer):
        raise UserError("The scene changed since the last Build & Render: press Build & Render "
                        "again to inspect the scene as it is now")


def kept_tree(context):
    """kept_build(), checked to be of the scene as it is now."""
    build, tree = kept_build(context)
    check_fresh(context, build)
    return build, tree


def _inspect_flat(build, tree, origin, direction, source):
    inspection = trace.inspect(tree, origin, direction, build.cull, source)
    return inspection, walk_arrays.draw_data(tree, build.triangles, inspection)


def _inspect_two_level(_build, tree, origin, direction, source):
    # Both levels' walk (InstancedTree.trace_path); no culling in two levels.
    inspection = trace.inspect_two_level(tree, origin, direction, source,
                                         shown_build.names_of(tree))
    return inspection, walk_arrays.two_level_draw_data(tree, inspection)


# The walk and what the viewport draws of it, by the tree's kind (tree.structure).
INSPECTIONS = {"bsp": _inspect_flat, "bvh": _inspect_flat, "two_level": _inspect_two_level}


def run_inspection(context, build, tree, origin, direction, source, start):
    """Trace, keep the result and its drawing; return the inspection."""
    inspection, data = INSPECTIONS[tree.structure](build, tree, origin, direction, source)
    inspection["draw"] = data
    # Click to panel ready: what the panel shows and time_inspector.py prints.
    inspection["seconds"] = time.perf_counter() - start
    STATE.inspection = inspection
    tag_redraw_viewports(context)
    return inspection


def inspect_preview_pixel(context, x, y, start=None):
    """Inspect the ray of preview image pixel (x, y) (y from the bottom)."""
    start = time.perf_counter() if start is None else start
    build, tree = kept_build(context)
    image = bpy.data.images.get(preview.IMAGE_NAME)
    if image is None:
        raise UserError("The image '{}' is gone: press Build & Render again".format(
            preview.IMAGE_NAME))
    if tuple(image.size) != build.image_size:
        raise UserError("The image '{}' is no longer the last Build & Render's preview ({} x {} "
                        "pixels, the build's was {} x {}): press Build & Render again".format(
                            preview.IMAGE_NAME, *image.size, *build.image_size))
    check_fresh(context, build)
    column, row = trace.render_pixel(x, y, build.image_size, build.render_size)
    source = "pixel ({}, {})".format(x, y)
    if build.split_b_ref is not None:
        tree, side = split_side(build, tree, x, y, column)
        source += ", tree " + side
    cam = make_camera(backend.import_bsplab(), build.camera)
    origin, direction = trace.pixel_ray(cam, *build.render_size, column, row)
    return run_inspection(context, build, tree, origin, direction, source, start)


def split_side(build, tree_a, x, y, column):
    """(tree, "A" or "B") shown at render column `column` of a split A/B
    preview; UserError on the line between them."""
    start, stop = compare_images.split_columns(build.render_size[0])
    if start <= column < stop:
        raise UserError("Pixel ({}, {}) is on the line between A and B: pick left of it for "
                        "tree A, right of it for tree B".format(x, y))
    if column < compare_images.split_column(build.render_size[0]):
        return tree_a, "A"
    tree_b = build.split_b()
    if tree_b is None:
        raise UserError("Tree B of the last Build & Render is no longer kept: press Build & "
                        "Render again")
    return tree_b, "B"


def inspect_any_ray(context, origin, direction, source, start=None):
    start = time.perf_counter() if start is None else start
    build, tree = kept_tree(context)
    if not all(math.isfinite(c) for c in (*origin, *direction)):
        raise UserError("The ray's origin and direction must be finite numbers")
    if not any(direction):
        raise UserError("The ray's direction must not be (0, 0, 0)")
    return run_inspection(context, build, tree, origin, direction, source, start)


def image_editor_pixel(space, region, region_x, region_y):
    """The preview pixel (x, y from the bottom) under a point of an Image
    Editor's main region; UserError if the editor shows another image."""
    image = space.image
    if image is None or image.name != preview.IMAGE_NAME:
        raise UserError("This Image Editor does not show the '{}' image: show it there (Build "
                        "& Render does in every unpinned editor) and pick again".format(
                            preview.IMAGE_NAME))
    # The Image Editor's view space spans the image over 0..1 on both axes.
    u, v = region.view2d.region_to_view(region_x, region_y)
    width, height = image.size
    return math.floor(u * width), math.floor(v * height)


def viewport_ray(region, region_x, region_y):
    """(origin, direction) of the 3D view's ray through a point of its region."""
    from bpy_extras import view3d_utils
    rv3d = region.data
    point = (region_x, region_y)
    origin = view3d_utils.region_2d_to_origin_3d(region, rv3d, point)
    direction = view3d_utils.region_2d_to_vector_3d(region, rv3d, point)
    return tuple(origin), tuple(direction)


def report_inspection(operator, inspection):
    totals = inspection["counts"]
    if inspection["missed_box"]:
        operator.report({'WARNING'}, "BSP Lab: the {} missed the tree box".format(
            "ray of " + inspection["source"] if "pixel" in inspection["source"] else "ray"))
        return
    hit = ("hit triangle {} at t = {:.4g}".format(totals["hit_prim"], totals["hit_t"])
           if totals["hit_prim"] is not None else "no hit")
    operator.report({'INFO'}, "BSP Lab ray: {} steps, {} tests, {}".format(
        totals["steps"], totals["tests"], hit))


def perform(operator, inspect, *args):
    """Call inspect(*args), report its answer or why it failed; return the
    operator's result. An unexpected failure is reported too (with the
    traceback in the console), never raised into Blender."""
    try:
        inspection = inspect(*args)
    except UserError as ex:
        operator.report({'ERROR'}, str(ex))
        return {'CANCELLED'}
    except Exception as ex:
        traceback.print_exc()
        operator.report({'ERROR'}, "BSP Lab ray inspector failed: {}: {}".format(
            type(ex).__name__, ex))
        return {'CANCELLED'}
    report_inspection(operator, inspection)
    return {'FINISHED'}


class InspectOperator:
    bl_options = {'REGISTER'}

    def run(self, context, inspect, *args):
        """perform() inspect(context, *args)."""
        return perform(self, inspect, context, *args)


class BSPLAB_OT_inspect_pixel(InspectOperator, bpy.types.Operator):
    """Trace the ray of one preview pixel with the kept tree and show its walk"""

    bl_idname = "bsplab.inspect_pixel"
    bl_label = "Inspect Preview Pixel"

    x: IntProperty(name="X", description="Pixel column of the preview image, from the left")
    y: IntProperty(name="Y", description="Pixel row of the preview image, from the bottom "
                                         "(Blender's image convention)")

    def execute(self, context):
        return self.run(context, inspect_preview_pixel, self.x, self.y)

    def invoke(self, context, event):
        area, region = context.area, context.region
        if area is not None and area.type == 'IMAGE_EDITOR' and region.type == 'WINDOW':
            try:
                self.x, self.y = image_editor_pixel(area.spaces.active, region,
                                                    event.mouse_region_x, event.mouse_region_y)
            except UserError as ex:
                self.report({'ERROR'}, str(ex))
                return {'CANCELLED'}
        return self.execute(context)


class BSPLAB_OT_inspect_ray(InspectOperator, bpy.types.Operator):
    """Trace one ray with the kept tree and show its walk"""

    bl_idname = "bsplab.inspect_ray"
    bl_label = "Inspect Ray"

    origin: FloatVectorProperty(name="Origin", size=3, subtype='XYZ')
    direction: FloatVectorProperty(name="Direction", size=3, default=(0.0, 0.0, -1.0),
                                   subtype='XYZ')

    def execute(self, context):
        return self.run(context, inspect_any_ray, tuple(self.origin), tuple(self.direction),
                        "ray")

    def invoke(self, context, event):
        area, region = context.area, context.region
        if area is not None and area.type == 'VIEW_3D' and region.type == 'WINDOW':
            self.origin, self.direction = viewport_ray(region, event.mouse_region_x,
                                                       event.mouse_region_y)
        return self.execute(context)


def region_under(window, x, y):
    """(area, region) of the editor's main region under window point (x, y),
    or (area, None) on its header, toolbar or sidebar, or (None, None)."""
    for area in window.screen.areas:
        if not (area.x <= x < area.x + area.width and area.y <= y < area.y + area.height):
            continue
        # The sidebar and toolbar may overlap the main region: they win.
        inside = [r for r in area.regions
                  if r.x <= x < r.x + r.width and r.y <= y < r.y + r.height]
        main = [r for r in inside if r.type == 'WINDOW']
        return area, (main[0] if main and len(inside) == 1 else None)
    return None, None


class BSPLAB_OT_inspect_pick(bpy.types.Operator):
    """Click a pixel of the preview or a point in the 3D Viewport: trace that ray with the kept tree and show its walk"""

    bl_idname = "bsplab.inspect_pick"
    bl_label = "Inspect a Ray"
    bl_options = {'REGISTER'}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            self.report({'ERROR'}, "Picking needs a window: call bsplab.inspect_pixel(x=, y=) "
                                   "or bsplab.inspect_ray(origin=, direction=) instead")
            return {'CANCELLED'}
        try:
            kept_tree(context)  # say now, not after the click, that there is nothing to pick
        except UserError as ex:
            self.report({'ERROR'}, str(ex))
            return {'CANCELLED'}
        context.window.cursor_modal_set('EYEDROPPER')
        context.workspace.status_text_set(PICK_HINT)
        context.window_manager.modal_handler_add(self)
        return {'RUNNING_MODAL'}

    def execute(self, context):
        return self.invoke(context, None)

    def modal(self, context, event):
        if event.type in {'ESC', 'RIGHTMOUSE'} and event.value == 'PRESS':
            self._end(context)
            return {'CANCELLED'}
        if event.type != 'LEFTMOUSE' or event.value != 'PRESS':
            return {'PASS_THROUGH'}  # navigating the view while picking is fine
        start = time.perf_counter()
        self._end(context)
        return perform(self, self._pick, context, event, start)

    def _pick(self, context, event, start):
        area, region = region_under(context.window, event.mouse_x, event.mouse_y)
        if region is not None:
            rx, ry = event.mouse_x - region.x, event.mouse_y - region.y
            if area.type == 'IMAGE_EDITOR':
                x, y = image_editor_pixel(area.spaces.active, region, rx, ry)
                return inspect_preview_pixel(context, x, y, start)
            if area.type == 'VIEW_3D':
                origin, direction = viewport_ray(region, rx, ry)
                return inspect_any_ray(context, origin, direction, "viewport", start)
        raise UserError("Pick in an Image Editor showing the preview or in a 3D Viewport's "
                        "view, not on {}".format(
                            "a panel or header" if area is not None else "the window's edge"))

    def _end(self, context):
        context.window.cursor_modal_restore()
        context.workspace.status_text_set(None)


class BSPLAB_OT_inspect_clear(bpy.types.Operator):
    """Remove the inspected ray from the viewport and the panel"""

    bl_idname = "bsplab.inspect_clear"
    bl_label = "Clear"
    bl_options = {'REGISTER'}

    def execute(self, context):
        STATE.inspection = None
        tag_redraw_viewports(context)
        return {'FINISHED'}


classes = (
    BSPLAB_OT_inspect_pixel,
    BSPLAB_OT_inspect_ray,
    BSPLAB_OT_inspect_pick,
    BSPLAB_OT_inspect_clear,
)

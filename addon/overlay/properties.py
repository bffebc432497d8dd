# SPDX-License-Identifier: GPL-3.0-or-later
"""The overlay's settings (`Scene.bsplab_overlay`, the panel's "Tree
Overlay" box); geometry.settings_of() makes its cache key of them."""

import bpy

from ..sidebar import tag_redraw_viewports
from . import draw, geometry


def _show_changed(self, context):
    draw.sync_handler(self.show)
    tag_redraw_viewports(context)


def _changed(self, context):
    tag_redraw_viewports(context)


def _kind_colour(name, index):
    return bpy.props.FloatVectorProperty(
        name=name, subtype='COLOR', size=3, min=0.0, max=1.0,
        default=geometry.DEFAULT_KIND_COLOURS[index], update=_changed,
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


classes = (BSPLabOverlaySettings,)


def register_props():
    bpy.types.Scene.bsplab_overlay = bpy.props.PointerProperty(type=BSPLabOverlaySettings)


def unregister_props():
    del bpy.types.Scene.bsplab_overlay

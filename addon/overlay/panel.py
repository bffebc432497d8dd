# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Tree Overlay" sub-panel of the BSP Lab sidebar tab."""

import bpy

from ..sidebar import BSPLabFeaturePanel, draw_toggle
from . import draw as overlay_draw
from . import geometry

KIND_COLOUR_PROPS = (("colour_x", "x"), ("colour_y", "y"), ("colour_z", "z"),
                     ("colour_general", "general"))
NO_TREE_MESSAGE = "Build & Render first: the overlay draws the last built tree"
TWO_LEVEL_MESSAGE = "Not available for two-level builds yet (Instances: Flatten draws)"


class BSPLAB_PT_overlay(BSPLabFeaturePanel, bpy.types.Panel):
    bl_label = "Tree Overlay"
    TOGGLE = ("bsplab_overlay", "show")

    def draw_header(self, context):
        draw_toggle(self, context)
        overlay_draw.redraw_if_tree_changed(context)

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        props = context.scene.bsplab_overlay
        tree = overlay_draw.kept_tree()
        if overlay_draw.kept_two_level():
            layout.label(text=TWO_LEVEL_MESSAGE, icon='INFO')
        elif tree is None:
            layout.label(text=NO_TREE_MESSAGE, icon='INFO')

        col = layout.column()
        col.active = props.show
        col.prop(props, "max_depth")
        col.prop(props, "scope")
        if props.scope == "cursor":
            col.prop(props, "subtree_depth")
        if geometry.is_bvh(tree):
            # Boxes by depth: a BVH has no kinds to colour and no cells.
            col.label(text="BVH: boxes, depth 0 orange \u2192 {} blue".format(props.max_depth))
        else:
            col.prop(props, "colour_by")
            draw_legend(col, props)
            col.prop(props, "alpha")
            col.prop(props, "cells")
        col.prop(props, "cap")

        if props.show and tree is not None:
            draw_notes(layout, overlay_draw.current_geometry(context.scene))


def draw_legend(layout, props):
    """The colour key: the kind colours themselves (editable swatches), or
    the depth ramp's two ends."""
    if props.colour_by == "kind":
        row = layout.row(align=True)
        for name, text in KIND_COLOUR_PROPS:
            row.prop(props, name, text=text)
    else:
        layout.label(text="depth 0 orange \u2192 depth {} blue".format(props.max_depth))


def draw_notes(layout, geometry):
    """How much is drawn, in red when the cap cut it."""
    notes = layout.column(align=True)
    notes.alert = geometry["cut"] or geometry["cells_cut"]
    for note in geometry["notes"]:
        notes.label(text=note)


classes = (BSPLAB_PT_overlay,)

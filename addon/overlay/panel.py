# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Tree Overlay" sub-panel of the BSP Lab sidebar tab."""

from typing import NamedTuple

import bpy

from ..jobs import shown_build
from ..sidebar import BSPLabFeaturePanel, draw_toggle
from . import draw as overlay_draw

KIND_COLOUR_PROPS = (("colour_x", "x"), ("colour_y", "y"), ("colour_z", "z"),
                     ("colour_general", "general"))
NO_TREE_MESSAGE = "Build & Render first: the overlay draws the last built tree"
# A two-level build: what is drawn, said once above the settings.
TWO_LEVEL_NOTE = "Two-level: top-level boxes, and the instance under the 3D cursor in place"


class PanelKind(NamedTuple):
    """What the panel says of one kind of kept tree."""

    note: str  # said above the settings, or None
    drawn_tree: object  # tree -> the tree whose structure the settings apply to
    in_place: bool  # whether a row names the instance drawn in place


_FLAT = PanelKind(None, lambda tree: tree, False)
# The panel by the kept tree's kind (tree.structure). Of a two-level build,
# the instances' mesh trees decide (all of one method).
PANEL_KINDS = {
    "bsp": _FLAT,
    "bvh": _FLAT,
    "two_level": PanelKind(TWO_LEVEL_NOTE, lambda tree: tree.meshes[0] if tree.meshes else None,
                           True),
}


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
        kind = PANEL_KINDS[tree.structure] if tree is not None else _FLAT
        if tree is None:
            layout.label(text=NO_TREE_MESSAGE, icon='INFO')
        elif kind.note:
            layout.label(text=kind.note, icon='INFO')

        col = layout.column()
        col.active = props.show
        col.prop(props, "max_depth")
        col.prop(props, "scope")
        if props.scope == "cursor":
            col.prop(props, "subtree_depth")
        drawn_tree = kind.drawn_tree(tree) if tree is not None else None
        # Before any build, the settings of split planes.
        SETTINGS_ROWS[drawn_tree.structure if drawn_tree is not None else "bsp"](col, props)
        col.prop(props, "cap")

        if props.show and tree is not None:
            arrays = overlay_draw.current_geometry(context.scene)
            if kind.in_place:
                draw_instance(layout, arrays, shown_build.names_of(tree))
            draw_notes(layout, arrays)


def draw_instance(layout, arrays, names):
    """Which instance a two-level overlay draws in place, by name when the
    build's names are known (none under the cursor: the notes say so)."""
    if arrays.get("instance") is not None:
        layout.label(text="In place: " + shown_build.instance_text(
            arrays["instance"], arrays["mesh"], names), icon='OUTLINER_OB_GROUP_INSTANCE')


def draw_plane_settings(layout, props):
    layout.prop(props, "colour_by")
    draw_legend(layout, props)
    layout.prop(props, "alpha")
    layout.prop(props, "cells")


def draw_box_settings(layout, props):
    # Boxes by depth: a BVH has no kinds to colour and no cells.
    layout.label(text="BVH: boxes, depth 0 orange \u2192 {} blue".format(props.max_depth))


# The settings that apply, by the drawn tree's structure.
SETTINGS_ROWS = {"bsp": draw_plane_settings, "bvh": draw_box_settings}


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

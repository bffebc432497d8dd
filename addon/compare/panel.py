# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Compare A/B" sub-panel: tree B's method, its options and the view.
(The A/B grid of the statistics is drawn by the Statistics panel, build_render/panel.py.)"""

import bpy

from .. import tree_options
from ..sidebar import BSPLabFeaturePanel, draw_options


class BSPLAB_PT_compare(BSPLabFeaturePanel, bpy.types.Panel):
    """Tree B of the A/B comparison: its method, its options and the view."""

    bl_label = "Compare A/B"
    TOGGLE = ("bsplab_compare", "enabled")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        compare = context.scene.bsplab_compare
        layout.active = compare.enabled
        layout.prop(compare, "method", text="B")
        draw_options(layout, compare, compare.method, tree_options.TREE_OPTIONS)
        layout.prop(compare, "view")


classes = (BSPLAB_PT_compare,)

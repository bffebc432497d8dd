# SPDX-License-Identifier: GPL-3.0-or-later
"""Tree B's settings (`Scene.bsplab_compare`): a method and its options,
offered from the same method table and option registry as A's, and the
view of the A/B preview (images.VIEWS)."""

import bpy
from bpy.props import BoolProperty, EnumProperty

from .. import tree_options

VIEW_ITEMS = (
    ('split', "Split", "A's image left, B's right, a magenta line between"),
    ('diff_steps', "Steps B - A",
     "Per pixel B's traversal steps minus A's: blue where B steps less, red where more, "
     "white where equal"),
    ('diff_tests', "Tests B - A",
     "Per pixel B's triangle tests minus A's: blue where B tests less, red where more, "
     "white where equal"),
    ('diff_box_tests', "Box Tests B - A",
     "Per pixel B's ray-box tests minus A's (a BVH's counter; a kd or BSP tree makes none): "
     "blue where B tests less, red where more, white where equal"),
)


class BSPLabCompareSettings(bpy.types.PropertyGroup):
    """Tree B of the A/B comparison: Build & Render reads it (build_render/scene_input.py)."""

    enabled: BoolProperty(
        name="Compare with B",
        description="Build & Render also builds and renders tree B (same camera, mode, threads "
                    "and culling) and shows A and B side by side or their difference",
        default=False,
    )
    method: tree_options.method_property(
        "Tree B's construction method (from the core's method table)")
    view: EnumProperty(
        name="View",
        description="What the A/B preview shows",
        items=VIEW_ITEMS,
        default='split',
    )

    def build_options(self, params):
        """B's keyword options for `bsplab.build`, without the thread count."""
        return tree_options.build_options(self, tree_options.TREE_OPTIONS, params)


tree_options.add_option_properties(BSPLabCompareSettings, tree_options.TREE_OPTIONS)

classes = (BSPLabCompareSettings,)


def register_props():
    bpy.types.Scene.bsplab_compare = bpy.props.PointerProperty(type=BSPLabCompareSettings)


def unregister_props():
    del bpy.types.Scene.bsplab_compare

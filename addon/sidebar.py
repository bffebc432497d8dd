# SPDX-License-Identifier: GPL-3.0-or-later
"""The "BSP Lab" tab of the 3D Viewport's sidebar (N panel): what every
feature's panel shares, and the redraws the features ask for.

A feature's panel is a sub-panel of the main one (build_render/panel.py):
`class BSPLAB_PT_<name>(BSPLabSubPanel, bpy.types.Panel)`. Its place is
its `bl_order` (SUB_PANEL_ORDER): Blender sorts a parent's sub-panels by
it, whatever order the features register them in.
"""

from . import backend
from .tree_options import SHORT_LABELS

MAIN_PANEL = "BSPLAB_PT_main"
# The sub-panels of the main panel, top to bottom.
SUB_PANEL_ORDER = (
    "BSPLAB_PT_compare",
    "BSPLAB_PT_stats",
    "BSPLAB_PT_sweep",
    "BSPLAB_PT_inspector",
    "BSPLAB_PT_overlay",
)


def sub_panel_order(idname):
    """The `bl_order` of a sub-panel of the main panel: its place in
    SUB_PANEL_ORDER, or after them all when it is not listed (a new
    feature's panel goes last, in the order the features register)."""
    if idname in SUB_PANEL_ORDER:
        return SUB_PANEL_ORDER.index(idname) + 1
    return len(SUB_PANEL_ORDER) + 1


class BSPLabPanel:
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "BSP Lab"


class BSPLabSubPanel(BSPLabPanel):
    """A sub-panel of the main panel, in its place (sub_panel_order). Its
    `bl_idname` is its class name (BSPLAB_PT_<name>), as Blender asks."""

    bl_parent_id = MAIN_PANEL

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        cls.bl_idname = cls.__name__
        cls.bl_order = sub_panel_order(cls.bl_idname)


class BSPLabFeaturePanel(BSPLabSubPanel):
    """A sub-panel closed at first whose header's tick box turns its feature
    on and off: TOGGLE is (the Scene's property group, its boolean)."""

    bl_options = {'DEFAULT_CLOSED'}
    TOGGLE = ("", "")

    def draw_header(self, context):
        draw_toggle(self, context)


def draw_toggle(panel, context):
    """The feature's tick box in `panel`'s header, without a label (the
    panel's title is its label)."""
    group, name = panel.TOGGLE
    panel.layout.prop(getattr(context.scene, group), name, text="")


def draw_options(layout, settings, method, names):
    """The method's build options among `names`, with the registry's short labels."""
    params = backend.methods().get(method, {}).get("params", ())
    col = layout.column(align=True)
    for name in names:
        if name in params:
            col.prop(settings, name, text=SHORT_LABELS[name])


def _areas(context, area_type):
    wm = context.window_manager
    for window in (wm.windows if wm is not None else ()):
        for area in window.screen.areas:
            if area.type == area_type:
                yield area


def tag_redraw_sidebars(context):
    """Only the 3D views' sidebars: redrawing whole 3D views ten times a
    second would cost heavy scenes more than the job itself."""
    for area in _areas(context, 'VIEW_3D'):
        for region in area.regions:
            if region.type == 'UI':
                region.tag_redraw()


def tag_redraw_viewports(context):
    """The 3D views, their drawing and their sidebars."""
    for area in _areas(context, 'VIEW_3D'):
        area.tag_redraw()

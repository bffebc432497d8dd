# SPDX-License-Identifier: GPL-3.0-or-later
"""Scene settings of BSP Lab: `bpy.types.Scene.bsplab`."""

import json

import bpy
from bpy.props import (
    BoolProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    StringProperty,
)

from . import backend

# Blender keeps only a borrowed pointer to the strings of dynamic enum items:
# the lists returned by the callbacks must stay referenced from Python or the
# UI shows garbage (documented for `EnumProperty(items=callback)`).
_method_items = []
_mode_items = []

# Options the panel leaves at the core's defaults: a build that needs more
# than the default memory limit is no preview.
HIDDEN_OPTIONS = ("memory_limit_mb",)

# A Blender property's limit for an open lower limit (a cost "> 0"): the
# smallest step the panel's fields show.
OPEN_MIN_STEP = 0.001

# IntProperty is 32-bit.
INT_PROPERTY_MAX = 2**31 - 1


def _panel_order(schema):
    """The BSP family's options first (what differs between methods), then
    the common ones, each group in the core's order."""
    names = [name for name in schema if name not in HIDDEN_OPTIONS]
    return tuple(sorted(names, key=lambda name: schema[name]["group"] != "bsp"))


def _limits(spec):
    """Blender's min/max/soft_max keywords for one option's schema. (K's are
    the widest over the methods; the operator checks the chosen method's.)"""
    out = {}
    if spec["min"] is not None:
        out["min"] = spec["min"] + (OPEN_MIN_STEP if spec["min_open"] else 0)
    if spec["max"] is not None:
        out["max"] = spec["max"]
    if spec["soft_max"] is not None:
        out["soft_max"] = spec["soft_max"]
    if spec["type"] == "int":
        out = {key: int(min(value, INT_PROPERTY_MAX)) for key, value in out.items()}
    return out


def option_property(spec):
    """The bpy property of one build option: its name, help text, default
    and limits all from the core's registry (`bsplab.method_table.OPTIONS`)."""
    common = {"name": spec["label"], "description": spec["help"]}
    if spec["type"] == "enum":
        items = tuple((c["name"], c["label"], c["help"]) for c in spec["choices"])
        return EnumProperty(items=items, default=spec["default"], **common)
    if spec["type"] == "int":
        return IntProperty(default=spec["default"], **common, **_limits(spec))
    return FloatProperty(default=spec["default"], **common, **_limits(spec))


# The build options the panel can edit, in the panel's order; empty when the
# core is missing (nothing can be built then). A method's `params` in
# `bsplab.methods()` says which apply to it.
OPTION_SCHEMA = backend.option_schema()
BUILD_OPTIONS = _panel_order(OPTION_SCHEMA)
SWEEP_K_MAX = OPTION_SCHEMA["k"]["max"] if "k" in OPTION_SCHEMA else INT_PROPERTY_MAX


def _method_enum_items(_self, _context):
    global _method_items
    items = [
        (name, info.get("label", name), info.get("description", ""))
        for name, info in backend.methods().items()
    ]
    # Keep the list Blender already points to while it is unchanged: A's and
    # B's method enums share it, and replacing it under one would free the
    # strings the other shows.
    if items != _method_items:
        _method_items = items
    return _method_items


def _mode_enum_items(_self, _context):
    global _mode_items
    _mode_items = [
        (mode, mode.replace("_", " ").title(), "Render mode '{}' of the core".format(mode))
        for mode in backend.render_modes()
    ]
    return _mode_items


def _method_changed(self, _context):
    """Load the new method's own defaults (K differs between methods)."""
    info = backend.methods().get(self.method, {})
    for name, value in info.get("defaults", {}).items():
        if name in BUILD_OPTIONS and hasattr(self, name):
            try:
                setattr(self, name, value)
            except (TypeError, ValueError):
                pass  # A default the property cannot hold: keep the current value.


class BSPLabSettings(bpy.types.PropertyGroup):
    method: EnumProperty(
        name="Method",
        description="Tree construction method (from the core's method table)",
        items=_method_enum_items,
        update=_method_changed,
    )
    preview_percentage: IntProperty(
        name="Preview Resolution",
        description="Preview size as a percentage of the scene's render resolution",
        default=50, min=1, max=100, subtype='PERCENTAGE',
    )
    cull: BoolProperty(
        name="Leaf Culling",
        description="In each leaf, skip the triangles whose box misses the box of the "
                    "ray's segment there (needs leaf boxes; always on for Heat Culled)",
        default=False,
    )
    count_steps: BoolProperty(
        name="Count Steps & Tests",
        description="Count every ray's node steps and triangle tests for the statistics. "
                    "Off, the shaded, normal and depth modes trace in ray packets (faster; "
                    "the same image) and the panel shows no counts. The heat maps always count",
        default=True,
    )
    render_mode: EnumProperty(
        name="Mode",
        description="What the preview shows",
        items=_mode_enum_items,
    )
    compare_with_embree: BoolProperty(
        name="Compare with Embree",
        description="Trace the same camera rays with Embree and compare hits and time",
        default=False,
    )

    # The result, written by the operator only. JSON keeps the nested
    # statistics of the core as they are, whatever keys they have.
    stats_json: StringProperty(
        name="Statistics",
        description="Statistics of the last Build & Render, as JSON",
        default="",
    )

    # Sweep K: the experiment on this scene (see sweep.py).
    sweep_methods: StringProperty(
        name="Methods",
        description="Methods to sweep, separated by spaces (kd is always added as the "
                    "reference)",
        default="bsp_wn+kd bsp_cn+kd",
    )
    sweep_k_min: IntProperty(
        name="K From", description="Smallest K of the sweep", default=3, min=1, max=SWEEP_K_MAX,
    )
    sweep_k_max: IntProperty(
        name="K To", description="Largest K of the sweep", default=8, min=1, max=SWEEP_K_MAX,
    )
    sweep_repetitions: IntProperty(
        name="Repetitions",
        description="Traces per tree; the table shows their median (and min-max)",
        default=3, min=1, max=50,
    )
    sweep_workload: EnumProperty(
        name="Rays",
        description="The rays each tree traces",
        items=(
            ('primary', "Camera", "Primary rays of the scene camera at the preview size"),
            ('ao', "Ambient Occlusion", "One short cosine-weighted ray from each camera hit"),
            ('diffuse', "Diffuse Bounce", "One full-length cosine-weighted ray from each hit"),
        ),
        default='primary',
    )
    sweep_json: StringProperty(
        name="Sweep Results",
        description="The last Sweep K's table, as JSON",
        default="",
    )

    @property
    def sweep(self):
        """The last Sweep K's table as a dict (empty before the first sweep)."""
        try:
            return json.loads(self.sweep_json) if self.sweep_json else {}
        except ValueError:
            return {}

    @property
    def stats(self):
        """The last run's statistics as a dict (empty before the first run)."""
        if not self.stats_json:
            return {}
        try:
            return json.loads(self.stats_json)
        except ValueError:
            return {}

    def build_options(self, params):
        """Keyword options for `bsplab.build` limited to the method's params."""
        return _build_options(self, BUILD_OPTIONS, params)


def _build_options(settings, names, params):
    return {name: getattr(settings, name) for name in names if name in params}


# The build options but the thread count, which changes no tree: the panel
# draws A's threads with the render settings, and B is built with A's.
TREE_OPTIONS = tuple(name for name in BUILD_OPTIONS if name != "threads")

COMPARE_VIEWS = (
    ('split', "Split", "A's image left, B's right, a magenta line between"),
    ('diff_steps', "Steps B - A",
     "Per pixel B's traversal steps minus A's: blue where B steps less, red where more, "
     "white where equal"),
    ('diff_tests', "Tests B - A",
     "Per pixel B's triangle tests minus A's: blue where B tests less, red where more, "
     "white where equal"),
)


class BSPLabCompareSettings(bpy.types.PropertyGroup):
    """Tree B of the A/B comparison (`Scene.bsplab_compare`): a method and its
    options, offered from the same method table and option registry as A's."""

    enabled: BoolProperty(
        name="Compare with B",
        description="Build & Render also builds and renders tree B (same camera, mode, threads "
                    "and culling) and shows A and B side by side or their difference",
        default=False,
    )
    method: EnumProperty(
        name="Method",
        description="Tree B's construction method (from the core's method table)",
        items=_method_enum_items,
        update=_method_changed,
    )
    view: EnumProperty(
        name="View",
        description="What the A/B preview shows",
        items=COMPARE_VIEWS,
        default='split',
    )

    def build_options(self, params):
        """B's keyword options for `bsplab.build`, without the thread count."""
        return _build_options(self, TREE_OPTIONS, params)


class BSPLabJobState(bpy.types.PropertyGroup):
    """State of the running job. On the window manager, not the scene:
    it is runtime state, and updating it must not touch scene data."""

    is_running: BoolProperty(name="Running", default=False)
    progress: FloatProperty(
        name="Progress", default=0.0, min=0.0, max=1.0, subtype='FACTOR',
    )


def _add_option_properties(cls, names):
    """The build options' properties, added before the class is registered."""
    for name in names:
        cls.__annotations__[name] = option_property(OPTION_SCHEMA[name])


_add_option_properties(BSPLabSettings, BUILD_OPTIONS)
_add_option_properties(BSPLabCompareSettings, TREE_OPTIONS)

classes = (
    BSPLabSettings,
    BSPLabCompareSettings,
    BSPLabJobState,
)


def register_props():
    bpy.types.Scene.bsplab = bpy.props.PointerProperty(type=BSPLabSettings)
    bpy.types.Scene.bsplab_compare = bpy.props.PointerProperty(type=BSPLabCompareSettings)
    bpy.types.WindowManager.bsplab_job = bpy.props.PointerProperty(type=BSPLabJobState)


def unregister_props():
    del bpy.types.WindowManager.bsplab_job
    del bpy.types.Scene.bsplab_compare
    del bpy.types.Scene.bsplab

# SPDX-License-Identifier: GPL-3.0-or-later
"""Build & Render's settings (`Scene.bsplab`), the K sweep's included
(k_sweep/: saved files have them here)."""

import json

import bpy
from bpy.props import (
    BoolProperty,
    EnumProperty,
    IntProperty,
    StringProperty,
)

from .. import backend, tree_options
from ..state import STATE


def _mode_enum_items(_self, _context):
    STATE.enum_items["mode"] = [
        (mode, mode.replace("_", " ").title(), "Render mode '{}' of the core".format(mode))
        for mode in backend.render_modes()
    ]
    return STATE.enum_items["mode"]


class BSPLabSettings(bpy.types.PropertyGroup):
    method: tree_options.method_property(
        "Tree construction method (from the core's method table)")
    instances: EnumProperty(
        name="Instances",
        description="How objects that share a mesh (linked duplicates, collection and "
                    "geometry-node instances) are built",
        items=(
            ('two_level', "Two-level",
             "One tree per unique mesh, shared by all its instances, and a BVH over the "
             "instances: less memory, and a press after moving an instance rebuilds only "
             "the BVH"),
            ('flatten', "Flatten",
             "Every instance's triangles copied into world space, one tree over them all"),
        ),
        default='two_level',
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
    # statistics of bsplab as they are, whatever keys they have.
    stats_json: StringProperty(
        name="Statistics",
        description="Statistics of the last Build & Render, as JSON",
        default="",
    )

    # The K sweep's settings and table (k_sweep/). They stay on
    # Scene.bsplab, where saved files and scripts have them
    # (`scene.bsplab.sweep_k_min`): a group of their own would lose them.
    sweep_methods: StringProperty(
        name="Methods",
        description="Methods to sweep, separated by spaces (kd is always added as the "
                    "reference)",
        default="bsp_wn+kd bsp_cn+kd",
    )
    sweep_k_min: IntProperty(
        name="K From", description="Smallest K of the sweep", default=3, min=1,
        max=tree_options.K_MAX,
    )
    sweep_k_max: IntProperty(
        name="K To", description="Largest K of the sweep", default=8, min=1,
        max=tree_options.K_MAX,
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
    def k_sweep_table(self):
        """The last Sweep K's table as a dict (empty before the first sweep)."""
        return _json_or_empty(self.sweep_json)

    @property
    def stats(self):
        """The last run's statistics as a dict (empty before the first run)."""
        return _json_or_empty(self.stats_json)

    def build_options(self, params):
        """Keyword options for `bsplab.build` limited to the method's params."""
        return tree_options.build_options(self, tree_options.BUILD_OPTIONS, params)


def _json_or_empty(text):
    if not text:
        return {}
    try:
        return json.loads(text)
    except ValueError:
        return {}


tree_options.add_option_properties(BSPLabSettings, tree_options.BUILD_OPTIONS)

classes = (BSPLabSettings,)


def register_props():
    bpy.types.Scene.bsplab = bpy.props.PointerProperty(type=BSPLabSettings)


def unregister_props():
    del bpy.types.Scene.bsplab

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

# Build options the panel can edit, in the panel's order. A method's `params`
# in `bsplab.methods()` says which apply to it; options the add-on does not
# know keep the core's defaults.
BUILD_OPTIONS = (
    "k",
    "seed",
    "rbsp_set",
    "cluster_iterations",
    "cluster_sample",
    "ize_candidates",
    "traversal_cost",
    "intersect_cost",
    "empty_bonus",
    "alpha",
    "general_cost",
    "max_depth",
    "leaf_size",
    "max_duplication",
    "leaf_boxes",
    "threads",
)


def _method_enum_items(_self, _context):
    global _method_items
    _method_items = [
        (name, info.get("label", name), info.get("description", ""))
        for name, info in backend.methods().items()
    ]
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
    k: IntProperty(
        name="K",
        description="Number of split directions tried per node",
        default=6, min=1, max=64,
    )
    seed: IntProperty(
        name="Seed",
        description="Seed of the random choices of randomised methods",
        default=1, min=0,
    )
    rbsp_set: EnumProperty(
        name="Directions",
        description="The fixed direction set of RBSP",
        items=(
            ('auto', "Auto", "k-DOP directions for K = 3, 7, 9, 13, else the axes plus a golden spiral"),
            ('spiral', "Spiral", "K directions on a golden spiral"),
            ('dop', "k-DOP", "The k-DOP directions (K = 3, 7, 9 or 13)"),
        ),
        default='auto',
    )
    cluster_iterations: IntProperty(
        name="Cluster Iterations",
        description="k-means iterations for clustering the node's normals",
        default=16, min=1, max=500,
    )
    cluster_sample: IntProperty(
        name="Cluster Sample",
        description="Normals sampled per node for the clustering",
        default=1024, min=1, soft_max=65536,
    )
    ize_candidates: IntProperty(
        name="IZE Candidates",
        description="Triangle planes tried per node",
        default=256, min=1, soft_max=4096,
    )
    traversal_cost: FloatProperty(
        name="Traversal Cost",
        description="SAH cost of visiting one interior node",
        default=1.0, min=0.001, soft_max=10.0,
    )
    intersect_cost: FloatProperty(
        name="Intersection Cost",
        description="SAH cost of one ray-triangle test",
        default=1.5, min=0.001, soft_max=10.0,
    )
    empty_bonus: FloatProperty(
        name="Empty Bonus",
        description="SAH discount for splits that cut off empty space",
        default=0.2, min=0.0, max=0.99,
    )
    alpha: FloatProperty(
        name="Alpha",
        description="Per-triangle factor of a general (non-axis) node's traversal cost",
        default=0.1, min=0.0, soft_max=1.0,
    )
    general_cost: FloatProperty(
        name="General Cost",
        description="Traversal cost of a general (non-axis) node",
        default=2.0, min=0.001, soft_max=10.0,
    )
    max_depth: IntProperty(
        name="Max Depth",
        description="Maximum tree depth (0: automatic, 8 + 1.3 log2 N)",
        default=0, min=0, max=64,
    )
    leaf_size: IntProperty(
        name="Leaf Size",
        description="Stop splitting nodes with at most this many triangles",
        default=1, min=1, soft_max=64,
    )
    max_duplication: FloatProperty(
        name="Max Duplication",
        description="Stop splitting when triangle references exceed this multiple of the triangles",
        default=8.0, min=1.0, soft_max=32.0,
    )
    preview_percentage: IntProperty(
        name="Preview Resolution",
        description="Preview size as a percentage of the scene's render resolution",
        default=50, min=1, max=100, subtype='PERCENTAGE',
    )
    leaf_boxes: EnumProperty(
        name="Leaf Boxes",
        description="Boxes kept for leaf culling with the ray segment's box",
        items=(
            ('triangle', "Triangle", "Each triangle's own box (24 bytes per triangle)"),
            ('clipped', "Clipped", "Each reference's box clipped to its leaf cell "
                                   "(24 bytes per reference; culls more)"),
            ('none', "None", "No boxes: leaf culling is not possible"),
        ),
        default='triangle',
    )
    cull: BoolProperty(
        name="Leaf Culling",
        description="In each leaf, skip the triangles whose box misses the box of the "
                    "ray's segment there (needs leaf boxes; always on for Heat Culled)",
        default=False,
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
    threads: IntProperty(
        name="Threads",
        description="Worker threads of the core (0: all cores)",
        default=0, min=0, soft_max=64,
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
        name="K From", description="Smallest K of the sweep", default=3, min=1, max=64,
    )
    sweep_k_max: IntProperty(
        name="K To", description="Largest K of the sweep", default=8, min=1, max=64,
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
        return {name: getattr(self, name) for name in BUILD_OPTIONS if name in params}


class BSPLabJobState(bpy.types.PropertyGroup):
    """State of the running job. On the window manager, not the scene:
    it is runtime state, and updating it must not touch scene data."""

    is_running: BoolProperty(name="Running", default=False)
    progress: FloatProperty(
        name="Progress", default=0.0, min=0.0, max=1.0, subtype='FACTOR',
    )


classes = (
    BSPLabSettings,
    BSPLabJobState,
)


def register_props():
    bpy.types.Scene.bsplab = bpy.props.PointerProperty(type=BSPLabSettings)
    bpy.types.WindowManager.bsplab_job = bpy.props.PointerProperty(type=BSPLabJobState)


def unregister_props():
    del bpy.types.WindowManager.bsplab_job
    del bpy.types.Scene.bsplab

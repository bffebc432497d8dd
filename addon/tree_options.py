# SPDX-License-Identifier: GPL-3.0-or-later
"""The registry's methods and build options as Blender properties, for the
settings of tree A (build_render/properties.py) and tree B (compare/properties.py).

Every option's name, help text, default and limits come from the registry
(`bsplab.option_schema()`); none is retyped here.
"""

from bpy.props import EnumProperty, FloatProperty, IntProperty

from . import backend
from .state import STATE

# Options the panel leaves at the registry's defaults: a build that needs
# more than the default memory limit is no preview.
HIDDEN_OPTIONS = ("memory_limit_mb",)

# Where the panel's default differs from the registry's, and why: the first
# press of Build & Render should give a preview quickly, and the fast build
# (binned planes near the root) builds several times quicker for a tree a few
# percent costlier (docs/build_quality.md); exact is one click away.
PANEL_DEFAULTS = {"build_quality": "fast"}

# A Blender property's limit for an open lower limit (a cost "> 0"): the
# smallest step the panel's fields show.
OPEN_MIN_STEP = 0.001

# IntProperty is 32-bit.
INT_PROPERTY_MAX = 2**31 - 1


def _panel_order(schema):
    """The BSP family's options first (what differs between methods), then
    the common ones, each group in the registry's order. Not the "top"
    group's: they set a two-level build's top level, no method's tree, and a
    two-level press builds its top level at their registry defaults."""
    names = [name for name in schema
             if name not in HIDDEN_OPTIONS and schema[name]["group"] != "top"]
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
    and limits all from the registry (`bsplab.method_table.OPTIONS`), but
    the defaults of PANEL_DEFAULTS, then the own defaults of the method a
    new scene starts at."""
    common = {"name": spec["label"], "description": spec["help"]}
    default = PANEL_DEFAULTS.get(spec["name"],
                                 FIRST_METHOD_DEFAULTS.get(spec["name"], spec["default"]))
    if spec["type"] == "enum":
        items = tuple((c["name"], c["label"], c["help"]) for c in spec["choices"])
        return EnumProperty(items=items, default=default, **common)
    if spec["type"] == "int":
        return IntProperty(default=default, **common, **_limits(spec))
    return FloatProperty(default=default, **common, **_limits(spec))


# The build options the panel can edit, in the panel's order; empty when
# bsplab is missing (nothing can be built then). A method's `params` in
# `bsplab.methods()` says which apply to it.
OPTION_SCHEMA = backend.option_schema()
# The own defaults of the method a new scene starts at (the method enum's
# first item, the registry's first method: kd), read once.
FIRST_METHOD_DEFAULTS = next(iter(backend.methods().values()), {}).get("defaults", {})
BUILD_OPTIONS = _panel_order(OPTION_SCHEMA)
# The build options but the thread count, which changes no tree: the panel
# draws A's threads with the render settings, and B is built with A's.
TREE_OPTIONS = tuple(name for name in BUILD_OPTIONS if name != "threads")
K_MAX = OPTION_SCHEMA["k"]["max"] if "k" in OPTION_SCHEMA else INT_PROPERTY_MAX

# The sidebar is narrow: the registry's short labels instead of the properties' names.
SHORT_LABELS = {name: spec["short_label"] for name, spec in OPTION_SCHEMA.items()}


def method_enum_items(_self, _context):
    """The items of A's and B's method enums: the registry's methods."""
    items = [
        (name, info.get("label", name), info.get("description", ""))
        for name, info in backend.methods().items()
    ]
    # Keep the list Blender already points to while it is unchanged: A's and
    # B's method enums share it, and replacing it under one would free the
    # strings the other shows.
    if items != STATE.enum_items.get("method"):
        STATE.enum_items["method"] = items
    return STATE.enum_items["method"]


def method_changed(self, _context):
    """Load the new method's own defaults (K differs between methods). An
    option some other method has a default of its own for (the BVH's
    intersect_cost) goes back to the registry's default when the new method
    has none: the BVH's cheaper tests would make a kd tree's leaves grow.
    An option of PANEL_DEFAULTS keeps its
    value (the panel's default, or what the user chose) unless the method
    has a default of its own for it."""
    methods = backend.methods()
    own = dict(methods.get(self.method, {}).get("defaults", {}))
    for other in methods.values():
        for name in other.get("defaults", {}):
            if name not in own and name not in PANEL_DEFAULTS and name in OPTION_SCHEMA:
                own[name] = OPTION_SCHEMA[name]["default"]
    for name, value in own.items():
        if name in PANEL_DEFAULTS and value == OPTION_SCHEMA.get(name, {}).get("default"):
            continue
        if name in BUILD_OPTIONS and hasattr(self, name):
            try:
                setattr(self, name, value)
            except (TypeError, ValueError):
                pass  # A default the property cannot hold: keep the current value.


def method_property(description):
    """A tree's method enum, from the registry's method table."""
    return EnumProperty(name="Method", description=description, items=method_enum_items,
                        update=method_changed)


def build_options(settings, names, params):
    """Keyword options for `bsplab.build`: those of `names` the method takes."""
    return {name: getattr(settings, name) for name in names if name in params}


def add_option_properties(cls, names):
    """The build options' properties, added to a PropertyGroup before it is registered."""
    for name in names:
        cls.__annotations__[name] = option_property(OPTION_SCHEMA[name])

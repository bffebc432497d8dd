# SPDX-License-Identifier: GPL-3.0-or-later
"""Lazy access to the compiled `bsplab` core.

The add-on must register, draw its panel and report a clear error when the
core is missing, so nothing imports `bsplab` at module level.
"""

import importlib

CORE_MODULE = "bsplab"

# Shown when the core cannot be imported; the import error is appended.
MISSING_MESSAGE = (
    "BSP Lab core module 'bsplab' is not available ({}). Install the BSP Lab "
    "extension zip, which bundles it, or 'pip install ./core' into Blender's Python"
)

# Used by the UI when the core is missing, so the panel still draws.
FALLBACK_METHODS = {
    "kd": {"label": "kd-tree", "description": "Core not installed", "params": []},
}
# Only what the enum needs to have an item: nothing renders without the core,
# and a copy of the core's list would drift from it (`bsplab.RENDER_MODES`).
FALLBACK_RENDER_MODES = ("shaded",)


class CoreMissing(Exception):
    pass


def import_core():
    """Return the `bsplab` module or raise CoreMissing with a user message."""
    try:
        return importlib.import_module(CORE_MODULE)
    except ImportError as ex:
        raise CoreMissing(MISSING_MESSAGE.format(ex)) from ex


def blender_module(name):
    """The core package's `bsplab.blender.<name>` module (scene reading shared
    with `bsplab.io.load_blend`); raise CoreMissing without the core."""
    import_core()
    try:
        return importlib.import_module("{}.blender.{}".format(CORE_MODULE, name))
    except ImportError as ex:  # a core older than bsplab.blender
        raise CoreMissing(MISSING_MESSAGE.format(ex)) from ex


def heat_ramp():
    """The core's colour ramp of the heat maps (`bsplab.render.heat_ramp`):
    the preview's colour bar must show exactly the colours of the image."""
    import_core()
    return importlib.import_module(CORE_MODULE + ".render").heat_ramp


def core_or_none():
    try:
        return import_core()
    except CoreMissing:
        return None


def methods():
    core = core_or_none()
    if core is None:
        return FALLBACK_METHODS
    return core.methods()


def option_schema():
    """Name -> schema of every build option (the core's registry); empty
    without the core, whose absence the panel reports."""
    core = core_or_none()
    if core is None:
        return {}
    return core.option_schema()


def render_modes():
    core = core_or_none()
    if core is None:
        return FALLBACK_RENDER_MODES
    return tuple(core.RENDER_MODES)

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
FALLBACK_RENDER_MODES = ("shaded", "normal", "depth", "heat_steps", "heat_tests")


class CoreMissing(Exception):
    pass


def import_core():
    """Return the `bsplab` module or raise CoreMissing with a user message."""
    try:
        return importlib.import_module(CORE_MODULE)
    except ImportError as ex:
        raise CoreMissing(MISSING_MESSAGE.format(ex)) from ex


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


def render_modes():
    core = core_or_none()
    if core is None:
        return FALLBACK_RENDER_MODES
    return tuple(core.RENDER_MODES)

# SPDX-License-Identifier: GPL-3.0-or-later
"""The add-on's one way to the `bsplab` package (the library built on the
compiled core).

The add-on must register, draw its panel and report a clear error when
`bsplab` is missing, so nothing imports it at module level: every module
asks here, and only here are module names written as strings.
"""

import importlib

BSPLAB_MODULE = "bsplab"

# Shown when bsplab cannot be imported; the import error is appended.
MISSING_MESSAGE = (
    "BSP Lab core module 'bsplab' is not available ({}). Install the BSP Lab "
    "extension zip, which bundles it, or 'pip install ./core' into Blender's Python"
)

# Used by the UI when bsplab is missing, so the panel still draws.
FALLBACK_METHODS = {
    "kd": {"label": "kd-tree", "description": "Core not installed", "params": []},
}
# Only what the enum needs to have an item: nothing renders without bsplab,
# and a copy of its list would drift from it (`bsplab.RENDER_MODES`).
FALLBACK_RENDER_MODES = ("shaded",)


class BsplabMissing(Exception):
    pass


def import_bsplab():
    """Return the `bsplab` module or raise BsplabMissing with a user message."""
    try:
        return importlib.import_module(BSPLAB_MODULE)
    except ImportError as ex:
        raise BsplabMissing(MISSING_MESSAGE.format(ex)) from ex


def submodule(name):
    """`bsplab.<name>` (e.g. "lab", "render", "blender.scene_camera"); raise
    BsplabMissing without bsplab, or with one older than that module."""
    import_bsplab()
    try:
        return importlib.import_module("{}.{}".format(BSPLAB_MODULE, name))
    except ImportError as ex:  # a bsplab older than the module
        raise BsplabMissing(MISSING_MESSAGE.format(ex)) from ex


def blender_module(name):
    """`bsplab.blender.<name>`: the scene readers shared with
    `bsplab.io.load_blend`."""
    return submodule("blender." + name)


def heat_ramp():
    """The colour ramp of the heat maps (`bsplab.render.heat_ramp`): the
    preview's colour bar must show exactly the colours of the image."""
    return submodule("render").heat_ramp


def lab():
    """`bsplab.lab`, the lab's one public entry (Sweep K's experiment)."""
    return submodule("lab")


def bsplab_or_none():
    try:
        return import_bsplab()
    except BsplabMissing:
        return None


def methods():
    bsplab = bsplab_or_none()
    if bsplab is None:
        return FALLBACK_METHODS
    return bsplab.methods()


def option_schema():
    """Name -> schema of every build option (the registry); empty without
    bsplab, whose absence the panel reports."""
    bsplab = bsplab_or_none()
    if bsplab is None:
        return {}
    return bsplab.option_schema()


def render_modes():
    bsplab = bsplab_or_none()
    if bsplab is None:
        return FALLBACK_RENDER_MODES
    return tuple(bsplab.RENDER_MODES)

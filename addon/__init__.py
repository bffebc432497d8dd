# SPDX-License-Identifier: GPL-3.0-or-later
"""BSP Lab: build kd/BSP trees of the scene and preview ray tracing with them.

Blender 4.2+ reads `blender_manifest.toml`; older versions (3.4 and later)
read `bl_info` when the folder is installed as a legacy add-on. Install the
legacy add-on under a folder name other than `bsplab`, which is the name of
the library it drives.

The add-on is one subpackage per feature (docs/addon.md#layout), each with
its `classes`, `register()` and `unregister()` (registration.py), around one
runtime state object (state.py). Adding a feature is one subpackage and one
line in FEATURES.
"""

bl_info = {
    "name": "BSP Lab",
    "author": "BSP Lab developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "3D Viewport > Sidebar > BSP Lab",
    "description": "Build kd and BSP trees of the scene and preview their ray tracing",
    "category": "3D View",
}

# Support "Reload Scripts", which re-runs this file in the same module: drop
# every module of the add-on's packages (walking sys.modules under this
# package's name) and the names they left here, so the imports below load
# each afresh, in the order the imports themselves give.
if "bpy" in locals():
    import sys as _sys
    _name = None
    for _name in [name for name in _sys.modules if name.startswith(__name__ + ".")]:
        del _sys.modules[_name]
        globals().pop(_name[len(__name__) + 1:].partition(".")[0], None)
    del _name, _sys

import importlib

import bpy  # noqa: F401  (what tells a reload from the first import, above)

from . import state

# The features, registered in this order and unregistered in reverse: the
# drawing helpers and the shared job machinery first, Build & Render (the
# main panel, which the other panels sit in) before the features that use
# its tree.
FEATURES = tuple(importlib.import_module("{}.{}".format(__name__, name)) for name in (
    "drawing",
    "jobs",
    "build_render",
    "compare",
    "k_sweep",
    "inspector",
    "overlay",
))


def register():
    # Registering twice would fail on the already registered classes; start
    # over instead, so re-running register() is safe.
    if state.STATE.registered:
        unregister()
    state.add_handlers()
    for feature in FEATURES:
        feature.register()
    state.STATE.registered = True


def unregister():
    if not state.STATE.registered:
        return
    state.STATE.cancel_job()
    for feature in reversed(FEATURES):
        feature.unregister()
    state.remove_handlers()  # and forget the file's trees, inspection and overlay
    state.STATE.registered = False

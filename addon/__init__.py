# SPDX-License-Identifier: GPL-3.0-or-later
"""BSP Lab: build kd/BSP trees of the scene and preview ray tracing with them.

Blender 4.2+ reads `blender_manifest.toml`; older versions (3.4 and later)
read `bl_info` when the folder is installed as a legacy add-on. Install the
legacy add-on under a folder name other than `bsplab`, which is the core's
module name.
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

# Support "Reload Scripts": re-import the submodules, dependencies first.
if "bpy" in locals():
    import importlib
    import sys as _sys
    for _name in ("backend", "extract", "camera", "preview", "stats", "compare", "tree_cache",
                  "jobs", "sweep", "inspector_store", "inspector_trace", "inspector_draw",
                  "properties", "operators", "ui", "inspector", "inspector_panel"):
        _module = _sys.modules.get("{}.{}".format(__name__, _name))
        if _module is not None:
            importlib.reload(_module)
    del _name, _module, _sys

import bpy

from . import inspector, inspector_panel, operators, properties, ui

classes = (
    *properties.classes,
    *operators.classes,
    *ui.classes,
    *inspector.classes,
    *inspector_panel.classes,
)

_register_classes, _unregister_classes = bpy.utils.register_classes_factory(classes)
_registered = False


def register():
    global _registered
    # Registering twice would fail on the already registered classes; start
    # over instead, so re-running register() is safe.
    if _registered:
        unregister()
    _register_classes()
    properties.register_props()
    operators.add_handlers()
    inspector.add_handlers()
    _registered = True


def unregister():
    global _registered
    if not _registered:
        return
    operators.cancel_active_job()
    operators.remove_handlers()  # and forget the kept tree
    inspector.remove_handlers()  # and forget the inspection
    properties.unregister_props()
    _unregister_classes()
    _registered = False

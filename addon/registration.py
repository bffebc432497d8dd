# SPDX-License-Identifier: GPL-3.0-or-later
"""What every feature subpackage's register() and unregister() do.

A feature (addon/<feature>/__init__.py) lists its Blender classes in
`classes`, in registration order (property groups before what points to
them, a parent panel before its sub-panels), and makes its two functions
with `feature()`: the add-on's __init__.py calls them in FEATURES order and
in reverse.
"""

import bpy


def feature(classes, on_register=(), on_unregister=()):
    """(register, unregister) of a feature: register() registers `classes`
    in order (`bpy.utils.register_classes_factory`, there since Blender 2.80)
    and then calls `on_register` (adding scene properties, handlers);
    unregister() calls `on_unregister`, then unregisters the classes in
    reverse."""
    register_classes, unregister_classes = bpy.utils.register_classes_factory(classes)

    def register():
        register_classes()
        for function in on_register:
            function()

    def unregister():
        for function in on_unregister:
            function()
        unregister_classes()

    return register, unregister

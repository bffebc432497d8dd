# SPDX-License-Identifier: GPL-3.0-or-later
"""The running job's state (`WindowManager.bsplab_job`), which the job
operator sets (job_operator.py) and the panels draw."""

import bpy
from bpy.props import BoolProperty, FloatProperty


class BSPLabJobState(bpy.types.PropertyGroup):
    """State of the running job. On the window manager, not the scene:
    it is runtime state, and updating it must not touch scene data."""

    is_running: BoolProperty(name="Running", default=False)
    progress: FloatProperty(
        name="Progress", default=0.0, min=0.0, max=1.0, subtype='FACTOR',
    )


classes = (BSPLabJobState,)


def register_props():
    bpy.types.WindowManager.bsplab_job = bpy.props.PointerProperty(type=BSPLabJobState)


def unregister_props():
    del bpy.types.WindowManager.bsplab_job

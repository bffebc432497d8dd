# SPDX-License-Identifier: GPL-3.0-or-later
"""The A/B comparison: Build & Render with "Compare with B" on builds and
renders a second tree, B (build_render/job.py runs it). Here: B's settings
(properties.py), its sub-panel (panel.py) and the A/B preview's images,
side by side or as a difference map (images.py, bpy-free)."""

from ..registration import feature
from . import panel, properties

classes = (
    *properties.classes,
    *panel.classes,
)

register, unregister = feature(classes, on_register=(properties.register_props,),
                               on_unregister=(properties.unregister_props,))

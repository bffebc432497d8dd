# SPDX-License-Identifier: GPL-3.0-or-later
"""The tree overlay: the kept tree's split planes and cells drawn in the 3D
Viewport. What is drawn, bpy-free: one tree's arrays (geometry.py), a
two-level build's top boxes and instance in place (in_place.py), chosen by
`tree.structure` and kept (cache.py); the settings (properties.py), the
draw handler (draw.py) and the sub-panel (panel.py)."""

from ..registration import feature
from . import draw, panel, properties

classes = (
    *properties.classes,
    *panel.classes,
)

register, unregister = feature(
    classes, on_register=(properties.register_props, draw.start),
    on_unregister=(draw.stop, properties.unregister_props))

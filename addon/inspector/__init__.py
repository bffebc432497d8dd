# SPDX-License-Identifier: GPL-3.0-or-later
"""The ray inspector: trace one ray (a preview pixel's, or the viewport's
through a point) with the tree the preview shows and show its walk. The
ray and its walk (trace.py, bpy-free), the operators (operators.py), what
the viewport draws (draw.py) and the sub-panel (panel.py)."""

from ..registration import feature
from . import draw, operators, panel

classes = (
    *operators.classes,
    *panel.classes,
)

register, unregister = feature(classes, on_register=(draw.add_handler,),
                               on_unregister=(draw.remove_handler,))

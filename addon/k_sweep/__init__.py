# SPDX-License-Identifier: GPL-3.0-or-later
"""The K sweep ("Sweep K" in the panel): every chosen method at every K of
a range, built and traced on this scene beside kd and Embree; a table and a
plot. The experiment and its plot (experiment.py, plot.py, bpy-free), the
operator (operator.py) and the sub-panel (panel.py). Its settings stay on
Scene.bsplab (build_render/properties.py), where saved files have them."""

from ..registration import feature
from . import operator, panel

classes = (
    *operator.classes,
    *panel.classes,
)

register, unregister = feature(classes)

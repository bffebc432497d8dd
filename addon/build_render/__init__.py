# SPDX-License-Identifier: GPL-3.0-or-later
"""Build & Render: the settings (properties.py), its input read on the main
thread (scene_input.py), the job on a worker thread (job.py: trees A and
B, the render, the build statistics), the operator (operator.py), the
statistics' rows (statistics.py) and the main panel with its Statistics
sub-panel (panel.py). The machinery it shares with the other features
(the worker, the job operator, the tree cache, the scene reader, the
preview image, the record of what it shows) is the jobs package's."""

from ..registration import feature
from . import operator, panel, properties

classes = (
    *properties.classes,
    *operator.classes,
    *panel.classes,
)

register, unregister = feature(classes, on_register=(properties.register_props,),
                               on_unregister=(properties.unregister_props,))

# SPDX-License-Identifier: GPL-3.0-or-later
"""Build & Render: the settings (properties.py), the scene read on the main
thread (scene_reader.py), the job on a worker thread (worker.py, job.py)
with the kept tree (tree_cache.py), the operator (job_operator.py,
operator.py), the preview image (preview.py), the statistics
(statistics.py), the record of what the preview shows (shown_build.py)
and the main panel with its Statistics sub-panel (panel.py)."""

from ..registration import feature
from . import operator, panel, properties

classes = (
    *properties.classes,
    *operator.classes,
    *panel.classes,
)

register, unregister = feature(classes, on_register=(properties.register_props,),
                               on_unregister=(properties.unregister_props,))

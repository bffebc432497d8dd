# SPDX-License-Identifier: GPL-3.0-or-later
"""The machinery every feature's jobs share, below the features: the
worker-thread job and its errors (worker.py), the modal operator that runs
one (job_operator.py) with its progress on the window manager
(properties.py), the scene read on the main thread (scene_reader.py), one
tree of a press built or re-used (tree_run.py) from the kept trees
(tree_cache.py), the Embree comparison (embree_check.py), the user's
messages about a press (messages.py), the preview image block (preview.py)
and the record of what the preview shows (shown_build.py).

Build & Render, the K sweep, the ray inspector and the overlay import from
here; nothing here imports a feature. Registered as a feature of its own,
first after the drawing helpers: the operators' progress property must
exist before any operator runs."""

from ..registration import feature
from . import properties

classes = properties.classes

register, unregister = feature(classes, on_register=(properties.register_props,),
                               on_unregister=(properties.unregister_props,))

# SPDX-License-Identifier: GPL-3.0-or-later
"""World-space triangles of the evaluated scene: the core package's
`bsplab.blender.extract` (`scene_triangles`, `SceneGeometry`), the one copy
that `bsplab.io.load_blend` runs in Blender too. Looked up on first use
(PEP 562), so the add-on imports and registers without the core.
"""

from . import backend


def __getattr__(name):
    if name.startswith("__"):
        raise AttributeError(name)
    return getattr(backend.blender_module("extract"), name)

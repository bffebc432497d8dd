# SPDX-License-Identifier: GPL-3.0-or-later
"""Drawing for the other features, without bpy: the bitmap font and the
legends drawn into the add-on's images (numpy), and Blender's built-in GPU
shaders by one name across versions (gpu_shaders.py, imported only where
the viewport draws: the `gpu` module raises in background mode as soon as
a shader is made). Nothing to register."""

from ..registration import feature

classes = ()

register, unregister = feature(classes)

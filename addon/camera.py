# SPDX-License-Identifier: GPL-3.0-or-later
"""The scene camera: the core package's `bsplab.blender.camera`.

There is one copy of the camera reader, in the core package, because
`bsplab.io.load_blend` runs it in Blender too. Its names (`scene_camera`,
`CameraSpec`, `CameraError`) are looked up on first use (PEP 562), so the
add-on still imports, registers and draws when the core is missing.
"""

from . import backend


def preview_size(render, preview_percentage):
    """Preview size: render resolution x render % x the panel's preview %.

    The panel draws it with or without the core, so it cannot wait for the
    core's copy (bsplab.blender.camera.preview_size, which
    blender_tests/test_camera.py checks this one against)."""
    scale = render.resolution_percentage / 100.0 * preview_percentage / 100.0
    width = max(1, int(round(render.resolution_x * scale)))
    height = max(1, int(round(render.resolution_y * scale)))
    return width, height


def __getattr__(name):
    if name.startswith("__"):
        raise AttributeError(name)
    return getattr(backend.blender_module("scene_camera"), name)

# SPDX-License-Identifier: GPL-3.0-or-later
"""Main thread: copy what a job needs out of the scene (bpy) into plain
values, so the job itself runs on a worker thread without touching bpy.

The camera and the triangles are read by the `bsplab.blender` readers
(`scene_camera`, `CameraSpec`, `CameraError`; `scene_triangles`,
`SceneGeometry` for a flat build, `scene_instances`, `InstancedGeometry`
for a two-level one), the one copy that `bsplab.io.load_blend` runs in Blender
too. They are looked up on first use (PEP 562), so the add-on still imports,
registers and draws when bsplab is missing.
"""

import sys

from .. import backend
from .worker import UserError

# The names this module hands on from bsplab.blender, and from which reader.
READER_NAMES = {
    "scene_camera": "scene_camera", "CameraSpec": "scene_camera", "CameraError": "scene_camera",
    "scene_triangles": "extract", "SceneGeometry": "extract",
    "scene_instances": "extract", "InstancedGeometry": "extract",
}


def __getattr__(name):
    if name not in READER_NAMES:
        raise AttributeError("module {!r} has no attribute {!r}".format(__name__, name))
    return getattr(backend.blender_module(READER_NAMES[name]), name)


def _reader(name):
    # An attribute of this module (__getattr__ when not set), so a test can
    # replace one reader.
    return getattr(sys.modules[__name__], name)


def make_camera(bsplab, spec):
    """The bsplab.Camera of a CameraSpec (the scene camera as read here)."""
    return bsplab.Camera(**spec.kwargs())


def preview_size(render, preview_percentage):
    """Preview size: render resolution x render % x the panel's preview %.

    The panel draws it with or without bsplab, so it cannot wait for
    bsplab's copy (bsplab.blender.scene_camera.preview_size, which
    blender_tests/test_camera.py checks this one against)."""
    scale = render.resolution_percentage / 100.0 * preview_percentage / 100.0
    width = max(1, int(round(render.resolution_x * scale)))
    height = max(1, int(round(render.resolution_y * scale)))
    return width, height


def read_camera_and_geometry(context, bsplab, two_level=False):
    """The scene camera at the preview size and the visible triangles (a
    SceneGeometry; `two_level`: the InstancedGeometry of the unique meshes
    and their instances); raise UserError when either is missing or the
    camera is outside bsplab's ranges (bsplab.camera.RANGES, wide enough
    for any usable Blender camera)."""
    depsgraph = context.evaluated_depsgraph_get()
    try:
        cam = _reader("scene_camera")(context.scene, depsgraph,
                                      context.scene.bsplab.preview_percentage)
    except _reader("CameraError") as ex:
        raise UserError(str(ex)) from ex
    try:
        make_camera(bsplab, cam)
    except (TypeError, ValueError) as ex:
        raise UserError("The scene camera '{}' cannot be previewed: {}".format(
            cam.name, ex)) from ex
    geometry = _reader("scene_instances" if two_level else "scene_triangles")(depsgraph)
    if geometry.triangle_count == 0:
        if geometry.instances == 0:
            raise UserError("No visible mesh in the scene: nothing to build a tree from")
        raise UserError("The visible meshes are empty: they have no faces to build a tree from")
    return cam, geometry

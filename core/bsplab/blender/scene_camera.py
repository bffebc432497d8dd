# SPDX-License-Identifier: GPL-3.0-or-later
"""The scene camera as the library's `bsplab.Camera` parameters.

Takes bpy objects, imports neither bpy nor the rest of bsplab (see
bsplab/blender/__init__.py for why)."""

from dataclasses import dataclass

import numpy as np


class CameraError(Exception):
    pass


@dataclass
class CameraSpec:
    """Everything `bsplab.Camera` needs to make the camera rays; no bpy references."""

    matrix_world: np.ndarray  # (4, 4) float64, scale removed
    lens: float
    sensor_width: float
    sensor_height: float
    sensor_fit: str
    shift_x: float
    shift_y: float
    pixel_aspect: float  # pixel width / pixel height
    clip_start: float
    clip_end: float
    width: int
    height: int
    name: str = ""

    def kwargs(self):
        return {
            "matrix_world": self.matrix_world,
            "lens": self.lens,
            "sensor_width": self.sensor_width,
            "sensor_height": self.sensor_height,
            "sensor_fit": self.sensor_fit,
            "shift_x": self.shift_x,
            "shift_y": self.shift_y,
            "pixel_aspect": self.pixel_aspect,
            "clip_start": self.clip_start,
            "clip_end": self.clip_end,
        }


def preview_size(render, preview_percentage):
    """Preview size: render resolution x render % x the panel's preview %."""
    scale = render.resolution_percentage / 100.0 * preview_percentage / 100.0
    width = max(1, int(round(render.resolution_x * scale)))
    height = max(1, int(round(render.resolution_y * scale)))
    return width, height


def _without_scale(matrix):
    # Blender's camera ignores object scale; a scaled camera must not change
    # the field of view, so normalise the rotation columns.
    m = np.array(matrix, dtype=np.float64)
    norms = np.linalg.norm(m[:3, :3], axis=0)
    if np.any(norms == 0.0) or not np.all(np.isfinite(m)):
        raise CameraError("The scene camera's transform is degenerate (zero scale or NaN)")
    m[:3, :3] /= norms
    return m


def scene_camera(scene, depsgraph, preview_percentage):
    """Read the active scene camera; raise CameraError with a user message."""
    cam_obj = scene.camera
    if cam_obj is None:
        raise CameraError("The scene has no active camera: add one and set it as the scene camera")
    if cam_obj.type != 'CAMERA':
        raise CameraError("The scene camera '{}' is not a camera object".format(cam_obj.name))
    # The evaluated camera has animation, constraints and drivers applied.
    cam_eval = cam_obj.evaluated_get(depsgraph)
    data = cam_eval.data
    if data.type != 'PERSP':
        raise CameraError(
            "Camera '{}' is {}: BSP Lab previews perspective cameras only".format(
                cam_obj.name, data.type.lower()))
    render = scene.render
    width, height = preview_size(render, preview_percentage)
    return CameraSpec(
        matrix_world=_without_scale(cam_eval.matrix_world),
        lens=float(data.lens),
        sensor_width=float(data.sensor_width),
        sensor_height=float(data.sensor_height),
        sensor_fit=data.sensor_fit,
        shift_x=float(data.shift_x),
        shift_y=float(data.shift_y),
        pixel_aspect=float(render.pixel_aspect_x) / float(render.pixel_aspect_y),
        clip_start=float(data.clip_start),
        clip_end=float(data.clip_end),
        width=width,
        height=height,
        name=cam_obj.name,
    )

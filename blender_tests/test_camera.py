"""The scene camera as core camera parameters, framed as Blender frames it."""

import bpy
import numpy as np
import pytest



def spec_of(addon, scene, preview=50):
    return addon.jobs.scene_reader.scene_camera(scene, bpy.context.evaluated_depsgraph_get(), preview)


def test_camera_spec(addon, test_scene):
    scene = test_scene["scene"]
    cam = test_scene["camera"]
    cam.data.lens = 35.0
    cam.data.shift_x = 0.1
    cam.data.sensor_fit = 'VERTICAL'
    spec = spec_of(addon, scene)
    assert (spec.width, spec.height) == (80, 60)
    assert spec.lens == pytest.approx(35.0)
    assert spec.shift_x == pytest.approx(0.1)
    assert spec.sensor_fit == 'VERTICAL'
    assert spec.pixel_aspect == 1.0
    assert np.allclose(spec.matrix_world, np.array(cam.matrix_world), atol=1e-6)


def test_preview_size_uses_both_percentages(addon, test_scene):
    scene = test_scene["scene"]
    scene.render.resolution_x, scene.render.resolution_y = 1920, 1080
    scene.render.resolution_percentage = 50
    assert addon.jobs.scene_reader.preview_size(scene.render, 25) == (240, 135)
    assert addon.jobs.scene_reader.preview_size(scene.render, 1) == (10, 5)
    scene.render.resolution_x, scene.render.resolution_y = 4, 4
    scene.render.resolution_percentage = 1
    assert addon.jobs.scene_reader.preview_size(scene.render, 1) == (1, 1)


def test_camera_scale_is_ignored(addon, test_scene):
    cam = test_scene["camera"]
    before = spec_of(addon, test_scene["scene"]).matrix_world
    cam.scale = (3.0, 3.0, 3.0)
    bpy.context.view_layer.update()
    after = spec_of(addon, test_scene["scene"]).matrix_world
    assert np.allclose(before, after, atol=1e-6)


def test_no_camera(addon, test_scene):
    test_scene["scene"].camera = None
    with pytest.raises(addon.jobs.scene_reader.CameraError, match="no active camera"):
        spec_of(addon, test_scene["scene"])


def test_orthographic_camera_is_refused(addon, test_scene):
    test_scene["camera"].data.type = 'ORTHO'
    with pytest.raises(addon.jobs.scene_reader.CameraError, match="perspective"):
        spec_of(addon, test_scene["scene"])


FRAMINGS = [
    # resolution, sensor fit, shift, pixel aspect
    ((160, 120), 'AUTO', (0.0, 0.0), (1, 1)),
    ((120, 160), 'AUTO', (0.0, 0.0), (1, 1)),
    ((160, 90), 'HORIZONTAL', (0.2, -0.1), (1, 1)),
    ((160, 90), 'VERTICAL', (0.0, 0.3), (1, 1)),
    ((90, 160), 'VERTICAL', (-0.25, 0.0), (1, 1)),
    ((160, 120), 'AUTO', (0.1, 0.1), (2, 1)),
    ((100, 120), 'AUTO', (0.0, 0.0), (1, 2)),
]


@pytest.mark.parametrize("resolution,fit,shift,aspect", FRAMINGS)
def test_framing_matches_blender(addon, core, test_scene, resolution, fit, shift, aspect):
    """The core camera's image window equals Blender's camera frame
    (`Camera.view_frame`), for every sensor fit, shift and pixel aspect."""
    scene = test_scene["scene"]
    render = scene.render
    render.resolution_x, render.resolution_y = resolution
    render.pixel_aspect_x, render.pixel_aspect_y = aspect
    data = test_scene["camera"].data
    data.sensor_fit = fit
    data.sensor_width, data.sensor_height = 36.0, 20.0
    data.shift_x, data.shift_y = shift
    spec = spec_of(addon, scene, 100)
    xmin, xmax, ymin, ymax = core.Camera(**spec.kwargs()).viewplane(spec.width, spec.height)
    frame = np.array([tuple(v) for v in data.view_frame(scene=scene)])
    frame = frame[:, :2] / -frame[:, 2:3]  # onto the z = -1 plane
    assert np.allclose([frame[:, 0].min(), frame[:, 0].max(), frame[:, 1].min(), frame[:, 1].max()],
                       [xmin, xmax, ymin, ymax], rtol=1e-5, atol=1e-6)

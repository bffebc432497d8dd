"""The overlay's and the ray inspector's GPU drawing, off screen in background mode.

Blender 5.1 added `gpu.init()`, which gives background mode a GPU context
(here Mesa's llvmpipe through EGL), so on the bpy 5.2 module the draw
handlers' own code (built-in shaders by name, batch_for_shader, the
polyline uniforms, gpu.state) runs and draws into a GPUOffScreen seen
through the scene's camera. Before 5.1 the `gpu` module raises in background
mode: there this file skips, and the drawing is checked in a real window by
gui_check_overlay.py and gui_check_inspector.py (Debian's Blender under Xvfb).
"""

import bpy
import gpu
import numpy as np
import pytest

from conftest import require

pytestmark = pytest.mark.skipif(
    not hasattr(gpu, "init"),
    reason="Blender {} has no gpu.init(): no GPU in background mode before 5.1 (the GUI "
           "checks draw in a window instead)".format(bpy.app.version_string))

# The off-screen image: the test scene's render size (its camera's aspect).
WIDTH, HEIGHT = 160, 120
# Colours come back as 8-bit values: compare within two steps.
COLOUR_TOLERANCE = 2.0 / 255
# The overlay of a whole tree to depth 8 covers much of the view; an overlay
# that drew nothing would leave every pixel clear.
MIN_OVERLAY_COVERAGE = 0.05


@pytest.fixture(scope="module")
def gpu_context():
    try:
        gpu.init()
    except SystemError as ex:
        require(False, "gpu.init() failed (Mesa's EGL and llvmpipe: libegl-mesa0, "
                       "libgl1-mesa-dri): {}".format(ex))
    return gpu.platform.renderer_get()


def draw_through_camera(scene, draw):
    """Call `draw` in an off-screen frame buffer seen through the scene's
    camera; the RGBA pixels, rows from the bottom."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    projection = scene.camera.calc_matrix_camera(depsgraph, x=WIDTH, y=HEIGHT)
    view = scene.camera.matrix_world.inverted()
    offscreen = gpu.types.GPUOffScreen(WIDTH, HEIGHT)
    try:
        with offscreen.bind():
            framebuffer = gpu.state.active_framebuffer_get()
            framebuffer.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
            with gpu.matrix.push_pop():
                gpu.matrix.load_matrix(view)
                gpu.matrix.load_projection_matrix(projection)
                draw()
            buffer = framebuffer.read_color(0, 0, WIDTH, HEIGHT, 4, 0, 'FLOAT')
            return np.array(buffer.to_list(), dtype=np.float32).reshape(HEIGHT, WIDTH, 4)
    finally:
        offscreen.free()


def camera_pixel(scene, point):
    """The off-screen pixel (column, row from the bottom) where the camera sees `point`."""
    import mathutils
    depsgraph = bpy.context.evaluated_depsgraph_get()
    projection = scene.camera.calc_matrix_camera(depsgraph, x=WIDTH, y=HEIGHT)
    clip = projection @ scene.camera.matrix_world.inverted() @ mathutils.Vector((*point, 1.0))
    ndc_x, ndc_y = clip.x / clip.w, clip.y / clip.w
    return int((ndc_x + 1) / 2 * WIDTH), int((ndc_y + 1) / 2 * HEIGHT)


def press(scene):
    assert (scene.render.resolution_x, scene.render.resolution_y) == (WIDTH, HEIGHT)
    assert bpy.ops.bsplab.build_render() == {'FINISHED'}


def test_overlay_draws_the_kept_trees_planes(addon, core, test_scene, gpu_context):
    scene = test_scene["scene"]
    press(scene)
    overlay, state = addon.overlay.draw, addon.state.STATE
    scene.bsplab_overlay.show = False
    hidden = draw_through_camera(scene, overlay.draw_overlay)
    assert state.overlay_draw_calls == 0
    assert not hidden.any()

    scene.bsplab_overlay.show = True
    pixels = draw_through_camera(scene, overlay.draw_overlay)
    geometry = overlay.current_geometry(scene)
    # One batch per non-empty part: faces, their outlines, the cells.
    parts = [geometry[key] for key in ("face_indices", "line_indices", "cell_indices")]
    assert state.overlay_draw_calls == sum(1 for indices in parts if len(indices)) > 0
    coverage = np.count_nonzero(pixels[..., 3] > 0) / (WIDTH * HEIGHT)
    assert coverage > MIN_OVERLAY_COVERAGE, (coverage, gpu_context)


def test_inspector_draws_the_hit_where_the_preview_pixel_is(addon, core, test_scene, gpu_context):
    scene = test_scene["scene"]
    press(scene)
    inspection = inspect_middle_pixel(addon)
    assert inspection["counts"]["hit_prim"] >= 0
    assert_hit_drawn(addon, scene, inspection, gpu_context)


def inspect_middle_pixel(addon):
    """The ray inspector on the middle of the preview, picked as
    test_inspector.py does it; the inspection."""
    width, height = addon.state.STATE.shown_build.render_size
    image_height = bpy.data.images[addon.jobs.preview.IMAGE_NAME].size[1]
    assert bpy.ops.bsplab.inspect_pixel(x=width // 2, y=image_height - 1 - height // 2) \
        == {'FINISHED'}
    return addon.state.STATE.inspection


def assert_hit_drawn(addon, scene, inspection, gpu_context):
    """The inspector's drawing: the hit point drawn last, opaque and on top,
    at the pixel where the camera sees it, and around it the tested
    triangles and the cells."""
    pixels = draw_through_camera(scene, addon.inspector.draw._draw)
    column, row = camera_pixel(scene, inspection["draw"]["hit"][0])
    centre = pixels[row, column, :3]
    hit_rgb = np.array(addon.inspector.draw.HIT_COLOUR[:3], dtype=np.float32)
    assert np.allclose(centre, hit_rgb, atol=COLOUR_TOLERANCE), (centre, hit_rgb, gpu_context)
    assert np.count_nonzero(pixels[..., 3] > 0) > addon.inspector.draw.HIT_POINT_SIZE ** 2


# -----------------------------------------------------------------------------
# Two-level builds (test_instances.py's grid of collection instances)


@pytest.fixture
def instanced_scene(addon):
    import bsplab_test_utils as utils
    from test_instances import build_instanced_scene
    return build_instanced_scene(utils.reset_file("two_level"))


def coverage(pixels):
    return np.count_nonzero(pixels[..., 3] > 0) / (WIDTH * HEIGHT)


def test_overlay_draws_a_two_level_build_and_the_instance_in_place(addon, core, instanced_scene,
                                                                  gpu_context):
    from test_two_level_views import grid_cube_point
    scene = instanced_scene["scene"]
    press(scene)
    overlay, state = addon.overlay.draw, addon.state.STATE
    assert state.shown_build.tree().structure == "two_level"
    props = scene.bsplab_overlay
    props.show, props.max_depth = True, 3
    # The cursor far from every instance: the top level's boxes only.
    scene.cursor.location = (0.0, 0.0, 100.0)
    assert overlay.current_geometry(scene)["instance"] is None
    top_only = draw_through_camera(scene, overlay.draw_overlay)
    assert state.overlay_draw_calls > 0
    assert coverage(top_only) > 0.0, gpu_context
    # On a cube of the grid: its own tree drawn in place besides - more drawn.
    scene.cursor.location = grid_cube_point(instanced_scene, 1, 1)
    assert overlay.current_geometry(scene)["instance"] is not None
    both = draw_through_camera(scene, overlay.draw_overlay)
    assert coverage(both) > coverage(top_only), (coverage(both), coverage(top_only))


def test_inspector_draws_a_two_level_hit_where_the_preview_pixel_is(addon, core, instanced_scene,
                                                                   gpu_context):
    scene = instanced_scene["scene"]
    press(scene)
    inspection = inspect_middle_pixel(addon)
    assert inspection["structure"] == "two_level"
    assert inspection["counts"]["hit_instance"] is not None
    assert_hit_drawn(addon, scene, inspection, gpu_context)

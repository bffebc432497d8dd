"""The "BSP Lab Preview" image block."""

import os

import bpy
import numpy as np

import bsplab_test_utils as utils


def random_image(height, width, seed=0):
    rng = np.random.default_rng(seed)
    image = rng.random((height, width, 4), dtype=np.float32)
    image[..., 3] = 1.0
    return image


def test_created_float_sized_and_flipped(addon, empty_scene):
    rgba = random_image(6, 10)
    image = addon.jobs.preview.write_preview(rgba)
    assert image.name == addon.jobs.preview.IMAGE_NAME
    assert tuple(image.size) == (10, 6)
    assert image.is_float
    assert image.source == 'GENERATED'
    flat = np.empty(10 * 6 * 4, np.float32)
    image.pixels.foreach_get(flat)
    # Blender's first row is the bottom one: the core's last.
    assert np.array_equal(flat.reshape(6, 10, 4)[0], rgba[-1])
    assert np.array_equal(utils.image_pixels_top_down(image), rgba)


def test_reused_and_resized(addon, empty_scene):
    first = addon.jobs.preview.write_preview(random_image(6, 10))
    pointer = first.as_pointer()
    rgba = random_image(3, 17, seed=1)
    second = addon.jobs.preview.write_preview(rgba)
    assert second.as_pointer() == pointer
    assert len([i for i in bpy.data.images if i.name.startswith(addon.jobs.preview.IMAGE_NAME)]) == 1
    assert tuple(second.size) == (17, 3)
    assert np.array_equal(utils.image_pixels_top_down(second), rgba)


def test_byte_image_of_the_same_name_becomes_float(addon, empty_scene):
    bpy.data.images.new(addon.jobs.preview.IMAGE_NAME, 4, 4, alpha=True, float_buffer=False)
    rgba = random_image(5, 7)
    image = addon.jobs.preview.write_preview(rgba)
    assert image.is_float
    assert np.allclose(utils.image_pixels_top_down(image), rgba)


def test_save_png_keeps_the_generated_image(addon, empty_scene, tmp_path):
    rgba = random_image(5, 8)
    image = addon.jobs.preview.write_preview(rgba)
    path = str(tmp_path / "preview.png")
    addon.jobs.preview.save_png(image, path)
    assert os.path.getsize(path) > 0
    assert image.source == 'GENERATED'
    assert [i.name for i in bpy.data.images] == [addon.jobs.preview.IMAGE_NAME]
    loaded = bpy.data.images.load(path)
    loaded.colorspace_settings.name = 'Non-Color'
    assert tuple(loaded.size) == (8, 5)
    # 16-bit PNG: values survive to within quantisation.
    assert np.allclose(utils.image_pixels_top_down(loaded), rgba, atol=1e-4)


def test_shown_in_open_image_editors(addon, empty_scene):
    window = bpy.context.window_manager.windows[0]
    area = window.screen.areas[0]
    area.type = 'IMAGE_EDITOR'
    image = addon.jobs.preview.write_preview(random_image(2, 2))
    assert area.spaces.active.image == image
    # A pinned editor keeps its image.
    other = bpy.data.images.new("Other", 2, 2)
    area.spaces.active.image = other
    area.spaces.active.use_image_pin = True
    addon.jobs.preview.write_preview(random_image(2, 2))
    assert area.spaces.active.image == other

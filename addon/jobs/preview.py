# SPDX-License-Identifier: GPL-3.0-or-later
"""The "BSP Lab Preview" image block."""

import bpy
import numpy as np

IMAGE_NAME = "BSP Lab Preview"

# The core's values are display-ready in [0, 1]; "Non-Color" stops Blender
# from treating them as scene-linear, so the Image Editor and a saved PNG show
# the same values the core's own PNG writer does.
COLORSPACE = "Non-Color"


def _prepare_image(width, height, name=IMAGE_NAME):
    """Get or create the image block: generated, float, RGBA, width x height."""
    image = bpy.data.images.get(name)
    if image is None:
        return bpy.data.images.new(name, width, height, alpha=True, float_buffer=True)
    if image.source != 'GENERATED':
        # Saved to disk at some point: turn it back into a generated buffer,
        # which keeps the datablock (and the editors showing it).
        image.source = 'GENERATED'
    if not image.use_generated_float:
        image.use_generated_float = True
    if tuple(image.size) != (width, height):
        image.generated_width = width
        image.generated_height = height
        if tuple(image.size) != (width, height):
            image.scale(width, height)
    return image


def write_preview(rgba, name=IMAGE_NAME):
    """Store an (H, W, 4) image whose row 0 is the top; return the image block."""
    rgba = np.asarray(rgba, dtype=np.float32)
    height, width = rgba.shape[:2]
    image = _prepare_image(width, height, name)
    try:
        image.colorspace_settings.name = COLORSPACE
    except TypeError:
        pass  # A custom OCIO config without "Non-Color": keep its default.
    # Blender's row 0 is the bottom row.
    pixels = np.ascontiguousarray(rgba[::-1]).reshape(-1)
    image.pixels.foreach_set(pixels)
    image.update()
    show_in_image_editors(image)
    return image


def read_pixels(image):
    """The image's pixels as (H, W, 4) float32 with row 0 at the top."""
    width, height = image.size
    flat = np.empty(width * height * 4, dtype=np.float32)
    image.pixels.foreach_get(flat)
    return flat.reshape(height, width, 4)[::-1].copy()


def show_in_image_editors(image):
    """Show the image in every open Image Editor that is not pinned."""
    wm = bpy.context.window_manager
    if wm is None:
        return
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type != 'IMAGE_EDITOR':
                continue
            space = area.spaces.active
            if not space.use_image_pin and space.image != image:
                space.image = image
                _fit_view(window, area)
            area.tag_redraw()


def _fit_view(window, area):
    """Zoom a newly assigned editor to the whole image (Blender >= 3.2)."""
    region = next((r for r in area.regions if r.type == 'WINDOW'), None)
    if region is None or bpy.app.background or not hasattr(bpy.context, "temp_override"):
        return
    try:
        with bpy.context.temp_override(window=window, area=area, region=region):
            bpy.ops.image.view_all(fit_view=True)
    except RuntimeError:
        pass  # Only cosmetic.


def save_png(image, filepath):
    """Write the image block to a PNG without turning it into a file image.

    `Image.save()` re-sources the datablock to the file; a throw-away copy of
    the pixels keeps the preview a generated buffer.
    """
    width, height = image.size
    flat = np.empty(width * height * 4, dtype=np.float32)
    image.pixels.foreach_get(flat)
    tmp = bpy.data.images.new(IMAGE_NAME + " (export)", width, height, alpha=True, float_buffer=True)
    try:
        tmp.colorspace_settings.name = image.colorspace_settings.name
        tmp.pixels.foreach_set(flat)
        tmp.filepath_raw = filepath
        tmp.file_format = 'PNG'
        tmp.save()
    finally:
        bpy.data.images.remove(tmp)

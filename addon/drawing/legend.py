# SPDX-License-Identifier: GPL-3.0-or-later
"""Legends drawn into the add-on's images with numpy (no bpy): the colour
bar under a heat preview and the legend box of the Sweep K plot."""

import numpy as np

from . import bitmap_font as font

# The heat modes: the render statistic that holds the counter's maximum, and
# the unit the bar is labelled with.
HEAT_UNITS = {
    "heat_steps": ("max_steps", "traversal steps per ray"),
    "heat_tests": ("max_tests", "triangle tests per ray"),
    "heat_culled": ("max_culled", "culled tests per ray"),
    "heat_box_tests": ("max_box_tests", "box tests per ray"),  # a BVH's
}
STRIP_BACKGROUND = (0.05, 0.05, 0.06)  # the core's preview background
TEXT = (0.92, 0.92, 0.92)
PAD = 4


def text_scale(width):
    """Glyph scale for an image `width` pixels wide: 5 x 7 glyphs on a small
    preview, larger on a big one so the labels stay readable once zoomed to fit."""
    return max(1, int(width) // 640)


def heat_scale_top(mode, render_stats):
    """The count shown by the ramp's last colour, or None if `mode` is no heat
    mode. The core colours count / max(largest count, 1), so the bar runs from
    0 to that maximum (at least 1)."""
    if mode not in HEAT_UNITS:
        return None
    key, _ = HEAT_UNITS[mode]
    largest = render_stats.get(key)
    if largest is None:
        raise ValueError("the render statistics have no {!r}: cannot label the colour bar of "
                         "{}".format(key, mode))
    return max(int(largest), 1)


def colour_bar_strip(width, top, ramp, caption, scale=1, low="0", middle=None):
    """An (h, width, 4) strip: the ramp from `low` (left, labelled with it;
    0 by default) to `top` (right, labelled with it) and the caption (the
    unit) below it. `middle`, if given, labels the bar's centre on a row of
    its own under the bar (the 0 of a diverging bar).
    `ramp(x)` gives the (N, 3) colours of values x in [0, 1]."""
    lo_text, hi_text = str(low), str(int(top))
    lo_w, text_h = font.text_size(lo_text, scale)
    hi_w, _ = font.text_size(hi_text, scale)
    pad = PAD * scale
    # The caption's row, below the bar (and below the middle label if any).
    caption_y = 2 * pad + text_h + (0 if middle is None else pad + text_h)
    height = caption_y + text_h + pad
    strip = np.empty((height, width, 4), dtype=np.float32)
    strip[..., :3] = STRIP_BACKGROUND
    strip[..., 3] = 1.0
    x0, x1 = 2 * pad + lo_w, width - 2 * pad - hi_w  # the bar's columns [x0, x1)
    if x1 - x0 < 2:
        raise ValueError("a {} px wide image has no room for a colour bar".format(width))
    xs = np.arange(x1 - x0, dtype=np.float32) / (x1 - x0 - 1)
    strip[pad:pad + text_h, x0:x1, :3] = np.asarray(ramp(xs), dtype=np.float32)[None]
    font.draw_text(strip, lo_text, pad, pad, TEXT, scale)
    font.draw_text(strip, hi_text, width - pad, pad, TEXT, scale, anchor="right")
    if middle is not None:
        font.draw_text(strip, str(middle), (x0 + x1) // 2, 2 * pad + text_h, TEXT, scale,
                       anchor="centre")
    font.draw_text(strip, caption, width // 2, caption_y, TEXT, scale, anchor="centre")
    return strip


def strip_min_width(top, caption, scale, low="0"):
    """The narrowest strip whose bar, labels and caption all fit."""
    pad = PAD * scale
    labels = font.text_size(str(low), scale)[0] + font.text_size(str(int(top)), scale)[0]
    bar = 40 * scale
    return max(labels + bar + 4 * pad, font.text_size(caption, scale)[0] + 2 * pad)


def with_heat_bar(image, mode, render_stats, ramp):
    """The preview of a heat mode with its colour bar below; any other mode's
    image unchanged. The render keeps its pixels at the top left (row 0 is the
    top), so pixel (x, y) of the render is still the camera's ray (x, y); an
    image narrower than the bar is padded on the right with the background."""
    top = heat_scale_top(mode, render_stats)
    if top is None:
        return image
    return with_colour_bar(image, top, ramp, HEAT_UNITS[mode][1])


def with_colour_bar(image, top, ramp, caption, low="0", middle=None):
    """The image with a colour bar strip (see colour_bar_strip) below it, the
    image's pixels kept at the top left and an image narrower than the bar
    padded on the right with the background."""
    height, width = image.shape[:2]
    scale = text_scale(width)
    full_width = max(width, strip_min_width(top, caption, scale, low))
    strip = colour_bar_strip(full_width, top, ramp, caption, scale, low, middle)
    out = np.empty((height + strip.shape[0], full_width, 4), dtype=np.float32)
    out[:height, :, :3] = STRIP_BACKGROUND
    out[:height, :, 3] = 1.0
    out[:height, :width] = image
    out[height:] = strip
    return out


SAMPLE = 15  # length of the line sample beside each name: one and a half dashes
# A dashed line (the Sweep K plot's levels): DASH px drawn of every DASH_PERIOD.
DASH, DASH_PERIOD = 5, 10


def legend_size(names, scale=1):
    """(width, height) of the legend box of `names`."""
    pad = PAD * scale
    text_w = max((font.text_size(n, scale)[0] for n in names), default=0)
    return 3 * pad + SAMPLE * scale + text_w, pad + len(names) * font.LINE_H * scale + pad


def draw_legend(img, x, y, entries, scale=1):
    """A framed legend at (x, y) (its top left): one row per (name, rgb, dashed)
    with a sample line (dashed as the plot's levels: DASH, DASH_PERIOD) and the
    name, both in its colour."""
    w, h = legend_size([name for name, _, _ in entries], scale)
    pad = PAD * scale
    img[y:y + h, x:x + w, :3] = 1.0
    img[y, x:x + w, :3] = img[y + h - 1, x:x + w, :3] = 0.6
    img[y:y + h, x, :3] = img[y:y + h, x + w - 1, :3] = 0.6
    for i, (name, rgb, dashed) in enumerate(entries):
        top = y + pad + i * font.LINE_H * scale
        mid = top + font.GLYPH_H * scale // 2
        sx = x + pad
        sample = img[mid - scale:mid + scale, sx:sx + SAMPLE * scale, :3]
        if dashed:
            for start in range(0, sample.shape[1], DASH_PERIOD * scale):
                sample[:, start:start + DASH * scale] = rgb
        else:
            sample[:] = rgb
        font.draw_text(img, name, sx + SAMPLE * scale + pad, top, rgb, scale)
    return w, h

# SPDX-License-Identifier: GPL-3.0-or-later
"""The K sweep's plot, drawn with numpy (Blender's Python has no plotting
library): render time against K as % of kd's, one line per method, with
axes, a grid, a title and a legend naming each method in its colour."""

import numpy as np

from ..drawing import bitmap_font, legend


class PlotError(Exception):
    """A plot that cannot be drawn (experiment.py says it is the K sweep's)."""


# Line colours of the plot; the panel names them beside each method.
COLOURS = (
    ("blue", (0.12, 0.47, 0.71)),
    ("orange", (1.0, 0.5, 0.05)),
    ("green", (0.17, 0.63, 0.17)),
    ("red", (0.84, 0.15, 0.16)),
    ("purple", (0.58, 0.4, 0.74)),
    ("brown", (0.55, 0.34, 0.29)),
    ("pink", (0.89, 0.47, 0.76)),
    ("olive", (0.74, 0.74, 0.13)),
)


def _line(img, x0, y0, x1, y1, colour, width=2):
    n = int(max(abs(x1 - x0), abs(y1 - y0))) + 1
    xs = np.linspace(x0, x1, n).round().astype(int)
    ys = np.linspace(y0, y1, n).round().astype(int)
    h, w = img.shape[:2]
    for dx in range(-(width // 2), width - width // 2):
        for dy in range(-(width // 2), width - width // 2):
            xx, yy = np.clip(xs + dx, 0, w - 1), np.clip(ys + dy, 0, h - 1)
            img[yy, xx, :3] = colour


def _dot(img, x, y, colour, r=3):
    h, w = img.shape[:2]
    y0, y1, x0, x1 = max(0, y - r), min(h, y + r + 1), max(0, x - r), min(w, x + r + 1)
    img[y0:y1, x0:x1, :3] = colour


TITLE = "Render time against K, % of kd's"
MARGIN_LEFT, MARGIN_RIGHT, MARGIN_TOP, MARGIN_BOTTOM = 44, 10, 22, 34
AXIS, GRID, INK = (0.2,) * 3, (0.88,) * 3, (0.1,) * 3


def _tick_step(span, most):
    """The smallest of 1, 2, 5, 10, 20, 50, ... whose ticks over `span` are at most `most`."""
    step = 1
    while span / step > most:
        step = step * 5 // 2 if str(step).startswith("2") else step * 2
    return step


def _value_range(series, flat):
    """The plot's y range [v_lo, v_hi]: every value and kd's 100 %, on 10 % lines."""
    values = [p["pct_kd"] for _, pts in series for p in pts] + [v for _, v in flat] + [100.0]
    return 10 * np.floor(min(values) / 10 - 0.5), 10 * np.ceil(max(values) / 10 + 0.5)


def _legend_entries(table):
    """(name, rgb, dashed) per method: a line over K, or a dashed level (kd,
    and methods without K)."""
    rgb = dict(COLOURS)
    return [(m["name"], rgb[m["colour"]],
             not m["points"] or m["points"][0]["k"] is None) for m in table["methods"]]


def plot(table, width, height):
    """Render time (% of kd) against K, one line per method; row 0 is the top.
    Axes with tick labels (K below, % of kd on the left), a title, a grid, and
    a legend naming each method in its colour on the right; kd's 100 % and
    the methods without K are dashed levels."""
    img = np.ones((height, width, 4), dtype=np.float32)
    series = [(m, [p for p in m["points"] if p["k"] is not None]) for m in table["methods"]]
    flat = [(m, m["points"][0]["pct_kd"]) for m in table["methods"]
            if m["points"] and m["points"][0]["k"] is None]
    ks = [p["k"] for _, pts in series for p in pts]
    k_lo, k_hi = (min(ks), max(ks)) if ks else (0, 1)
    if k_hi == k_lo:
        k_lo, k_hi = k_lo - 1, k_hi + 1
    v_lo, v_hi = _value_range(series, flat)
    entries = _legend_entries(table)
    legend_w, _ = legend.legend_size([name for name, _, _ in entries])
    left, right = MARGIN_LEFT, width - MARGIN_RIGHT - legend_w - 8
    top, bottom = MARGIN_TOP, height - MARGIN_BOTTOM
    if right - left < 40:
        raise PlotError("the Sweep K plot is too narrow for its legend")

    def xy(k, v):
        x = left + (k - k_lo) / (k_hi - k_lo) * (right - left)
        y = bottom - (v - v_lo) / (v_hi - v_lo) * (bottom - top)
        return int(round(x)), int(round(y))

    _axes(img, xy, (k_lo, k_hi), (v_lo, v_hi), (left, top, right, bottom))
    for m, v in flat:  # kd and the methods without K: dashed levels in their colour
        y, c = xy(k_lo, v)[1], dict(COLOURS)[m["colour"]]
        for x in range(left, right, legend.DASH_PERIOD):  # 2 px thick, as _line
            img[y - 1:y + 1, x:min(x + legend.DASH, right), :3] = c
    for m, pts in series:
        c = dict(COLOURS)[m["colour"]]
        for a, b in zip(pts, pts[1:]):
            _line(img, *xy(a["k"], a["pct_kd"]), *xy(b["k"], b["pct_kd"]), c)
        for p in pts:
            _dot(img, *xy(p["k"], p["pct_kd"]), c)
    legend.draw_legend(img, right + 8, top, entries)
    bitmap_font.draw_text(img, TITLE, (left + right) // 2, 6, INK, anchor="centre")
    img[..., 3] = 1.0
    table["plot_axes"] = {"k": [int(k_lo), int(k_hi)], "pct_kd": [float(v_lo), float(v_hi)]}
    return img


def _axes(img, xy, k_range, v_range, box):
    """Grid, axes, tick marks and tick labels, and the axis titles."""
    (k_lo, k_hi), (v_lo, v_hi), (left, top, right, bottom) = k_range, v_range, box
    v_step = 10 * _tick_step((v_hi - v_lo) / 10, 8)
    for v in np.arange(v_lo, v_hi + 1e-9, v_step):
        y = xy(k_lo, v)[1]
        _line(img, left, y, right, y, GRID, 1)
        _line(img, left - 3, y, left, y, AXIS, 1)
        bitmap_font.draw_text(img, "{:.0f}%".format(v), left - 5, y - 3, INK, anchor="right")
    k_step = _tick_step(k_hi - k_lo, 12)
    for k in range(int(k_lo), int(k_hi) + 1):
        x = xy(k, v_lo)[0]
        _line(img, x, top, x, bottom, GRID, 1)
        if k % k_step == 0:
            _line(img, x, bottom, x, bottom + 3, AXIS, 1)
            bitmap_font.draw_text(img, str(k), x, bottom + 6, INK, anchor="centre")
    _line(img, left, bottom, right, bottom, AXIS, 1)
    _line(img, left, top, left, bottom, AXIS, 1)
    bitmap_font.draw_text(img, "K", (left + right) // 2, bottom + 18, INK, anchor="centre")

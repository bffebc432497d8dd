"""The add-on's text and legends in its images (addon/drawing/bitmap_font.py,
addon/drawing/legend.py, the K sweep's plot of addon/k_sweep/plot.py) and its
report of a cancelled job, without Blender: the modules touch no bpy and are
imported as submodules of a package whose path is the addon folder
(addon_without_blender.py)."""

import numpy as np
import pytest

import bsplab
from bsplab.render import heat_ramp

from addon_without_blender import addon_module as _addon_module


font = _addon_module("drawing.bitmap_font")
legend = _addon_module("drawing.legend")
experiment = _addon_module("k_sweep.experiment")
plot = _addon_module("k_sweep.plot")
jobs = _addon_module("build_render.job")
worker = _addon_module("jobs.worker")

INK = (1.0, 0.0, 0.0)


def _canvas(h=40, w=120):
    img = np.zeros((h, w, 4), np.float32)
    img[..., 3] = 1
    return img


def _ink(img, rgb=INK, tol=0.02):
    return np.all(np.abs(img[..., :3] - np.array(rgb, np.float32)) < tol, axis=-1)


def _read(img, x0, y0, x1, y1, rgb, scale=1):
    """The text drawn in the box, read back by matching each glyph cell."""
    mask = _ink(img[y0:y1, x0:x1], rgb)[::scale, ::scale]
    out = []
    for i in range(0, mask.shape[1] + 1, font.ADVANCE):
        cell = mask[:, i:i + font.GLYPH_W]
        if cell.shape[1] < font.GLYPH_W:
            break
        matches = [c for c, g in font.GLYPHS.items() if np.array_equal(g, cell)]
        out.append(matches[0] if matches else "?")
    return "".join(out)


def test_every_glyph_is_distinct_and_inked():
    seen = {}
    for ch, g in font.GLYPHS.items():
        assert g.shape == (font.GLYPH_H, font.GLYPH_W), ch
        assert g.any() or ch == " ", ch
        key = g.tobytes()
        assert key not in seen, (ch, seen.get(key))
        seen[key] = ch


@pytest.mark.parametrize("scale", [1, 2])
def test_text_is_drawn_inside_its_box_only(scale):
    img = _canvas(60, 300)
    x0, y0, x1, y1 = font.draw_text(img, "K=13 bsp_wn+kd 97.5%", 7, 5, INK, scale)
    assert (x1 - x0, y1 - y0) == font.text_size("K=13 bsp_wn+kd 97.5%", scale)
    ink = _ink(img)
    assert ink[y0:y1, x0:x1].sum() > 50 * scale * scale
    ink[y0:y1, x0:x1] = False
    assert not ink.any(), "ink outside the text's box"
    assert _read(img, x0, y0, x1, y1, INK, scale) == "K=13 BSP_WN+KD 97.5%"


def test_anchors_and_clipping():
    img = _canvas()
    box = font.draw_text(img, "120%", 100, 2, INK, anchor="right")
    assert box[2] == 100 and _read(img, *box, INK) == "120%"
    box = font.draw_text(img, "K", 60, 20, INK, anchor="centre")
    assert box[0] <= 60 < box[2]
    # Half outside the image: clipped, no error, nothing wraps around.
    font.draw_text(img, "WIDE TEXT", 110, 35, INK)
    assert not _ink(img)[:, :100][35:].any()
    with pytest.raises(ValueError, match="anchor"):
        font.draw_text(img, "x", 0, 0, INK, anchor="middle")


def test_unknown_characters_are_drawn_as_question_marks():
    img = _canvas()
    box = font.draw_text(img, "a€b", 2, 2, INK)
    assert _read(img, *box, INK) == "A?B"


def _heat_stats(mode, largest):
    key = legend.HEAT_UNITS[mode][0]
    return {"mode": mode, key: largest}


@pytest.mark.parametrize("mode,largest", [("heat_steps", 57), ("heat_tests", 3),
                                          ("heat_culled", 0)])
def test_heat_preview_gets_its_colour_bar(mode, largest):
    render = np.random.default_rng(1).random((30, 40, 4)).astype(np.float32)
    out = legend.with_heat_bar(render, mode, _heat_stats(mode, largest), heat_ramp)
    # The render's pixels are untouched at the top left.
    assert np.array_equal(out[:30, :40], render)
    strip = out[30:]
    top = max(largest, 1)
    # The bar: its first and last columns are the ramp's end colours.
    bar_rows = np.flatnonzero(np.all(np.abs(strip[:, :, :3] - heat_ramp(np.float32(0.0)))
                                     < 1e-5, axis=-1).any(axis=1))
    assert len(bar_rows) > 0
    row = strip[bar_rows[0], :, :3]
    first = np.flatnonzero(np.all(np.abs(row - heat_ramp(np.float32(0.0))) < 1e-5, axis=-1))
    last = np.flatnonzero(np.all(np.abs(row - heat_ramp(np.float32(1.0))) < 1e-5, axis=-1))
    assert len(first) and len(last) and first[0] < last[-1]
    # The labels: 0 left of the bar, the true maximum right of it, then the unit.
    pad = legend.PAD
    text_h = font.GLYPH_H
    w_max = font.text_size(str(top))[0]
    width = out.shape[1]
    assert _read(strip, pad, pad, pad + 5, pad + text_h, legend.TEXT) == "0"
    assert _read(strip, width - pad - w_max, pad, width - pad, pad + text_h,
                 legend.TEXT) == str(top)
    caption = legend.HEAT_UNITS[mode][1]
    cw = font.text_size(caption)[0]
    cx0 = width // 2 - cw // 2
    assert _read(strip, cx0, 2 * pad + text_h, cx0 + cw, 2 * pad + 2 * text_h,
                 legend.TEXT) == caption.upper()


def test_other_modes_are_unchanged_and_missing_maximum_is_refused():
    img = np.zeros((4, 4, 4), np.float32)
    assert legend.with_heat_bar(img, "shaded", {}, heat_ramp) is img
    with pytest.raises(ValueError, match="max_tests"):
        legend.with_heat_bar(img, "heat_tests", {"max_tests": None}, heat_ramp)


def test_bar_of_a_real_heat_render_is_labelled_with_its_largest_count():
    from bsplab import scenes
    tree = bsplab.build(scenes.generate("room"), method="kd")
    image, stats = bsplab.render(tree, scenes.default_camera("room"), 48, 32, "heat_culled")
    assert stats["max_culled"] > 0  # leaf culling skipped some tests in the room
    out = legend.with_heat_bar(image, "heat_culled", stats, heat_ramp)
    assert out.shape[0] > 32 and np.array_equal(out[:32, :48], image)
    # The image's hottest pixel has the ramp's last colour: the bar's right end.
    assert np.all(np.abs(image[..., :3] - heat_ramp(np.float32(1.0))) < 1e-5, axis=-1).any()


def _table():
    def pts(values, ks):
        return [{"k": k, "pct_kd": v, "tests": 1.0, "steps": 2.0} for k, v in zip(ks, values)]
    methods = [
        {"name": "kd", "points": pts([100.0], [None])},
        {"name": "bsp_wn+kd", "points": pts([97.0, 88.0, 104.0], [3, 4, 5])},
        {"name": "bsp_ize+kd", "points": pts([120.0], [None])},
    ]
    for i, m in enumerate(methods):
        m["colour"] = plot.COLOURS[i][0]
    return {"methods": methods}


def test_sweep_plot_has_axes_ticks_title_and_a_legend_in_each_colour():
    table = _table()
    w, h = experiment.PLOT_SIZE
    img = plot.plot(table, w, h)
    colours = dict(plot.COLOURS)
    # The legend: each method's name in its colour, in order, right of the plot.
    entries = [(m["name"], colours[m["colour"]]) for m in table["methods"]]
    lw, _ = legend.legend_size([n for n, _ in entries])
    lx, ly = w - plot.MARGIN_RIGHT - lw, plot.MARGIN_TOP
    for i, (name, rgb) in enumerate(entries):
        tx = lx + 2 * legend.PAD + legend.SAMPLE
        ty = ly + legend.PAD + i * font.LINE_H
        tw = font.text_size(name)[0]
        assert _read(img, tx, ty, tx + tw, ty + font.GLYPH_H, rgb) == name.upper()
        # and the data in that colour inside the plot area
        assert _ink(img[:, :lx], rgb).sum() > 20, name
    axes = table["plot_axes"]
    assert axes["k"] == [3, 5]
    assert axes["pct_kd"][0] <= 88 and axes["pct_kd"][1] >= 120
    # The x tick labels 3, 4, 5 and the y tick labels are in the image's ink.
    ink = _ink(img, plot.INK)
    below = ink[h - plot.MARGIN_BOTTOM + 2:]
    assert below.sum() > 3 * 8  # three K labels and the axis title "K"
    assert ink[:, :plot.MARGIN_LEFT].sum() > 40  # the % labels
    assert ink[:plot.MARGIN_TOP].sum() > 100  # the title


def _runs(mask):
    """Lengths of the runs of True and of False along a 1-D mask."""
    edges = np.flatnonzero(np.diff(mask.astype(np.int8))) + 1
    return [len(r) for r in np.split(mask, edges)], bool(mask[0])


def test_legend_dashes_like_the_plots_levels():
    # kd's level is drawn dashed in the plot; its legend sample must show the
    # same dashes (it once showed dots), and a solid entry a solid line.
    img = _canvas(60, 200)
    legend.draw_legend(img, 0, 0, [("kd", INK, True), ("bsp", (0.0, 0.0, 1.0), False)])
    mid = legend.PAD + font.GLYPH_H // 2
    x0 = legend.PAD
    dashed = _ink(img)[mid, x0:x0 + legend.SAMPLE]
    runs, starts_inked = _runs(dashed)
    assert starts_inked and runs[0] == legend.DASH
    assert runs[1] == legend.DASH_PERIOD - legend.DASH
    solid = _ink(img, (0.0, 0.0, 1.0))[mid + font.LINE_H, x0:x0 + legend.SAMPLE]
    assert solid.all()
    # The plot's kd level: the same dash and gap lengths along its row.
    table = _table()
    w, h = experiment.PLOT_SIZE
    image = plot.plot(table, w, h)
    kd = next(m for m in table["methods"] if m["name"] == "kd")
    row = _ink(image, dict(plot.COLOURS)[kd["colour"]])[:, plot.MARGIN_LEFT + 1:w // 2]
    y = int(np.argmax(row.sum(axis=1)))
    runs, _ = _runs(row[y])
    assert legend.DASH in runs[1:-1] and legend.DASH_PERIOD - legend.DASH in runs[1:-1]


def test_tick_step():
    assert [plot._tick_step(s, 8) for s in (5, 8, 9, 30, 70, 200)] == [1, 1, 2, 5, 10, 50]


@pytest.mark.parametrize("job_class,words", [(jobs.Job, "Build & Render cancelled"),
                                             (experiment.KSweepJob, "Sweep K cancelled")])
def test_a_cancel_is_reported_as_information(job_class, words):
    job = job_class(bsplab, None)  # never started: only its report is read
    job.error = bsplab.Cancelled("cancelled")
    level, message = worker.failure_report(job)
    assert level == 'INFO' and words in message
    job.error = ValueError("bad K")
    level, message = worker.failure_report(job)
    assert level == 'ERROR' and "bad K" in message

# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Sweep K" experiment on the current scene.

The core lab's sweep (`bsplab.lab.sweep_k`) runs in this process on the
scene's own triangles and camera: every chosen method at every K of the
range, each tree traced `repetitions` times beside Embree (where Embree can
run here), kd always included as the reference. The result is a small table
(render time as % of kd, tests per ray) and a plot drawn into an image
block. Like Build & Render, it reads bpy on the main thread only.
"""

import importlib
import json
from dataclasses import dataclass

import numpy as np

from . import camera, jobs

PLOT_NAME = "BSP Lab Sweep K"
PLOT_SIZE = (480, 300)
MAX_CELLS = 200  # a sweep larger than this belongs in `python -m bsplab experiment`
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


class SweepError(Exception):
    """A sweep that cannot run; the message is for the user."""


@dataclass
class SweepInput:
    triangles: np.ndarray
    camera: "camera.CameraSpec"  # a string: the core (and its CameraSpec) may be missing
    methods: list
    k_min: int
    k_max: int
    repetitions: int
    workload: str
    scene_name: str


def parse_methods(text, known):
    """The methods named in `text` (spaces or commas), kd first; raise SweepError."""
    names = [n for n in text.replace(",", " ").split() if n]
    unknown = [n for n in names if n not in known]
    if unknown:
        raise SweepError("Unknown method(s) {} for Sweep K; known: {}".format(
            ", ".join(unknown), ", ".join(known)))
    if not names:
        raise SweepError("Sweep K needs at least one method")
    # kd is the reference every percentage is taken against.
    return ["kd"] + [n for n in dict.fromkeys(names) if n != "kd"]


def plan(methods, known, k_min, k_max):
    """{method: [K, ...]} of the sweep (K below a method's minimum is left out)."""
    if k_min > k_max:
        raise SweepError("K range is empty: from {} to {}".format(k_min, k_max))
    out = {}
    for m in methods:
        info = known[m]
        if "k" not in info.get("params", ()):
            out[m] = [None]
            continue
        ks = [k for k in range(k_min, k_max + 1) if info["min_k"] <= k <= info["max_k"]]
        if not ks:
            raise SweepError("{} takes K from {} to {}: none in {}..{}".format(
                m, info["min_k"], info["max_k"], k_min, k_max))
        out[m] = ks
    cells = sum(len(ks) for ks in out.values())
    if cells > MAX_CELLS:
        raise SweepError("Sweep K would build {} trees (at most {} here); narrow the K "
                         "range or the methods, or run `python -m bsplab experiment`".format(
                             cells, MAX_CELLS))
    return out


class SweepJob(jobs.WorkerJob):
    """Runs the sweep on a worker thread."""

    title = "Sweeping K"

    def __init__(self, core, inp):
        super().__init__(core, inp)
        self.progress = core.Progress()
        self._done, self._total = 0, 1

    def _on_progress(self, done, total, _label):
        self._done, self._total = done, total
        self.progress.reset()  # the next cell's fraction; reset() also clears a cancel...
        if self.cancelled:     # ...so a cancel that came meanwhile is set again
            self.progress.cancel()

    def _compute(self):
        core, inp = self.core, self.input
        lab = importlib.import_module(core.__name__ + ".lab")  # its one public entry
        ks = plan(inp.methods, core.methods(), inp.k_min, inp.k_max)
        rows = lab.sweep_k(inp.triangles, core.Camera(**inp.camera.kwargs()), inp.methods, ks,
                           repetitions=inp.repetitions, workload=inp.workload,
                           width=inp.camera.width, height=inp.camera.height,
                           scene_name=inp.scene_name, progress=self.progress,
                           on_progress=self._on_progress)
        table = summarise(lab, rows, inp.methods)
        table["scene"] = {"triangles": len(inp.triangles), "rays": int(rows[0]["rays"]),
                          "workload": inp.workload, "repetitions": inp.repetitions}
        return {"table": table, "plot": plot(table, *PLOT_SIZE)}

    def cancel(self):
        super().cancel()
        self.progress.cancel()

    def fraction(self):
        return min(1.0, (self._done + 0.9 * self.progress.value) / max(1, self._total))


def summarise(lab, rows, methods):
    """The lab's table of the sweep, each method with its plot colour."""
    table = lab.sweep_table(rows, methods)
    for i, m in enumerate(table["methods"]):
        m["colour"] = COLOURS[i % len(COLOURS)][0]
    return table


# -----------------------------------------------------------------------------
# The plot: drawn with numpy (Blender's Python has no plotting library)


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


def plot(table, width, height):
    """Render time (% of kd) against K, one line per method; row 0 is the top.
    Grey lines: the kd level (100 %, dashed look) and a grid every 10 %."""
    img = np.ones((height, width, 4), dtype=np.float32)
    series = [(m, [p for p in m["points"] if p["k"] is not None]) for m in table["methods"]]
    flat = [(m, m["points"][0]["pct_kd"]) for m in table["methods"]
            if m["name"] != "kd" and m["points"] and m["points"][0]["k"] is None]
    ks = [p["k"] for _, pts in series for p in pts]
    values = [p["pct_kd"] for _, pts in series for p in pts] + [v for _, v in flat] + [100.0]
    k_lo, k_hi = (min(ks), max(ks)) if ks else (0, 1)
    if k_hi == k_lo:
        k_lo, k_hi = k_lo - 1, k_hi + 1
    v_lo = 10 * np.floor(min(values) / 10 - 0.5)
    v_hi = 10 * np.ceil(max(values) / 10 + 0.5)
    margin = 24

    def xy(k, v):
        x = margin + (k - k_lo) / (k_hi - k_lo) * (width - 2 * margin)
        y = height - margin - (v - v_lo) / (v_hi - v_lo) * (height - 2 * margin)
        return int(round(x)), int(round(y))

    for v in np.arange(v_lo, v_hi + 1e-9, 10):
        _line(img, margin, xy(k_lo, v)[1], width - margin, xy(k_lo, v)[1], (0.88,) * 3, 1)
    for k in range(int(k_lo), int(k_hi) + 1):
        _line(img, xy(k, 0)[0], margin, xy(k, 0)[0], height - margin, (0.93,) * 3, 1)
    _line(img, margin, height - margin, width - margin, height - margin, (0.2,) * 3, 1)
    _line(img, margin, margin, margin, height - margin, (0.2,) * 3, 1)
    y100 = xy(k_lo, 100.0)[1]
    for x in range(margin, width - margin, 12):  # kd: dashed
        _line(img, x, y100, min(x + 6, width - margin), y100, (0.1,) * 3, 2)
    rgb = dict(COLOURS)
    for m, v in flat:  # methods without K: dotted levels in their colour
        y = xy(k_lo, v)[1]
        for x in range(margin, width - margin, 8):
            _dot(img, x, y, rgb[m["colour"]], 1)
    for m, pts in series:
        if m["name"] == "kd":
            continue
        c = rgb[m["colour"]]
        for a, b in zip(pts, pts[1:]):
            _line(img, *xy(a["k"], a["pct_kd"]), *xy(b["k"], b["pct_kd"]), c)
        for p in pts:
            _dot(img, *xy(p["k"], p["pct_kd"]), c)
    img[..., 3] = 1.0
    table["plot_axes"] = {"k": [int(k_lo), int(k_hi)], "pct_kd": [float(v_lo), float(v_hi)]}
    return img


def table_json(result):
    return json.dumps(result["table"])

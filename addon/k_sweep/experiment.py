# SPDX-License-Identifier: GPL-3.0-or-later
"""The K sweep ("Sweep K" in the panel) on the current scene, without bpy.

The lab's K sweep (`bsplab.lab.sweep_k`) runs in this process on the
scene's own triangles and camera: every chosen method at every K of the
range, each tree traced `repetitions` times beside Embree (where Embree can
run here), kd always included as the reference. The result is a small table
(render time as % of kd, tests per ray) and a plot drawn into an image
block (plot.py). Like Build & Render, it reads bpy on the main thread only
(operator.py).
"""

import json
from dataclasses import dataclass

import numpy as np

from .. import backend
from ..jobs.worker import WorkerJob
from . import plot

PLOT_NAME = "BSP Lab Sweep K"
PLOT_SIZE = (600, 320)
MAX_CELLS = 200  # a sweep larger than this belongs in `python -m bsplab experiment`
class KSweepError(Exception):
    """A K sweep that cannot run; the message is for the user."""


@dataclass
class KSweepInput:
    triangles: np.ndarray
    camera: object  # a CameraSpec (bsplab.blender.scene_camera): kwargs(), width, height
    methods: list
    k_min: int
    k_max: int
    repetitions: int
    workload: str
    scene_name: str


def parse_methods(text, known):
    """The methods named in `text` (spaces or commas), kd first; raise KSweepError."""
    names = [n for n in text.replace(",", " ").split() if n]
    unknown = [n for n in names if n not in known]
    if unknown:
        raise KSweepError("Unknown method(s) {} for Sweep K; known: {}".format(
            ", ".join(unknown), ", ".join(known)))
    if not names:
        raise KSweepError("Sweep K needs at least one method")
    # kd is the reference every percentage is taken against.
    return ["kd"] + [n for n in dict.fromkeys(names) if n != "kd"]


def plan(methods, known, k_min, k_max):
    """{method: [K, ...]} of the sweep (K below a method's minimum is left out)."""
    if k_min > k_max:
        raise KSweepError("K range is empty: from {} to {}".format(k_min, k_max))
    out = {}
    for m in methods:
        info = known[m]
        if "k" not in info.get("params", ()):
            out[m] = [None]
            continue
        ks = [k for k in range(k_min, k_max + 1) if info["min_k"] <= k <= info["max_k"]]
        if not ks:
            raise KSweepError("{} takes K from {} to {}: none in {}..{}".format(
                m, info["min_k"], info["max_k"], k_min, k_max))
        out[m] = ks
    cells = sum(len(ks) for ks in out.values())
    if cells > MAX_CELLS:
        raise KSweepError("Sweep K would build {} trees (at most {} here); narrow the K "
                         "range or the methods, or run `python -m bsplab experiment`".format(
                             cells, MAX_CELLS))
    return out


class KSweepJob(WorkerJob):
    """Runs the K sweep on a worker thread."""

    title = "Sweeping K"
    cancelled_message = "BSP Lab: Sweep K cancelled; the previous table and plot are unchanged"

    def __init__(self, bsplab, inp):
        super().__init__(bsplab, inp)
        self.progress = bsplab.Progress()
        self._done, self._total = 0, 1

    def _on_progress(self, done, total, _label):
        self._done, self._total = done, total
        self.progress.reset()  # the next cell's fraction; reset() also clears a cancel...
        if self.cancelled:     # ...so a cancel that came meanwhile is set again
            self.progress.cancel()

    def _compute(self):
        bsplab, inp = self.bsplab, self.input
        lab = backend.lab()
        ks = plan(inp.methods, bsplab.methods(), inp.k_min, inp.k_max)
        rows = lab.sweep_k(inp.triangles, bsplab.Camera(**inp.camera.kwargs()), inp.methods, ks,
                           repetitions=inp.repetitions, workload=inp.workload,
                           width=inp.camera.width, height=inp.camera.height,
                           scene_name=inp.scene_name, progress=self.progress,
                           on_progress=self._on_progress)
        table = summarise(lab, rows, inp.methods)
        table["scene"] = {"triangles": len(inp.triangles), "rays": int(rows[0]["rays"]),
                          "workload": inp.workload, "repetitions": inp.repetitions}
        try:
            image = plot.plot(table, *PLOT_SIZE)
        except plot.PlotError as ex:
            raise KSweepError(str(ex)) from ex
        return {"table": table, "plot": image}

    def cancel(self):
        super().cancel()
        self.progress.cancel()

    def fraction(self):
        return min(1.0, (self._done + 0.9 * self.progress.value) / max(1, self._total))


def summarise(lab, rows, methods):
    """The lab's table of the sweep, each method with its plot colour."""
    table = lab.sweep_table(rows, methods)
    for i, m in enumerate(table["methods"]):
        m["colour"] = plot.COLOURS[i % len(plot.COLOURS)][0]
    return table


def table_json(result):
    return json.dumps(result["table"])

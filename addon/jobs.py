# SPDX-License-Identifier: GPL-3.0-or-later
"""Jobs that run on a worker thread and report back to the main thread.

Nothing here touches bpy: the operators copy the scene into numpy arrays and
plain values first (`JobInput`), a job computes on a worker thread (the core
releases the GIL, so Blender stays responsive) and the main thread then reads
`result` or `error`. That split is also what lets the tests run a job without
Blender (core/tests/test_addon_jobs.py).
"""

import threading
import time
from dataclasses import dataclass

import numpy as np

from . import backend, tree_cache


class UserError(Exception):
    """An error with a message meant for the user's eyes."""


class WorkerJob:
    """Base of the worker jobs: subclasses compute without touching bpy
    (`_compute`), say how far they are (`fraction`) and stop when asked
    (`cancel`); the operator polls `is_alive` and, once done, reads `result`
    or `error` on the main thread."""

    title = "Working"
    # Reported (as information, not an error) when the user cancelled the job.
    cancelled_message = "BSP Lab: cancelled"

    def __init__(self, core, inp):
        self.core = core
        self.input = inp
        self.cancelled = False
        self.result = None
        self.error = None
        self._thread = None

    def _compute(self):
        raise NotImplementedError

    def run(self):
        try:
            self.result = self._compute()
        except BaseException as ex:  # Reported on the main thread.
            self.error = ex

    def start(self):
        # Daemon: quitting Blender mid-job must not wait for the core.
        self._thread = threading.Thread(target=self.run, name="BSP Lab: " + self.title,
                                        daemon=True)
        self._thread.start()

    def is_alive(self):
        return self._thread is not None and self._thread.is_alive()

    def join(self, timeout=None):
        if self._thread is not None:
            self._thread.join(timeout)

    def cancel(self):
        self.cancelled = True

    def fraction(self):
        return 0.0


@dataclass
class JobInput:
    """Everything Build & Render needs, copied out of bpy."""

    triangles: np.ndarray  # (N, 3, 3) float32, world space
    objects: int
    instances: int
    camera: object  # a CameraSpec: kwargs() for bsplab.Camera, width, height, name
    method: str
    options: dict
    mode: str
    threads: int
    cull: bool
    compare_with_embree: bool
    # The panel's Steps / Tests per Ray. Off, the hits-only modes render in
    # packets; the heat maps count whatever it says.
    count_steps: bool
    scene_name: str


def make_camera(core, spec):
    return core.Camera(**spec.kwargs())


def foreign_embree_library():
    """Name of an Embree library the host exports that clashes with embreex, if
    any (see `bsplab.oracle.foreign_embree_library`)."""
    return backend.import_core().oracle.foreign_embree_library()


def compare_with_embree(core, tree, cam, inp, embree_scene=None):
    """Trace the camera rays with the tree and with Embree; compare the hits.

    `embree_scene(triangles)` gives the Embree tracer and whether it was
    re-used (Job's, from its cache); by default a new one is built."""
    oracle = core.oracle
    try:
        import embreex  # noqa: F401  (the oracle imports it when tracing)
    except ImportError as ex:
        return {"available": False,
                "message": "embreex is not installed, comparison skipped ({})".format(ex)}
    clash = oracle.foreign_embree_library()
    if clash is not None:
        return {"available": False,
                "message": "Embree comparison unavailable: this Blender exports its own {}, "
                           "which clashes with embreex's Embree".format(clash)}
    origins, directions = cam.rays(inp.camera.width, inp.camera.height)
    start = time.perf_counter()
    # The same work on both sides: hits only, on one thread (embreex traces
    # its rays one by one on one thread), so the ratio compares the trees and
    # kernels, not the core counts.
    ours = tree.intersect(origins, directions, threads=1, cull=inp.cull, counters=False)
    bsplab_seconds = time.perf_counter() - start
    if embree_scene is None:
        tracer, reused = oracle.EmbreeTracer(tree.triangles), False
    else:
        tracer, reused = embree_scene(tree.triangles)
    start = time.perf_counter()
    theirs = tracer.intersect(origins, directions)
    embree_seconds = time.perf_counter() - start
    compare = oracle.compare(ours, theirs, triangles=tree.triangles,
                             origins=origins, directions=directions)
    return {
        "available": True,
        "bsplab_seconds": bsplab_seconds,
        "embree_seconds": embree_seconds,
        # When re-used: the build time of the press that built it.
        "embree_build_seconds": getattr(tracer, "build_seconds", None),
        "embree_reused": reused,
        # How many times longer the tree takes than Embree for the same rays.
        "time_ratio": bsplab_seconds / embree_seconds if embree_seconds > 0 else None,
        # Only the counts: the per-ray index arrays are of no use in the panel.
        "compare": {k: v for k, v in plain(compare).items() if not isinstance(v, (list, str))},
    }


def plain(value):
    """Make core results JSON-friendly (numpy scalars and arrays included)."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist() if value.size <= 16 else "array{}".format(value.shape)
    if isinstance(value, np.generic):
        return value.item()
    return value


class Job(WorkerJob):
    """Build & Render: build the tree (or re-use the cache's), render the
    camera's view, optionally compare the camera rays' hits with Embree's.

    With a `cache` (a tree_cache.TreeCache; the add-on passes its one), the
    tree of the previous press is re-used while the triangles, the method and
    the options that change the tree are the same, and the tree built here is
    kept for the next press. Without one, every job builds.
    """

    title = "Building & Rendering"
    cancelled_message = "BSP Lab: Build & Render cancelled; the previous preview is unchanged"

    def __init__(self, core, inp, cache=None):
        super().__init__(core, inp)
        self.build_progress = core.Progress()
        self.render_progress = core.Progress()
        self.cache = cache
        # Read now, on the main thread: a clear() after this (a file loaded
        # while the job runs) makes the cache refuse what the job would keep.
        self._generation = cache.generation() if cache is not None else None
        self._key = None
        self.reused = False
        self.fingerprint_seconds = None

    def _check_cancelled(self):
        if self.cancelled:
            raise self.core.Cancelled("cancelled")

    def _tree(self):
        """The cache's tree when it was built for this input, else a new one."""
        core, inp = self.core, self.input
        if self.cache is not None:
            start = time.perf_counter()
            self._key = tree_cache.tree_key(inp.triangles, inp.method, inp.options)
            self.fingerprint_seconds = time.perf_counter() - start
            tree = self.cache.tree(self._key)
            if tree is not None:
                self.reused = True
                return tree
        tree = core.build(inp.triangles, method=inp.method,
                          progress=self.build_progress, **inp.options)
        if self.cache is not None:
            # Kept before rendering: a cancelled render leaves a good tree.
            self.cache.keep_tree(self._key, tree, self._generation)
        return tree

    def _embree_scene(self, triangles):
        """The Embree tracer of the triangles and whether it was re-used."""
        geometry = self._key.geometry
        tracer = self.cache.embree(geometry)
        if tracer is not None:
            return tracer, True
        tracer = self.core.oracle.EmbreeTracer(triangles)
        self.cache.keep_embree(geometry, tracer, self._generation)
        return tracer, False

    def _compute(self):
        core, inp = self.core, self.input
        cam = make_camera(core, inp.camera)
        self._check_cancelled()
        tree = self._tree()
        self._check_cancelled()
        image, render_stats = core.render(tree, cam, inp.camera.width, inp.camera.height,
                                          mode=inp.mode, threads=inp.threads,
                                          cull=inp.cull or inp.mode == "heat_culled",
                                          # The panel's Steps / Tests per Ray: counted
                                          # in the same trace, or None: render()'s
                                          # default (packets where the mode allows).
                                          counters=True if inp.count_steps else None,
                                          progress=self.render_progress)
        self._check_cancelled()
        render_stats = dict(render_stats, width=inp.camera.width, height=inp.camera.height,
                            mode=inp.mode, camera=inp.camera.name)
        stats = {
            "scene": {"triangles": len(inp.triangles), "objects": inp.objects,
                      "instances": inp.instances},
            # A re-used tree's own statistics, build_seconds included: the
            # time of the press that built it.
            "build": dict(tree.stats, reused=self.reused,
                          fingerprint_seconds=self.fingerprint_seconds),
            "render": render_stats,
        }
        if inp.compare_with_embree:
            embree_scene = self._embree_scene if self.cache is not None else None
            stats["embree"] = compare_with_embree(core, tree, cam, inp, embree_scene)
            self._check_cancelled()
        return {"image": np.asarray(image, dtype=np.float32), "stats": plain(stats)}

    def cancel(self):
        super().cancel()
        self.build_progress.cancel()
        self.render_progress.cancel()

    def fraction(self):
        if self.reused:
            return self.render_progress.value
        # Building usually dominates; weigh it accordingly.
        return min(1.0, 0.6 * self.build_progress.value + 0.4 * self.render_progress.value)


def error_message(core, ex):
    """The user's message for an exception raised by a job."""
    if isinstance(ex, UserError):
        return str(ex)
    if core is not None and isinstance(ex, core.Cancelled):
        return "BSP Lab: Build & Render cancelled; the previous preview is unchanged"
    if isinstance(ex, MemoryError):
        # The core's message names the limit and what the build needed.
        return "BSP Lab: the tree exceeds the memory budget: {}".format(ex)
    if isinstance(ex, (ValueError, TypeError)):
        # The core's checks: NaN/inf coordinates, options out of range.
        return "BSP Lab cannot build the tree: {}".format(ex)
    return "BSP Lab failed: {}: {}".format(type(ex).__name__, ex)


def failure_report(job):
    """(report level, message) of a job that ended with an error. A cancel is
    what the user asked for: information, not a red error."""
    if job.core is not None and isinstance(job.error, job.core.Cancelled):
        return 'INFO', job.cancelled_message
    return 'ERROR', error_message(job.core, job.error)


def check_result(result):
    """Refuse a finished render in which every camera ray missed."""
    hits = result["stats"]["render"].get("hits")
    if hits == 0:
        raise UserError("No mesh in the camera's view: every camera ray missed")

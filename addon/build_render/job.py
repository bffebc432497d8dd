# SPDX-License-Identifier: GPL-3.0-or-later
"""Build & Render's job: build (or re-use) tree A, and B of an A/B
comparison, render the camera's view with them, compare with Embree.

Nothing here touches bpy: the operator copies the scene into numpy arrays
and plain values first (`JobInput`, scene_reader.py), the job computes on a
worker thread (worker.py) and the main thread then reads `result` or
`error`. That split is also what lets the tests run a job without Blender
(addon_tests/without_blender/test_build_job.py).
"""

import time
import weakref
from dataclasses import dataclass

import numpy as np

from .. import backend
from ..compare.images import VIEWS as COMPARE_VIEWS
from ..compare.images import needs_counts
from . import tree_cache
from .worker import UserError, WorkerJob

# The per-pixel counters an A/B preview may show.
COUNTERS = ("steps", "tests", "culled", "box_tests")


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
    # Tree B of an A/B comparison (a TreeChoice), None without one; B is
    # rendered with A's camera, mode, threads and culling.
    b: object = None
    # The comparison's preview (compare.VIEWS).
    compare_view: str = "split"


@dataclass(frozen=True)
class TreeChoice:
    """A method and its build options."""

    method: str
    options: dict


def make_camera(bsplab, spec):
    return bsplab.Camera(**spec.kwargs())


def foreign_embree_library():
    """Name of an Embree library the host exports that clashes with embreex, if
    any (see `bsplab.oracle.foreign_embree_library`)."""
    return backend.import_bsplab().oracle.foreign_embree_library()


def compare_with_embree(bsplab, tree, cam, inp, embree_scene=None):
    """Trace the camera rays with the tree and with Embree; compare the hits.

    `embree_scene(triangles)` gives the Embree tracer and whether it was
    re-used (Job's, from its cache); by default a new one is built."""
    oracle = bsplab.oracle
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
    """Make bsplab's results JSON-friendly (numpy scalars and arrays included)."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist() if value.size <= 16 else "array{}".format(value.shape)
    if isinstance(value, np.generic):
        return value.item()
    return value


class TreeRun:
    """One tree of a press: re-used from its cache or built, then rendered.
    Holds that tree's progress (build, render) and whether it was re-used."""

    def __init__(self, bsplab, choice, cache=None):
        self.bsplab = bsplab
        self.choice = choice
        self.cache = cache
        self.build_progress = bsplab.Progress()
        self.render_progress = bsplab.Progress()
        # Read now, on the main thread: a clear() after this (a file loaded
        # while the job runs) makes the cache refuse what the job would keep.
        self._generation = cache.generation() if cache is not None else None
        self.key = None
        self.reused = False
        self.fingerprint_seconds = None
        # The tree rendered with, weakly: its cache owns it (the ray inspector).
        self.tree_ref = None

    def tree(self, triangles, other=None, other_tree=None):
        """The cache's tree when it was built for this input, `other_tree`
        when `other` (a TreeRun) chose the same tree (B = A), else a new one."""
        choice = self.choice
        if other is not None and _same_tree(choice, other.choice):
            self.reused = True
            return other_tree
        if self.cache is not None:
            start = time.perf_counter()
            self.key = tree_cache.tree_key(triangles, choice.method, choice.options)
            self.fingerprint_seconds = time.perf_counter() - start
            tree = self.cache.tree(self.key)
            if tree is not None:
                self.reused = True
                return tree
        tree = self.bsplab.build(triangles, method=choice.method,
                               progress=self.build_progress, **choice.options)
        if self.cache is not None:
            # Kept before rendering: a cancelled render leaves a good tree.
            self.cache.keep_tree(self.key, tree, self._generation)
        return tree

    def keep_embree(self, tracer):
        self.cache.keep_embree(self.key.geometry, tracer, self._generation)

    def cancel(self):
        self.build_progress.cancel()
        self.render_progress.cancel()

    def fraction(self):
        if self.reused:
            return self.render_progress.value
        # Building usually dominates; weigh it accordingly.
        return min(1.0, 0.6 * self.build_progress.value + 0.4 * self.render_progress.value)


def _same_tree(one, other):
    """Whether two TreeChoices give the same tree (see tree_cache.tree_key)."""
    def kept(choice):
        return {name: value for name, value in choice.options.items()
                if name not in tree_cache.NOT_TREE_OPTIONS}
    return one.method == other.method and kept(one) == kept(other)


class Job(WorkerJob):
    """Build & Render: build the tree (or re-use the cache's), render the
    camera's view, optionally compare the camera rays' hits with Embree's.

    With a `cache` (a tree_cache.TreeCache; the add-on passes its one), the
    tree of the previous press is re-used while the triangles, the method and
    the options that change the tree are the same, and the tree built here is
    kept for the next press. Without one, every job builds.

    With `inp.b` (A/B comparison) a second tree, B, is built (kept in
    `cache_b`, or A's own tree when B chose the same) and rendered the same
    way; the result then also holds B's image and statistics, and the
    per-pixel counters of both when the preview needs them (compare.py).
    """

    title = "Building & Rendering"
    cancelled_message = "BSP Lab: Build & Render cancelled; the previous preview is unchanged"

    def __init__(self, bsplab, inp, cache=None, cache_b=None):
        super().__init__(bsplab, inp)
        # (No input: a job made only to read its report.)
        self.a = TreeRun(bsplab, TreeChoice(inp.method, inp.options) if inp else None, cache)
        self.b = TreeRun(bsplab, inp.b, cache_b) if inp and inp.b is not None else None
        self.build_progress = self.a.build_progress
        self.render_progress = self.a.render_progress
        self.cache = cache

    @property
    def reused(self):
        return self.a.reused

    @property
    def fingerprint_seconds(self):
        return self.a.fingerprint_seconds

    def _runs(self):
        return [run for run in (self.a, self.b) if run is not None]

    def _check_cancelled(self):
        if self.cancelled:
            raise self.bsplab.Cancelled("cancelled")

    def _embree_scene(self, triangles):
        """The Embree tracer of the triangles and whether it was re-used."""
        tracer = self.cache.embree(self.a.key.geometry)
        if tracer is not None:
            return tracer, True
        tracer = self.bsplab.oracle.EmbreeTracer(triangles)
        self.a.keep_embree(tracer)
        return tracer, False

    def _render(self, run, tree, cam):
        """(image, statistics) of one tree: the build's, the render's and
        Embree's comparison if asked for."""
        inp = self.input
        # A difference view is about the counts: both trees count.
        counted = inp.count_steps or (inp.b is not None and
                                      COMPARE_VIEWS.get(inp.compare_view) is not None)
        image, render_stats = self.bsplab.render(
            tree, cam, inp.camera.width, inp.camera.height, mode=inp.mode,
            threads=inp.threads, cull=self._cull(),
            # The panel's Steps / Tests per Ray: counted in the same trace,
            # or None: render()'s default (packets where the mode allows).
            counters=True if counted else None, progress=run.render_progress)
        self._check_cancelled()
        render_stats = dict(render_stats, width=inp.camera.width, height=inp.camera.height,
                            mode=inp.mode, camera=inp.camera.name)
        stats = {
            # A re-used tree's own statistics, build_seconds included: the
            # time of the press that built it.
            "build": dict(tree.stats, reused=run.reused,
                          fingerprint_seconds=run.fingerprint_seconds),
            "render": render_stats,
        }
        if inp.compare_with_embree:
            embree_scene = self._embree_scene if self.cache is not None else None
            stats["embree"] = compare_with_embree(self.bsplab, tree, cam, inp, embree_scene)
            self._check_cancelled()
        return np.asarray(image, dtype=np.float32), stats

    def _cull(self):
        return self.input.cull or self.input.mode == "heat_culled"

    def _counts(self, tree, cam):
        """The (H, W) per-pixel counters of the camera rays (deterministic:
        the very counts the render saw)."""
        inp = self.input
        origins, directions = cam.rays(inp.camera.width, inp.camera.height)
        hits = tree.intersect(origins, directions, threads=inp.threads, cull=self._cull(),
                              counters=True)
        shape = (inp.camera.height, inp.camera.width)
        return {name: np.asarray(hits[name]).reshape(shape) for name in COUNTERS}

    def _compute(self):
        bsplab, inp = self.bsplab, self.input
        cam = make_camera(bsplab, inp.camera)
        self._check_cancelled()
        tree = self.a.tree(inp.triangles)
        self.a.tree_ref = weakref.ref(tree)
        self._check_cancelled()
        image, stats = self._render(self.a, tree, cam)
        result = {"image": image}
        stats = dict({"scene": {"triangles": len(inp.triangles), "objects": inp.objects,
                                "instances": inp.instances}}, **stats)
        if self.b is not None:
            try:
                tree_b = self.b.tree(inp.triangles, other=self.a, other_tree=tree)
            except (ValueError, TypeError) as ex:
                # The core's checks of B's options: say it is B's.
                raise UserError("Tree B cannot be built: {}".format(ex)) from ex
            self.b.tree_ref = weakref.ref(tree_b)
            self._check_cancelled()
            result["b_image"], stats["b"] = self._render(self.b, tree_b, cam)
            stats["compare"] = {"view": inp.compare_view, "a_options": inp.options,
                                "b_method": inp.b.method,
                                "b_options": inp.b.options}
            if needs_counts(inp.mode, inp.compare_view):
                result["counts"] = {"a": self._counts(tree, cam), "b": self._counts(tree_b, cam)}
                self._check_cancelled()
        result["stats"] = plain(stats)
        return result

    def cancel(self):
        super().cancel()
        for run in self._runs():
            run.cancel()

    def fraction(self):
        runs = self._runs()
        return sum(run.fraction() for run in runs) / len(runs)


def check_result(result):
    """Refuse a finished render in which every camera ray missed."""
    hits = result["stats"]["render"].get("hits")
    if hits == 0:
        raise UserError("No mesh in the camera's view: every camera ray missed")

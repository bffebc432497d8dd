# SPDX-License-Identifier: GPL-3.0-or-later
"""Build & Render's job: build (or re-use) tree A, and B of an A/B
comparison, render the camera's view with them, compare with Embree.

Nothing here touches bpy: the operator copies the scene into numpy arrays
and plain values first (`JobInput`, scene_input.py), the job computes on a
worker thread (jobs/worker.py) and the main thread then reads `result` or
`error`. That split is also what lets the tests run a job without Blender
(addon/tests/test_build_job.py). Each tree is built or re-used by a
jobs.tree_run.TreeRun; the Embree comparison is jobs/embree_check.py.
"""

import weakref
from dataclasses import dataclass

import numpy as np

from ..compare.images import VIEWS as COMPARE_VIEWS
from ..compare.images import needs_counts
from ..jobs.embree_check import compare_with_embree
from ..jobs.messages import TWO_LEVEL_CULL_MESSAGE
from ..jobs.scene_reader import make_camera
from ..jobs.tree_run import TreeChoice, TreeRun
from ..jobs.worker import UserError, WorkerJob, plain

# The per-pixel counters an A/B preview may show.
COUNTERS = ("steps", "tests", "culled", "box_tests")


@dataclass
class JobInput:
    """Everything Build & Render needs, copied out of bpy."""

    # (N, 3, 3) float32 world-space triangles (a flat build), or None for
    # a two-level one (`instanced` then holds the scene).
    triangles: np.ndarray
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
    # A two-level build's scene (bsplab.blender.extract.InstancedGeometry:
    # unique meshes in object space, each instance's mesh and matrix), None
    # for a flat one.
    instanced: object = None

    @property
    def two_level(self):
        return self.instanced is not None

    @property
    def triangle_count(self):
        """Triangles of the (flattened) scene."""
        if self.instanced is not None:
            return self.instanced.triangle_count
        return len(self.triangles)


class Job(WorkerJob):
    """Build & Render: build the tree (or re-use the cache's), render the
    camera's view, optionally compare the camera rays' hits with Embree's.

    With a `cache` (a jobs.tree_cache.TreeCache; the add-on passes its one), the
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
            "build": BUILD_STATS[tree.structure](tree, run, inp.instanced),
            "render": render_stats,
        }
        if inp.compare_with_embree:
            embree_scene = self._embree_scene if self.cache is not None else None
            origins, directions = cam.rays(inp.camera.width, inp.camera.height)
            stats["embree"] = compare_with_embree(self.bsplab, tree, origins, directions,
                                                  inp.cull, embree_scene)
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

    def _tree(self, run, other=None, other_tree=None):
        inp = self.input
        if inp.two_level:
            return run.tree_instanced(inp.instanced, other=other, other_tree=other_tree)
        return run.tree(inp.triangles, other=other, other_tree=other_tree)

    def _compute(self):
        bsplab, inp = self.bsplab, self.input
        if inp.two_level and self._cull():
            raise UserError(TWO_LEVEL_CULL_MESSAGE)
        cam = make_camera(bsplab, inp.camera)
        self._check_cancelled()
        tree = self._tree(self.a)
        self.a.tree_ref = weakref.ref(tree)
        self._check_cancelled()
        image, stats = self._render(self.a, tree, cam)
        result = {"image": image}
        scene = {"triangles": inp.triangle_count, "objects": inp.objects,
                 "instances": inp.instances}
        if inp.two_level:
            scene["unique_meshes"] = len(inp.instanced.meshes)
        stats = dict({"scene": scene}, **stats)
        if self.b is not None:
            try:
                tree_b = self._tree(self.b, other=self.a, other_tree=tree)
            except UserError as ex:
                raise UserError("Tree B: {}".format(ex)) from ex
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


def flat_stats(tree, run, _geometry):
    """The Build statistics of a flat tree: its own (a re-used tree's
    build_seconds are the time of the press that built it) and what this
    press did."""
    return dict(tree.stats, structure=tree.structure, reused=run.reused,
                fingerprint_seconds=run.fingerprint_seconds)


def two_level_stats(scene, run, geometry):
    """The Build statistics of a two-level scene: the core's (unique meshes,
    instances, the top level's nodes and bytes, the mesh trees' nodes and
    bytes, the flattened scene's triangles), the mesh trees' structure
    ("mesh_structure") and warnings, and what this press built and re-used."""
    stats = dict(scene.stats)
    press = run.press or {}
    bottom = [tree.stats for tree in scene.meshes]
    stats.update(
        structure=scene.structure, reused=run.reused,
        fingerprint_seconds=run.fingerprint_seconds,
        # The press that built the scene: its mesh trees' and top's time
        # (a re-used scene: that earlier press's).
        build_seconds=press.get("build_seconds"),
        top_build_seconds_press=press.get("top_seconds"),
        mesh_trees_built=press.get("mesh_trees_built"),
        mesh_trees_reused=press.get("mesh_trees_reused"),
        top_built=press.get("top_built"),
        mesh_tree_count=len({id(tree) for tree in scene.meshes}),
        mesh_structure=scene.meshes[0].structure if scene.meshes else None,
        warnings=["mesh {}: {}".format(name, warning)
                  for name, s in zip(geometry.mesh_names if geometry else (), bottom)
                  for warning in s.get("warnings") or ()],
    )
    return stats


# The Build statistics by the tree's kind (tree.structure).
BUILD_STATS = {"bsp": flat_stats, "bvh": flat_stats, "two_level": two_level_stats}

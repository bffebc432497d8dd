# SPDX-License-Identifier: GPL-3.0-or-later
"""Build & Render's job: build (or re-use) tree A, and B of an A/B
comparison, render the camera's view with them, compare with Embree.

Nothing here touches bpy: the operator copies the scene into numpy arrays
and plain values first (`JobInput`, scene_reader.py), the job computes on a
worker thread (worker.py) and the main thread then reads `result` or
`error`. That split is also what lets the tests run a job without Blender
(addon/tests/test_build_job.py).
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


# The panel's "Instances" choice (Scene.bsplab.instances).
TWO_LEVEL, FLATTEN = "two_level", "flatten"
# Leaf culling has no two-level trace in the core (InstancedTree.intersect
# refuses cull=True).
TWO_LEVEL_CULL_MESSAGE = ("Leaf culling is not available for two-level builds: untick Leaf "
                          "Culling (and pick another mode than Heat Culled), or choose "
                          "Instances: Flatten")


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
    two_level = tree_cache.is_two_level(tree)
    start = time.perf_counter()
    # The same work on both sides: hits only, on one thread (embreex traces
    # its rays one by one on one thread), so the ratio compares the trees and
    # kernels, not the core counts.
    ours = tree.intersect(origins, directions, threads=1, cull=inp.cull and not two_level,
                          counters=False)
    bsplab_seconds = time.perf_counter() - start
    # Embree has no instances here: it traces the flattened scene (every
    # instance's triangles in world space), and a two-level hit is compared
    # by its index in that scene (flat_prim), with the transform's rounding
    # as the oracle's slack (docs/instances.md).
    triangles = tree.flatten() if two_level else tree.triangles
    if embree_scene is None:
        tracer, reused = oracle.EmbreeTracer(triangles), False
    else:
        tracer, reused = embree_scene(triangles)
    start = time.perf_counter()
    theirs = tracer.intersect(origins, directions)
    embree_seconds = time.perf_counter() - start
    slack = None
    if two_level:
        slack = tree.transform_slack(origins, directions, ours["t"], ours["instance"])
        ours = dict(ours, prim=ours["flat_prim"])
    compare = oracle.compare(ours, theirs, triangles=triangles,
                             origins=origins, directions=directions, slack=slack)
    return {
        # What was compared, for the panel.
        "compared": ("two-level hits (by flattened triangle) vs Embree on the flattened "
                     "scene" if two_level else "hits vs Embree on the same triangles"),
        "embree_triangles": len(triangles),
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
        # A two-level press: its mesh trees built and re-used (tree_instanced).
        self.press = None
        self._cancelled = False
        # A two-level press's build fraction: triangles of the mesh trees
        # to build, those built, and the size of the one building now.
        self._build_total = None
        self._build_done = 0
        self._build_size = 0

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

    def tree_instanced(self, geometry, other=None, other_tree=None):
        """The two-level scene of `geometry` (an InstancedGeometry): the
        cache's when it was built for the same meshes, instances, method and
        options; else one built from the cache's mesh trees where it holds
        them (then only the top level and the changed meshes' trees are
        built). Sets `self.press`: how many mesh trees this press built and
        re-used, and how long its builds took."""
        choice = self.choice
        bsplab = self.bsplab
        if other is not None and _same_tree(choice, other.choice):
            self.reused = True
            self.press = dict(other.press)
            return other_tree
        options = dict(choice.options)
        threads = options.pop("threads", 0)
        start = time.perf_counter()
        mesh_keys = [tree_cache.tree_key(mesh, choice.method, choice.options)
                     for mesh in geometry.meshes]
        self.key = tree_cache.instanced_key(mesh_keys, geometry.mesh_index, geometry.matrices)
        self.fingerprint_seconds = time.perf_counter() - start
        cache = self.cache
        if cache is not None:
            scene = cache.tree(self.key)
            if scene is not None:
                self.reused = True
                self.press = dict(getattr(scene, "addon_press", {}), mesh_trees_built=0,
                                  mesh_trees_reused=len(set(mesh_keys)), top_built=False)
                return scene
            # Forgotten before building: two sets of trees are never held.
            cache.keep_only_mesh_trees(mesh_keys)
        # A singular or non-finite instance matrix is refused now, with its
        # object named, rather than after the mesh trees' builds.
        try:
            bsplab.check_instance_matrices(geometry.matrices)
        except ValueError as ex:
            raise UserError(instance_message(str(ex), geometry)) from ex
        trees, built, reused, mesh_seconds = {}, 0, 0, 0.0
        todo = sum(len(mesh) for mesh, key in zip(geometry.meshes, mesh_keys)
                   if cache is None or cache.mesh_tree(key) is None)
        self._build_total = max(1, todo)
        self._build_done = 0
        for mesh, key in zip(geometry.meshes, mesh_keys):
            if key in trees:  # two meshes with the same triangles: one tree
                continue
            tree = cache.mesh_tree(key) if cache is not None else None
            if tree is not None:
                reused += 1
            else:
                self._start_build(len(mesh))
                began = time.perf_counter()
                tree = bsplab.build(mesh, method=choice.method, progress=self.build_progress,
                                    **choice.options)
                mesh_seconds += time.perf_counter() - began
                self._build_done += len(mesh)
                built += 1
                if cache is not None:
                    # Kept at once: a cancel later in the press keeps it.
                    cache.keep_mesh_tree(key, tree, self._generation)
            trees[key] = tree
        self._start_build(0)
        self._build_done = self._build_total  # the top level: its own progress
        began = time.perf_counter()
        try:
            scene = bsplab.build_instanced([trees[key] for key in mesh_keys],
                                           geometry.mesh_index, geometry.matrices,
                                           choice.method, threads=threads,
                                           progress=self.build_progress, **options)
        except ValueError as ex:
            raise UserError(instance_message(str(ex), geometry)) from ex
        top_seconds = time.perf_counter() - began
        self.press = {"mesh_trees_built": built, "mesh_trees_reused": reused, "top_built": True,
                      "mesh_build_seconds": mesh_seconds, "top_seconds": top_seconds,
                      "build_seconds": mesh_seconds + top_seconds}
        # What a later press that re-uses the scene shows as its build.
        scene.addon_press = dict(self.press)
        if cache is not None:
            cache.keep_tree(self.key, scene, self._generation)
        return scene

    def _start_build(self, triangles):
        """The next build of a two-level press: `triangles` of the mesh (0:
        the top level). Raises Cancelled when cancelled between builds."""
        if self._cancelled:
            raise self.bsplab.Cancelled("cancelled")
        self._build_size = triangles
        self.build_progress.reset()
        if self._cancelled:  # a cancel that came during the reset
            raise self.bsplab.Cancelled("cancelled")

    def keep_embree(self, tracer):
        self.cache.keep_embree(self.key.geometry, tracer, self._generation)

    def cancel(self):
        self._cancelled = True
        self.build_progress.cancel()
        self.render_progress.cancel()

    def _build_fraction(self):
        if self._build_total is None:
            return self.build_progress.value
        if self._build_size == 0 and self._build_done >= self._build_total:
            return self.build_progress.value  # the top level (or nothing left)
        done = self._build_done + self.build_progress.value * self._build_size
        return min(1.0, done / self._build_total)

    def fraction(self):
        if self.reused:
            return self.render_progress.value
        # Building usually dominates; weigh it accordingly.
        return min(1.0, 0.6 * self._build_fraction() + 0.4 * self.render_progress.value)


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
                          fingerprint_seconds=run.fingerprint_seconds,
                          instances_mode=FLATTEN),
            "render": render_stats,
        }
        if tree_cache.is_two_level(tree):
            stats["build"] = two_level_stats(tree, run, inp.instanced)
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


def two_level_stats(scene, run, geometry):
    """The Build statistics of a two-level scene: the core's (unique meshes,
    instances, the top level's nodes and bytes, the mesh trees' nodes and
    bytes, the flattened scene's triangles), the mesh trees' structure and
    warnings, and what this press built and re-used."""
    stats = dict(scene.stats)
    press = run.press or {}
    bottom = [tree.stats for tree in scene.meshes]
    stats.update(
        instances_mode=TWO_LEVEL, reused=run.reused,
        fingerprint_seconds=run.fingerprint_seconds,
        # The press that built the scene: its mesh trees' and top's time
        # (a re-used scene: that earlier press's).
        build_seconds=press.get("build_seconds"),
        top_build_seconds_press=press.get("top_seconds"),
        mesh_trees_built=press.get("mesh_trees_built"),
        mesh_trees_reused=press.get("mesh_trees_reused"),
        top_built=press.get("top_built"),
        mesh_tree_count=len({id(tree) for tree in scene.meshes}),
        structure=bottom[0].get("structure") if bottom else None,
        warnings=["mesh {}: {}".format(name, warning)
                  for name, s in zip(geometry.mesh_names if geometry else (), bottom)
                  for warning in s.get("warnings") or ()],
    )
    return stats


def instance_message(message, geometry):
    """The core's refusal of an instance ("instance N: its matrix is
    singular ...") with the instance's object named, for the user."""
    head, sep, rest = message.partition(": ")
    words = head.split()
    if sep and len(words) == 2 and words[0] == "instance" and words[1].isdigit():
        index = int(words[1])
        names = geometry.instance_names if geometry is not None else []
        name = names[index] if index < len(names) else "#{}".format(index)
        hint = (" (an object scaled to 0 on an axis?): give it a non-zero scale, or choose "
                "Instances: Flatten") if "singular" in rest else ""
        return "BSP Lab cannot build the two-level scene: the instance of {}: {}{}".format(
            name, rest, hint)
    return "BSP Lab cannot build the two-level scene: {}".format(message)


def check_result(result):
    """Refuse a finished render in which every camera ray missed."""
    hits = result["stats"]["render"].get("hits")
    if hits == 0:
        raise UserError("No mesh in the camera's view: every camera ray missed")

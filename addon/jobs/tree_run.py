# SPDX-License-Identifier: GPL-3.0-or-later
"""One tree of a press: re-used from its cache (tree_cache.py) or built,
flat or two-level, with its progress. Build & Render runs one for tree A
and one for tree B of an A/B comparison (build_render/job.py).

A two-level press (bsplab.build_instanced: a tree per unique mesh and a
BVH over the instances) follows the same three steps as a flat one: the
key (tree_cache.tree_key / instanced_key), the cache's tree for it, and the
build kept under it; in between it asks the cache once for the mesh trees
it holds and keeps each mesh tree it builds at once (a cancel later in the
press keeps them).

No bpy here: it runs on the worker thread, and addon/tests/ run it
without Blender.
"""

import time
from dataclasses import dataclass

from . import tree_cache
from .messages import instance_message
from .worker import UserError

# The panel's "Instances" choice (Scene.bsplab.instances): how a scene whose
# objects share meshes is built.
TWO_LEVEL, FLATTEN = "two_level", "flatten"


@dataclass(frozen=True)
class TreeChoice:
    """A method and its build options."""

    method: str
    options: dict


def same_tree(one, other):
    """Whether two TreeChoices give the same tree (see tree_cache.tree_key)."""
    def kept(choice):
        return {name: value for name, value in choice.options.items()
                if name not in tree_cache.not_tree_options()}
    return one.method == other.method and kept(one) == kept(other)


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

    def _fingerprint(self, make_key, scene):
        start = time.perf_counter()
        self.key = make_key(scene, self.choice.method, self.choice.options)
        self.fingerprint_seconds = time.perf_counter() - start

    def tree(self, triangles, other=None, other_tree=None):
        """The cache's tree when it was built for this input, `other_tree`
        when `other` (a TreeRun) chose the same tree (B = A), else a new one."""
        choice = self.choice
        if other is not None and same_tree(choice, other.choice):
            self.reused = True
            return other_tree
        if self.cache is not None:
            self._fingerprint(tree_cache.tree_key, triangles)
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
        if other is not None and same_tree(choice, other.choice):
            self.reused = True
            self.press = dict(other.press)
            return other_tree
        options = dict(choice.options)
        threads = options.pop("threads", 0)
        self._fingerprint(tree_cache.instanced_key, geometry)
        mesh_keys = self.key.meshes
        cache = self.cache
        kept = {}
        if cache is not None:
            scene = cache.tree(self.key)  # a miss forgets the mesh trees not needed
            if scene is not None:
                self.reused = True
                self.press = dict(getattr(scene, "addon_press", {}), mesh_trees_built=0,
                                  mesh_trees_reused=len(set(mesh_keys)), top_built=False)
                return scene
            kept = cache.mesh_trees(mesh_keys)
        # A singular or non-finite instance matrix is refused now, with its
        # object named, rather than after the mesh trees' builds.
        try:
            bsplab.check_instance_matrices(geometry.matrices)
        except ValueError as ex:
            raise UserError(instance_message(str(ex), geometry)) from ex
        trees, built, mesh_seconds = dict(kept), 0, 0.0
        todo = {key: mesh for mesh, key in zip(geometry.meshes, mesh_keys) if key not in kept}
        self._build_total = max(1, sum(len(mesh) for mesh in todo.values()))
        self._build_done = 0
        # Two meshes with the same triangles share a key: one tree.
        for key, mesh in todo.items():
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
        self.press = {"mesh_trees_built": built, "mesh_trees_reused": len(kept),
                      "top_built": True, "mesh_build_seconds": mesh_seconds,
                      "top_seconds": top_seconds, "build_seconds": mesh_seconds + top_seconds}
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

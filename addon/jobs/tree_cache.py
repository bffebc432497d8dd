# SPDX-License-Identifier: GPL-3.0-or-later
"""The last tree Build & Render built, kept for the next press.

A press that changes only how the tree is used (the render mode, the preview
size, the camera, leaf culling, the thread count) needs no new tree: the
tree depends on the scene's world-space triangles, the method and the build
options, nothing else. `TreeKey` fingerprints exactly those; while it is
unchanged the job renders with the kept tree instead of building again. The
Embree scene of "Compare with Embree" depends on the triangles alone and is
kept the same way.

One tree at a time: a press with another key forgets the kept tree before
building, so the old and the new tree are never held together.

A two-level build (bsplab.build_instanced: a tree per unique mesh and a
BVH over the instances) is kept as one tree too, under an `InstancedKey`
(every mesh's TreeKey and a digest of the instances' meshes and
matrices), and its mesh trees are also kept one by one under their own
TreeKeys: a press after moving, adding or deleting an instance finds
every mesh tree and builds the top level only; a press after editing one
mesh builds that mesh's tree only. Before building, the mesh trees this
press does not need are forgotten (as a flat tree is). The add-on
clears the cache when a file is loaded and when it is unregistered, so a
tree of another file is never shown.

No bpy here: the worker thread fills the cache, the main thread clears it,
and addon/tests/test_build_job.py tests it without Blender.
"""

import hashlib
import threading
from dataclasses import dataclass

import numpy as np

from .. import backend


def not_tree_options():
    """Build options that change how a tree is built, never the tree
    (`bsplab.method_table.NOT_TREE_OPTIONS`, named once there): the builder
    gives the same nodes on any number of threads, and the memory limit only
    decides whether a build may finish. (The tests check both claims.)"""
    return frozenset(backend.submodule("method_table").NOT_TREE_OPTIONS)

# 16 of SHA-256's 32 bytes: a collision between two scenes of one session
# is out of reach.
DIGEST_BYTES = 16


def geometry_digest(triangles):
    """Fingerprint of a triangle array: its shape, type and every byte.

    SHA-256 because OpenSSL runs it on the CPU's SHA instructions where they
    exist (x86 since AMD Zen and Intel Ice Lake): 11-15 ms for conference's
    331k triangles (12 MB) on the lab's machine, against 25 ms for blake2b,
    next to a build of 1.5 s or more. hashlib releases the GIL meanwhile.
    """
    array = np.ascontiguousarray(triangles)
    digest = hashlib.sha256(repr((array.shape, array.dtype.str)).encode())
    digest.update(memoryview(array).cast("B"))
    return digest.digest()[:DIGEST_BYTES]


@dataclass(frozen=True)
class TreeKey:
    """What a tree depends on: equal keys, the same tree."""

    geometry: bytes  # geometry_digest() of the triangles
    method: str
    options: tuple  # sorted (name, value) of the options that change the tree


def tree_key(triangles, method, options):
    """The TreeKey of a build of `triangles` with `method` and `options`."""
    skipped = not_tree_options()
    kept = tuple(sorted((name, value) for name, value in options.items()
                        if name not in skipped))
    return TreeKey(geometry_digest(triangles), method, kept)


def instances_digest(mesh_index, matrices):
    """Fingerprint of the instances: each one's mesh and matrix (every byte)."""
    digest = hashlib.sha256()
    for array in (np.ascontiguousarray(mesh_index, dtype=np.int64),
                  np.ascontiguousarray(matrices, dtype=np.float64)):
        digest.update(repr(array.shape).encode())
        digest.update(memoryview(array).cast("B"))
    return digest.digest()[:DIGEST_BYTES]


@dataclass(frozen=True)
class InstancedKey:
    """What a two-level build depends on: its mesh trees' keys (in mesh
    order) and its instances."""

    meshes: tuple  # a TreeKey per unique mesh
    instances: bytes  # instances_digest()

    @property
    def geometry(self):
        """The digest of the flattened scene's geometry (the Embree scene's
        key): the meshes' triangles and the instances, not the method."""
        digest = hashlib.sha256(self.instances)
        for key in self.meshes:
            digest.update(key.geometry)
        return digest.digest()[:DIGEST_BYTES]


def instanced_key(geometry, method, options):
    """The InstancedKey of a two-level build of `geometry` (an
    InstancedGeometry: the unique meshes, each instance's mesh and matrix)
    with `method` and `options`: each mesh's TreeKey, in mesh order, and
    the instances' digest."""
    return InstancedKey(tuple(tree_key(mesh, method, options) for mesh in geometry.meshes),
                        instances_digest(geometry.mesh_index, geometry.matrices))


class _Slot:
    """One value under the key it was made for (the cache's lock held)."""

    def __init__(self):
        self.key = self.value = None

    def get(self, key):
        """The value if it was made for `key`; else None, and the value is
        forgotten (the caller is about to make another)."""
        if self.key == key:
            return self.value
        self.key = self.value = None
        return None

    def keep(self, key, value):
        self.key, self.value = key, value


class TreeCache:
    """Holds one tree under its TreeKey and one Embree scene under the
    geometry digest of its triangles.

    `generation()` is read on the main thread when a job is made; a job
    keeps what it made only if no `clear()` happened since (a file loaded
    while it ran), so a cleared cache stays clear.
    """

    def __init__(self):
        self._lock = threading.Lock()
        self._generation = 0
        self._tree = _Slot()
        self._embree = _Slot()
        # The mesh trees of the last two-level build: {TreeKey: Tree}.
        self._mesh_trees = {}

    def generation(self):
        with self._lock:
            return self._generation

    def tree(self, key):
        """The kept tree if it was built for `key`; else None, and the kept
        tree is forgotten, so that two trees are never held together, with
        the mesh trees `key` does not need (all of them for a flat TreeKey;
        an InstancedKey's own meshes stay for the build to re-use)."""
        needed = set(key.meshes) if isinstance(key, InstancedKey) else set()
        with self._lock:
            tree = self._tree.get(key)
            if tree is None:
                self._mesh_trees = {k: t for k, t in self._mesh_trees.items() if k in needed}
            return tree

    def mesh_trees(self, keys):
        """{key: tree} of the kept mesh trees among `keys`."""
        with self._lock:
            return {key: self._mesh_trees[key] for key in keys if key in self._mesh_trees}

    def keep_mesh_tree(self, key, tree, generation):
        with self._lock:
            if generation == self._generation:
                self._mesh_trees[key] = tree

    def mesh_tree_count(self):
        """How many mesh trees are kept: for the tests."""
        with self._lock:
            return len(self._mesh_trees)

    def kept_tree(self):
        """The kept tree, whatever its key, or None; forgets nothing (the
        viewport overlay draws it)."""
        with self._lock:
            return self._tree.value

    def keep_tree(self, key, tree, generation):
        self._keep(self._tree, key, tree, generation)

    def embree(self, geometry):
        """The kept Embree scene if it holds the triangles of digest
        `geometry`; else None, and the kept one is forgotten."""
        with self._lock:
            return self._embree.get(geometry)

    def keep_embree(self, geometry, tracer, generation):
        self._keep(self._embree, geometry, tracer, generation)

    def _keep(self, slot, key, value, generation):
        with self._lock:
            if generation == self._generation:
                slot.keep(key, value)

    def clear(self):
        """Forget everything, and what the jobs running now would keep."""
        with self._lock:
            self._generation += 1
            self._tree = _Slot()
            self._embree = _Slot()
            self._mesh_trees = {}

    def __len__(self):
        """How many things are kept (0, 1 or 2; a two-level build's mesh
        trees are counted by mesh_tree_count()): for the tests."""
        with self._lock:
            return (self._tree.value is not None) + (self._embree.value is not None)

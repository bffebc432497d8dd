# SPDX-License-Identifier: GPL-3.0-or-later
"""Compare a tree's hits of the camera rays with Embree's (bsplab.oracle
over embreex), on the worker thread, for the panel's Embree section.

Embree has no instances here: it traces a flat triangle array. What that
array is and how a hit is matched depends on the tree's kind, chosen
through `SIDES` by `tree.structure`: a flat tree's own triangles; or a
two-level build's flattened scene (every instance's triangles in world
space), its hit matched by the index in that scene (flat_prim), with the
transform's rounding as the oracle's slack (docs/instances.md) and the
instances' exact world triangles as the scene the oracle judges against.
"""

import time
from dataclasses import dataclass

from .. import backend
from .worker import plain


@dataclass(frozen=True)
class Side:
    """How one kind of tree meets Embree."""

    compared: str  # what was compared, for the panel
    cull: bool  # whether the tree may trace with leaf culling
    triangles: object  # tree -> the (N, 3, 3) triangles Embree traces
    # (tree, origins, directions, hits) -> (hits by Embree's triangle index, slack or None)
    match: object
    # (oracle, tree) -> the scene as given, for the oracle's exact verdict
    # (None: the triangles Embree traces are it)
    exact_scene: object = lambda _oracle, _tree: None


def _same_hits(_tree, _origins, _directions, hits):
    return hits, None


def _flattened_hits(tree, origins, directions, hits):
    slack = tree.transform_slack(origins, directions, hits["t"], hits["instance"])
    return dict(hits, prim=hits["flat_prim"]), slack


_FLAT = Side("hits vs Embree on the same triangles", True, lambda tree: tree.triangles,
             _same_hits)
SIDES = {
    "bsp": _FLAT,
    "bvh": _FLAT,
    # Leaf culling has no two-level trace (InstancedTree.intersect refuses it).
    # Judged against the instances' exact world triangles (matrix times
    # vertex), which Embree's flattened float triangles round.
    "two_level": Side("two-level hits (by flattened triangle) vs Embree on the flattened "
                      "scene", False, lambda tree: tree.flatten(), _flattened_hits,
                      lambda oracle, tree: oracle.instanced_scene(tree)),
}


def foreign_embree_library():
    """Name of an Embree library the host exports that clashes with embreex, if
    any (see `bsplab.oracle.foreign_embree_library`)."""
    return backend.import_bsplab().oracle.foreign_embree_library()


def compare_with_embree(bsplab, tree, origins, directions, cull, embree_scene=None):
    """Trace the rays with the tree and with Embree; compare the hits.

    `embree_scene(triangles)` gives the Embree tracer and whether it was
    re-used (the job's, from its cache); by default a new one is built."""
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
    side = SIDES[tree.structure]
    start = time.perf_counter()
    # The same work on both sides: hits only, on one thread (embreex traces
    # its rays one by one on one thread), so the ratio compares the trees and
    # kernels, not the core counts.
    ours = tree.intersect(origins, directions, threads=1, cull=cull and side.cull,
                          counters=False)
    bsplab_seconds = time.perf_counter() - start
    triangles = side.triangles(tree)
    if embree_scene is None:
        tracer, reused = oracle.EmbreeTracer(triangles), False
    else:
        tracer, reused = embree_scene(triangles)
    start = time.perf_counter()
    theirs = tracer.intersect(origins, directions)
    embree_seconds = time.perf_counter() - start
    ours, slack = side.match(tree, origins, directions, ours)
    compare = oracle.compare(ours, theirs, triangles=triangles,
                             origins=origins, directions=directions, slack=slack,
                             scene=side.exact_scene(oracle, tree))
    return {
        "structure": tree.structure,
        "compared": side.compared,
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

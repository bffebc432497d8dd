"""What a trial times side by side in `timing.paired_rounds`, one thread each:
the trial's tree on the counting path (the lab's steps and tests per ray come
from it), the scene's kd-tree, Embree, and on request the same tree with leaf
culling on and on its hits-only paths.

The counting path writes eight arrays per ray; a renderer, and Embree, only
need the closest hit. So a speed quoted against Embree's (`bench`) is the
hits-only paths' speed: the table `HITS_ONLY_TRACERS` below says which of
them trace which workload."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .spec import Spec
from .timing import Tracer


@dataclass(frozen=True)
class Rays:
    """One workload's rays, as every tracer of a trial gets them."""
    workload: str
    origins: np.ndarray
    directions: np.ndarray
    tmax: float      # inf: unbounded


# The hits-only paths a results row has columns for: `<name>_s` (the rounds'
# times) and `<name>_unexplained` (rays whose answer differs from Embree's).
HITS_ONLY_PATHS = ("hits_only", "packets", "given_order")

# A factory makes a path's tracer for one trial and workload (None: the path
# does not apply to that tree). Its run() must
# return t, prim, u, v in the order of `rays` (they are checked against
# Embree's ray by ray); a path that wants the rays in another order reorders
# its own copy when the factory runs, outside the timed call.
TracerFactory = Callable[[object, Rays, Spec], "Tracer | None"]


def _single_rays(tree, rays: Rays, spec: Spec) -> Tracer:
    """One ray at a time, without counters: the path `render()`'s shaded,
    normal and depth modes take."""
    return Tracer(lambda: tree.intersect(rays.origins, rays.directions, tmax=rays.tmax,
                                         threads=1, counters=False))


def _single_rays_in_given_order(tree, rays: Rays, spec: Spec) -> Tracer:
    """The hits-only single rays in the caller's order (`ray_order="given"`):
    the speed the spatial order (core/src/trace/ray_order.hpp) is measured
    against, on the rays a kd or BSP tree sorts, and the one walk on which
    trees are compared with each other (report.py's kd ÷ BVH; the BVH keeps
    the given order either way)."""
    return Tracer(lambda: tree.intersect(rays.origins, rays.directions, tmax=rays.tmax,
                                         threads=1, counters=False, ray_order="given"))


def _packets(tree, rays: Rays, spec: Spec) -> Tracer:
    """Consecutive rays in SIMD packets, without counters: the path
    `render()`'s shaded, normal and depth modes take. It pays on coherent
    rays only: the primary ones, which the lab makes in tile order."""
    return Tracer(lambda: tree.intersect(rays.origins, rays.directions, tmax=rays.tmax,
                                         threads=1, counters=False, packets=True))


# Per workload, the hits-only paths a spec with `hits_only = true` times, by
# name (one of HITS_ONLY_PATHS). Packets pay on coherent rays only: the
# camera's, in tile order. Only random rays are sorted by the spatial order
# (ambient-occlusion and diffuse rays leave the camera's hits in pixel order,
# already coherent), so only they are timed in the given order too.
HITS_ONLY_TRACERS: dict[str, dict[str, TracerFactory]] = {
    "primary": {"hits_only": _single_rays, "packets": _packets},
    "ao": {"hits_only": _single_rays},
    "diffuse": {"hits_only": _single_rays},
    "random": {"hits_only": _single_rays, "given_order": _single_rays_in_given_order},
}


def trial_tracers(tree, kd, embree, spec: Spec, rays: Rays) -> dict[str, Tracer]:
    """The trial's tree and its references on the same rays, one thread each:
    `ours` (the counting path), `kd` (unless the tree is the kd reference),
    `embree` (where it runs), `culled` (spec.cull) and the workload's
    hits-only paths (spec.hits_only)."""
    o, d, tmax = rays.origins, rays.directions, rays.tmax
    etmax = None if np.isinf(tmax) else tmax
    out = {"ours": Tracer(lambda: tree.intersect(o, d, tmax=tmax, threads=1))}
    if kd is not tree:  # the kd trial's own times are its kd times
        out["kd"] = Tracer(lambda: kd.intersect(o, d, tmax=tmax, threads=1))
    if embree:
        out["embree"] = Tracer(lambda: embree.intersect(o, d, tmax=etmax),
                               lambda: embree.last_seconds)
    if spec.cull:
        out["culled"] = Tracer(lambda: tree.intersect(o, d, tmax=tmax, threads=1, cull=True))
    if spec.hits_only:
        for name, factory in HITS_ONLY_TRACERS.get(rays.workload, {}).items():
            if (tracer := factory(tree, rays, spec)) is not None:
                out[name] = tracer
    return out

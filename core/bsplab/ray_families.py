"""Ray families that probe the corners of a tree's robustness.

Camera and random rays rarely land exactly on a split plane, a cell face, an
edge or a vertex; real renderers send such rays all the time (walls that lie
in the scene box's faces, secondary rays that start on a surface, shadow rays
that end on one). Each family here aims at one of those cases; the agreement
tests and the fuzzer trace all of them against Embree.

Every family is deterministic for a seed and returns float32 `origins`,
`directions` and a float32 `tmax` per ray (inf for unbounded rays).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from . import mesh_edges
from .camera import Camera
from .workloads import bounds, framing_camera, random_rays

Family = Callable[[np.ndarray, int, np.random.Generator], tuple]


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _sphere(rng: np.random.Generator, n: int) -> np.ndarray:
    return _unit(rng.normal(size=(n, 3)))


def _box(tris: np.ndarray):
    lo, hi = bounds(tris)
    ext = np.maximum(hi - lo, 1e-30 * max(1.0, float(np.abs(hi).max())))
    return lo, hi, ext


def _surface_points(tris: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """Points on random triangles (uniform barycentrics), in double."""
    t = tris[rng.integers(0, len(tris), n)].astype(np.float64)
    a, b = rng.random(n), rng.random(n)
    flip = a + b > 1
    a[flip], b[flip] = 1 - a[flip], 1 - b[flip]
    return t[:, 0] + a[:, None] * (t[:, 1] - t[:, 0]) + b[:, None] * (t[:, 2] - t[:, 0])


def _aim(origins: np.ndarray, targets: np.ndarray) -> tuple:
    """Rays from float32 origins towards targets; drops rays of zero length."""
    o = origins.astype(np.float32)
    d = (np.asarray(targets, np.float64) - o.astype(np.float64)).astype(np.float32)
    keep = np.linalg.norm(d.astype(np.float64), axis=1) > 0
    return o[keep], d[keep]


def outside_in(tris, n, rng):
    """From outside the scene box towards random points inside it, and towards
    points on its faces: the rays that enter the box onto walls lying in the
    box's own planes."""
    lo, hi, ext = _box(tris)
    centre, radius = (lo + hi) / 2, float(np.linalg.norm(ext))
    origins = centre + _sphere(rng, n) * radius * rng.uniform(0.6, 3.0, (n, 1))
    targets = rng.uniform(lo, hi, (n, 3))
    # Half of them aim at a point of a box face (one coordinate pinned).
    half = rng.random(n) < 0.5
    axis = rng.integers(0, 3, n)
    side = np.where(rng.random(n) < 0.5, lo[axis], hi[axis])
    targets[half, axis[half]] = side[half]
    return _aim(origins, targets)


def axis_parallel(tris, n, rng):
    """Directions along +-x, +-y, +-z from origins that often share a
    coordinate with a vertex, so many rays run inside a wall's plane or a
    kd split plane."""
    lo, hi, ext = _box(tris)
    origins = rng.uniform(lo - 0.2 * ext, hi + 0.2 * ext, (n, 3))
    verts = tris.reshape(-1, 3)
    pin = verts[rng.integers(0, len(verts), n)]
    for k in range(3):
        use = rng.random(n) < 0.4
        origins[use, k] = pin[use, k]
    axis = rng.integers(0, 3, n)
    d = np.zeros((n, 3))
    d[np.arange(n), axis] = np.where(rng.random(n) < 0.5, -1.0, 1.0)
    return origins.astype(np.float32), d.astype(np.float32)


def through_vertices(tris, n, rng):
    """Aimed exactly at mesh vertices: every hit lands on shared corners."""
    lo, hi, ext = _box(tris)
    verts = tris.reshape(-1, 3)
    targets = verts[rng.integers(0, len(verts), n)].astype(np.float64)
    origins = rng.uniform(lo - 0.5 * ext, hi + 0.5 * ext, (n, 3))
    return _aim(origins, targets)


def through_edges(tris, n, rng):
    """Aimed at points on triangle edges (midpoints and random points)."""
    lo, hi, ext = _box(tris)
    t = tris[rng.integers(0, len(tris), n)].astype(np.float64)
    j = rng.integers(0, 3, n)
    a, b = t[np.arange(n), j], t[np.arange(n), (j + 1) % 3]
    s = np.where(rng.random(n) < 0.5, 0.5, rng.random(n))[:, None]
    origins = rng.uniform(lo - 0.5 * ext, hi + 0.5 * ext, (n, 3))
    return _aim(origins, a + s * (b - a))


def in_planes(tris, n, rng):
    """Rays lying in planes the builders split along: axis planes through
    vertex coordinates (kd splits sit there) and the triangles' own planes
    (the wn/cn/IZE candidates), started on the triangle so they run in it."""
    half = n // 2
    verts = tris.reshape(-1, 3)
    lo, hi, ext = _box(tris)
    # Axis planes through a vertex coordinate.
    o = rng.uniform(lo - 0.2 * ext, hi + 0.2 * ext, (half, 3))
    axis = rng.integers(0, 3, half)
    o[np.arange(half), axis] = verts[rng.integers(0, len(verts), half), axis]
    d = _sphere(rng, half)
    d[np.arange(half), axis] = 0.0
    # Triangle planes: from a point of a triangle, along a direction in it.
    m = n - half
    idx = rng.integers(0, len(tris), m)
    t = tris[idx].astype(np.float64)
    nrm = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    keep = np.linalg.norm(nrm, axis=1) > 0
    t, nrm = t[keep], _unit(nrm[keep])
    r = _sphere(rng, len(t))
    in_plane = r - np.einsum("ij,ij->i", r, nrm)[:, None] * nrm
    ok = np.linalg.norm(in_plane, axis=1) > 1e-6
    start = t[:, 0] + 0.5 * (t[:, 1] - t[:, 0]) * rng.random((len(t), 1))
    o2 = start[ok] - _unit(in_plane[ok]) * float(np.linalg.norm(ext))
    d2 = _unit(in_plane[ok])
    origins = np.concatenate([o, o2]).astype(np.float32)
    dirs = np.concatenate([d, d2]).astype(np.float32)
    keep = np.linalg.norm(dirs.astype(np.float64), axis=1) > 0
    return origins[keep], dirs[keep]


def from_surfaces(tris, n, rng):
    """Starting on a surface (a point inside a triangle, or a vertex), in a
    random direction: secondary rays without the usual offset."""
    origins = _surface_points(tris, n, rng)
    verts = tris.reshape(-1, 3)
    at_vertex = rng.random(n) < 0.25
    origins[at_vertex] = verts[rng.integers(0, len(verts), int(at_vertex.sum()))]
    return origins.astype(np.float32), _sphere(rng, n).astype(np.float32)


def short_segments(tris, n, rng):
    """Segments that end just before, on or just after a surface, and very
    short ones: shadow rays and the traversal's early exit."""
    lo, hi, ext = _box(tris)
    o, d = outside_in(tris, n, rng)
    target = _surface_points(tris, len(o), rng)
    o, d = _aim(o, target)  # t = 1 lands on a surface
    scale = rng.choice([1e-6, 0.5, 1.0 - 1e-6, 1.0, 1.0 + 1e-6, 2.0], len(o))
    return o, d, scale.astype(np.float32)


def long_rays(tris, n, rng):
    """From far away (a thousand scene sizes) towards the scene, and from
    inside with tiny and huge direction lengths."""
    lo, hi, ext = _box(tris)
    centre, size = (lo + hi) / 2, float(np.linalg.norm(ext))
    half = n // 2
    origins = centre + _sphere(rng, half) * size * 1000.0
    o1, d1 = _aim(origins, rng.uniform(lo, hi, (half, 3)))
    o2 = rng.uniform(lo, hi, (n - half, 3)).astype(np.float32)
    d2 = (_sphere(rng, n - half) * 10.0 ** rng.uniform(-6, 6, (n - half, 1))).astype(np.float32)
    return np.concatenate([o1, o2]), np.concatenate([d1, d2])


def edges_in_split_planes(tris, n, rng):
    """Aimed exactly through shared edges and vertices that lie in split
    planes: half of them at edges whose two end points share a coordinate
    (the edge lies in that axis plane, where kd and ^Kd trees split: at
    triangle bounds), the rest at any shared edge (it lies in both of its
    triangles' planes, the wn / cn / IZE candidates), one in five at a shared
    vertex. From outside the box and from inside it. A miss or a farther hit
    there, where Embree hits, is a leak (oracle.leaks): a closed surface's
    shared edge is hit by one of its triangles whatever the rounding."""
    lo, hi, ext = _box(tris)
    edges = mesh_edges.shared_edges(tris)
    if len(edges) == 0:
        return through_edges(tris, n, rng)
    in_axis = np.flatnonzero((edges[:, 0] == edges[:, 1]).any(axis=1))
    pick = rng.integers(0, len(edges), n)
    if len(in_axis):
        half = rng.random(n) < 0.5
        pick[half] = in_axis[rng.integers(0, len(in_axis), int(half.sum()))]
    e = edges[pick].astype(np.float64)
    s = np.where(rng.random(n) < 0.5, 0.5, rng.random(n))
    s[rng.random(n) < 0.2] = 0.0  # the vertex itself
    targets = e[:, 0] + s[:, None] * (e[:, 1] - e[:, 0])
    outside = rng.random(n) < 0.5
    origins = np.where(outside[:, None],
                       (lo + hi) / 2 + _sphere(rng, n) * float(np.linalg.norm(ext)) *
                       rng.uniform(0.6, 2.0, (n, 1)),
                       rng.uniform(lo, hi, (n, 3)))
    return _aim(origins, targets)


def along_edges(tris, n, rng):
    """Lying along shared edges (in both triangles' planes, and in axis
    planes for axis-aligned edges): from before one end point, along the
    edge. The rays of a renderer's grazing bounces and of edge-on walls;
    they must cost about what camera rays cost."""
    edges = mesh_edges.shared_edges(tris)
    if len(edges) == 0:
        return in_planes(tris, n, rng)
    e = edges[rng.integers(0, len(edges), n)].astype(np.float64)
    a, b = e[:, 0], e[:, 1]
    back = rng.uniform(0.0, 2.0, (n, 1))
    flip = rng.random(n) < 0.5
    a[flip], b[flip] = b[flip].copy(), a[flip].copy()
    return _aim(a - back * (b - a), b)


def from_distance(tris, n, rng, sizes: float):
    """From `sizes` scene sizes away (the box's diagonal) towards points of
    the scene."""
    lo, hi, ext = _box(tris)
    centre, size = (lo + hi) / 2, float(np.linalg.norm(ext))
    origins = centre + _sphere(rng, n) * size * sizes
    return _aim(origins, _surface_points(tris, n, rng))


def far_away(tris, n, rng):
    """From a million scene sizes away towards points of the scene: the
    traversal's tolerances must follow the segment inside the box, not |o|."""
    return from_distance(tris, n, rng, 1e6)


def _camera_rays(cam: Camera, n: int) -> tuple:
    side = max(1, int(np.sqrt(n)))
    return cam.rays(side, max(1, n // side))


def inside_camera(tris, n, rng):
    """Primary rays of the framing camera inside the scene box."""
    return _camera_rays(framing_camera(tris), n)


def outside_camera(tris, n, rng):
    """Primary rays of a camera outside the scene box, looking at its centre
    (the walls of a room are then seen from behind, through the box's faces)."""
    lo, hi, ext = _box(tris)
    centre = (lo + hi) / 2
    eye = centre + _unit(rng.normal(size=(1, 3)))[0] * 1.2 * float(np.linalg.norm(ext))
    up = (0.0, 0.0, 1.0) if abs(eye[2] - centre[2]) < 0.9 * np.linalg.norm(eye - centre) \
        else (0.0, 1.0, 0.0)
    return _camera_rays(Camera.look_at(tuple(eye), tuple(centre), up=up, fov_deg=50), n)


def random_inside(tris, n, rng):
    """Origins uniform in the scene box, directions uniform on the sphere."""
    return random_rays(tris, n, seed=int(rng.integers(1 << 31)))


FAMILIES: dict[str, Family] = {
    "inside_camera": inside_camera,
    "outside_camera": outside_camera,
    "random_inside": random_inside,
    "outside_in": outside_in,
    "axis_parallel": axis_parallel,
    "through_vertices": through_vertices,
    "through_edges": through_edges,
    "in_planes": in_planes,
    "from_surfaces": from_surfaces,
    "short_segments": short_segments,
    "long_rays": long_rays,
    "edges_in_split_planes": edges_in_split_planes,
    "along_edges": along_edges,
    "far_away": far_away,
}


def family(name: str, triangles: np.ndarray, count: int, seed: int = 0) -> tuple:
    """(origins, directions, tmax) of one family; tmax is inf unless the
    family bounds its segments."""
    if name not in FAMILIES:
        raise ValueError(f"unknown ray family {name!r}; known: {', '.join(FAMILIES)}")
    rng = np.random.default_rng([seed, list(FAMILIES).index(name)])
    out = FAMILIES[name](np.asarray(triangles, np.float32), int(count), rng)
    o, d = out[0], out[1]
    tmax = out[2] if len(out) > 2 else np.full(len(o), np.inf, np.float32)
    return (np.ascontiguousarray(o, np.float32), np.ascontiguousarray(d, np.float32),
            np.ascontiguousarray(tmax, np.float32))


# The distances from the origin, in the scene's units, of the `shifted`
# scenes: a tree's bounds must follow the scene's size, not its distance
# from the origin (the trees' local frame, docs/algorithms.md#far-scenes).
SHIFTS = (1e3, 1e4, 1e5, 1e6, 1e7)
# The families traced on them: rays from outside, from inside, and grazing.
SHIFTED_FAMILIES = ("outside_camera", "inside_camera", "outside_in", "through_edges")


def representable_at(x, shift: float) -> np.ndarray:
    """float32 copies of `x` (rounded to float32 at x + shift and moved back):
    values whose sum with `shift` is exact in float32, so that the copy at
    the origin and the one at `shift` are the same points."""
    at = (np.asarray(x, np.float64) + shift).astype(np.float32)
    back = (at.astype(np.float64) - shift).astype(np.float32)
    if not np.array_equal((back.astype(np.float64) + shift).astype(np.float32), at):
        raise ValueError(f"the points do not round-trip at {shift:g}: |x| reaches "
                         f"{float(np.abs(np.asarray(x, np.float64)).max()):g}, too near the "
                         "shift for exact moves")
    return back


def shifted(name: str, triangles: np.ndarray, count: int, shift: float, seed: int = 0):
    """The `shifted` family: one scene and one set of rays (family `name`),
    at the origin and moved by `shift` along every axis, identical geometry
    (every coordinate representable_at the shift). Returns ((triangles,
    origins) at the origin, (triangles, origins) at the shift, directions,
    tmax)."""
    base = representable_at(triangles, shift)
    o, d, tmax = family(name, base, count, seed)
    o0 = representable_at(o, shift)
    moved = (base.astype(np.float64) + shift).astype(np.float32)
    o_moved = (o0.astype(np.float64) + shift).astype(np.float32)
    return (base, o0), (moved, o_moved), d, tmax

"""Which triangle edges a mesh shares: the same two vertices, bit for bit, in
two or more triangles. A ray through a shared edge must hit one of its
triangles (the triangle test is watertight there); through an open edge a
single-precision test may rightly miss. The edge family aims at shared edges
(ray_families.edges_in_split_planes) and the leak check tells the two apart
(oracle.leaks)."""

from __future__ import annotations

import hashlib
from collections import OrderedDict

import numpy as np


def edge_keys(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, 6) uint32 keys of the edges a[i]-b[i] (float32 points): the raw
    bits of both end points, the smaller first, so that an edge has one key
    whichever way it runs."""
    ka = np.ascontiguousarray(a, np.float32).view(np.uint32).reshape(-1, 3)
    kb = np.ascontiguousarray(b, np.float32).view(np.uint32).reshape(-1, 3)
    diff = ka != kb
    first = np.argmax(diff, axis=1)
    r = np.arange(len(ka))
    a_first = (diff.any(axis=1) & (ka[r, first] < kb[r, first]))[:, None]
    return np.concatenate([np.where(a_first, ka, kb), np.where(a_first, kb, ka)], axis=1)


def triangle_edges(tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The end points of every triangle's three edges, (3N, 3) each: edge j of
    triangle i (row 3 i + j) runs from vertex j to vertex j + 1."""
    t = np.asarray(tris, np.float32)
    return t.reshape(-1, 3), np.roll(t, -1, axis=1).reshape(-1, 3)


def edge_groups(tris: np.ndarray) -> np.ndarray:
    """(3N,) int: one number per distinct edge, for every triangle's edge
    (row 3 i + j as in triangle_edges); equal numbers, the same edge."""
    a, b = triangle_edges(tris)
    return np.unique(edge_keys(a, b), axis=0, return_inverse=True)[1].ravel()


def crosses_surface(tris: np.ndarray, groups: np.ndarray, ids: np.ndarray, prim: int,
                    edge: int, direction: np.ndarray, parallel_cos: float = 0.0,
                    slack: float = 0.0) -> bool:
    """Whether a ray along `direction` through edge `edge` of triangle
    `prim` passes from one side of the surface to the other there (one of
    the edge's other triangles faces the ray the way `prim` does, windings
    made consistent), rather than touching a silhouette edge - a convex
    corner seen from outside, where a single-precision test may rightly
    miss both triangles. An other triangle within `parallel_cos` (the
    cosine of the ray's angle to its normal) of lying edge-on to the ray
    does not count: seen along the ray it is a segment, so the edge is a
    silhouette there unless the float data round the right way (a ray lying
    in a sphere's face plane, through the edge to its neighbour).
    Nor does one narrower than `slack` seen along the ray (its height over
    the edge, projected on the plane across the ray): a ray displaced that
    far (the instanced oracle's transform rounding) may pass beside it, as
    past a zero-thickness box's rim, whose side faces are edge-on slivers.
    `groups` is edge_groups(tris) and `ids` triangle_ids(tris), computed
    once by the caller: both sort the whole mesh, and the leak check asks
    this for many rays."""
    t32 = np.asarray(tris, np.float32)
    row = 3 * prim + edge
    d = np.asarray(direction, np.float64)
    speed = np.linalg.norm(d)

    def facing(r: int) -> float:
        t = t32[r // 3].astype(np.float64)
        n = np.cross(t[1] - t[0], t[2] - t[0])
        f = float(np.dot(n, d))
        if abs(f) <= parallel_cos * np.linalg.norm(n) * speed:
            return 0.0
        if slack > 0:
            # Twice the projected area over the projected edge's length.
            e = t[(r % 3 + 1) % 3] - t[r % 3]
            across = np.linalg.norm(np.cross(e, d))
            if abs(f) <= slack * across:
                return 0.0
        return f

    def start(r: int) -> np.ndarray:  # the edge's first end point (triangle_edges' a)
        return t32[r // 3, r % 3]

    mine = facing(row)
    for other in np.flatnonzero(groups == groups[row]):
        if ids[other // 3] == ids[prim]:  # itself, or a duplicate of it
            continue
        # The same edge run the same way: the other triangle's winding is
        # the opposite of a consistent surface's.
        flip = -1.0 if (start(other) == start(row)).all() else 1.0
        if flip * facing(other) * mine > 0:
            return True
    return False


def touching_vertex(tris: np.ndarray, shared: np.ndarray, prim: int, vertex: int,
                    direction: np.ndarray, parallel_cos: float = 0.0) -> bool:
    """Whether a ray along `direction` through vertex `vertex` of triangle
    `prim` may rightly miss every triangle there: the vertex lies on an open
    edge (the surface's border: no closed fan around it), or some triangle
    around it faces the ray the other way (a corner of a box seen from
    outside, which the ray only touches), or lies within `parallel_cos` of
    edge-on to it (a ray along a cone's edge through its apex: seen along
    the ray the fan's edges there coincide only in exact arithmetic).
    `shared` is shared_mask(tris)."""
    t = np.asarray(tris, np.float32)
    v = t[prim, vertex]
    at = (t == v).all(axis=2)  # (N, 3): triangle i has the vertex as its corner j
    rows, corner = np.nonzero(at)
    # The two edges of a triangle at its corner j: j -> j + 1 and j - 1 -> j.
    if not (shared[rows, corner] & shared[rows, (corner + 2) % 3]).all():
        return True
    around = t[rows].astype(np.float64)
    n = np.cross(around[:, 1] - around[:, 0], around[:, 2] - around[:, 0])
    d = np.asarray(direction, np.float64)
    facing = n @ d
    edge_on = np.abs(facing) <= parallel_cos * np.linalg.norm(n, axis=1) * np.linalg.norm(d)
    return bool(edge_on.any() or ((facing > 0).any() and (facing < 0).any()))


def triangle_ids(tris: np.ndarray) -> np.ndarray:
    """(N,) int: one number per distinct triangle, as a set of three vertices
    (bit for bit, any order): duplicates of a triangle get its number."""
    t = np.ascontiguousarray(tris, np.float32).view(np.uint32).reshape(-1, 3, 3)
    keys = np.sort(t.view(np.dtype((np.void, 12))).reshape(-1, 3), axis=1)
    return np.unique(keys.view(np.uint8).reshape(len(t), -1), axis=0, return_inverse=True)[1].ravel()


def shared_mask(tris: np.ndarray, distinct: bool = False) -> np.ndarray:
    """(N, 3) bool: edge j of triangle i (vertex j to j + 1) is shared. With
    `distinct`, only by another triangle than a duplicate of triangle i: a
    doubled open grid's border is still a border (the leak check's view)."""
    groups = edge_groups(tris)
    if not distinct:
        return (np.bincount(groups)[groups] >= 2).reshape(-1, 3)
    return _shared_by_others(groups, triangle_ids(tris))


def _shared_by_others(groups: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """shared_mask(distinct=True) from the mesh's edge_groups and
    triangle_ids: an edge counts as shared when triangles of two numbers
    have it."""
    pairs = np.unique(np.stack([groups, np.repeat(ids, 3)], axis=1), axis=0)
    return (np.bincount(pairs[:, 0], minlength=groups.max() + 1)[groups] >= 2).reshape(-1, 3)


def shared_edges(tris: np.ndarray) -> np.ndarray:
    """(E, 2, 3) float32: every shared edge once."""
    a, b = triangle_edges(tris)
    keys = edge_keys(a, b)
    shared = shared_mask(tris).ravel()
    _, pick = np.unique(keys[shared], axis=0, return_index=True)
    rows = np.flatnonzero(shared)[pick]
    return np.stack([a[rows], b[rows]], axis=1)


# edge_tables' memory: the last few meshes' tables, by content.
_TABLES: OrderedDict = OrderedDict()
_TABLES_KEPT = 4


def edge_tables(tris: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """edge_groups, triangle_ids and shared_mask(distinct=True) of a mesh,
    computed once for each of the last few meshes (by content: a digest of
    the float32 triangles). Each sorts the whole mesh, and the leak check
    needs them for every batch of rays it checks: on a flattened instanced
    scene of 278k triangles the three sorts were 330 of a test's 350 s."""
    t = np.ascontiguousarray(tris, np.float32)
    key = hashlib.blake2b(t.view(np.uint8).data, digest_size=16).digest() + \
        str(t.shape).encode()
    if key in _TABLES:
        _TABLES.move_to_end(key)
        return _TABLES[key]
    groups, ids = edge_groups(t), triangle_ids(t)
    tables = (groups, ids, _shared_by_others(groups, ids))
    for a in tables:
        a.setflags(write=False)
    _TABLES[key] = tables
    while len(_TABLES) > _TABLES_KEPT:
        _TABLES.popitem(last=False)
    return tables

"""Small scenes made to break trees, described by plain data so that a
failing case can be written down, replayed and kept as a test.

A scene spec is a list of parts, each a dict with a "kind" and integer
parameters; `build_scene(spec)` turns it into float32 triangles. Positions
are snapped to a grid of eighths so that faces of different parts often
coincide, share planes or touch - the cases float code gets wrong. The
Hypothesis strategies that draw specs live in the test suite
(core/tests/library/test_fuzz.py); this module only needs numpy.
"""

from __future__ import annotations

import math

import numpy as np

KINDS = ("box", "tilted_box", "grid", "sliver", "degenerate", "soup", "duplicate", "fan")
# Parts made for BVHs, whose nodes are the boxes of their triangles: many
# overlapping axis-aligned boxes, some flat (zero thickness: two quads in
# one plane) or sharing faces, and axis-aligned quads in a few planes
# (zero-thickness triangle boxes, coplanar neighbours). The BVH's fuzz test
# (test_fuzz.py) draws them with the others.
BOX_KINDS = ("boxes", "quads")


def _grid_point(p) -> np.ndarray:
    return np.asarray(p, np.float64) / 8.0


def _rotation(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _box_tris(lo, hi) -> np.ndarray:
    c = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                  for z in (lo[2], hi[2])])
    f = [[0, 4, 6], [0, 6, 2], [1, 7, 5], [1, 3, 7], [0, 5, 4], [0, 1, 5], [2, 6, 7], [2, 7, 3],
         [0, 2, 3], [0, 3, 1], [4, 7, 6], [4, 5, 7]]
    return c[np.array(f)]


def _part(p: dict, done: list[np.ndarray]) -> np.ndarray:
    rng = np.random.default_rng(p.get("seed", 0))
    kind = p["kind"]
    if kind == "box":
        a, b = _grid_point(p["a"]), _grid_point(p["b"])
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        hi = np.where(hi > lo, hi, lo + 1 / 8)
        return _box_tris(lo, hi)
    if kind == "tilted_box":
        t = _box_tris(-_grid_point(p["half"]) - 1 / 16, _grid_point(p["half"]) + 1 / 16)
        return t @ _rotation(rng).T + _grid_point(p["at"])
    if kind == "grid":
        # An n x n grid in the plane coord[axis] = at[axis], starting at `at`.
        axis, n = p["axis"] % 3, 1 + p["n"] % 4
        u, v = (axis + 1) % 3, (axis + 2) % 3
        size = _grid_point([1 + p["size"] % 16])[0]
        o = _grid_point(p["at"])
        tris = []
        for i in range(n):
            for j in range(n):
                a = o.copy()
                a[u] += size * i / n
                a[v] += size * j / n
                b, c, d = a.copy(), a.copy(), a.copy()
                b[u] += size / n
                c[u] += size / n
                c[v] += size / n
                d[v] += size / n
                tris += [[a, b, c], [a, c, d]]
        return np.array(tris)
    if kind == "sliver":
        # Long thin triangles: length ~1, width 10^-width_exp.
        n = 1 + p["count"] % 6
        a = _grid_point(p["at"]) + rng.normal(size=(n, 3)) * 0.1
        axis = rng.normal(size=(n, 3))
        axis /= np.linalg.norm(axis, axis=1, keepdims=True)
        side = np.cross(axis, rng.normal(size=(n, 3)))
        side /= np.linalg.norm(side, axis=1, keepdims=True)
        w = 10.0 ** -(1 + p["width_exp"] % 5)
        return np.stack([a, a + axis, a + axis + w * side], axis=1)
    if kind == "degenerate":
        # Zero-area triangles: a repeated vertex, or three collinear points.
        a = _grid_point(p["at"])
        b = a + np.array([1.0, 0.5, 0.25])
        return np.array([[a, a, b], [a, b, b], [a, (a + b) / 2, b], [a, a, a]])
    if kind == "soup":
        n = 1 + p["count"] % 12
        return _grid_point(p["at"]) + rng.uniform(-1, 1, (n, 3, 3))
    if kind == "duplicate":
        # Copies of earlier triangles, some with the winding reversed.
        if not done:
            return np.zeros((0, 3, 3))
        prev = np.concatenate(done)
        pick = prev[rng.integers(0, len(prev), 1 + p["count"] % 4)]
        return np.concatenate([pick, pick[:, ::-1]])
    if kind == "fan":
        n = 3 + p["count"] % 30
        c = _grid_point(p["at"])
        ang = np.linspace(0, 2 * math.pi, n + 1)
        rim = c + 0.5 * np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], 1)
        tris = np.stack([np.repeat(c[None], n, 0), rim[:-1], rim[1:]], 1)
        return tris @ _rotation(rng).T if p.get("seed", 0) % 2 else tris
    if kind == "boxes":
        n = 1 + p["count"] % 12
        a = _grid_point(p["at"]) + rng.integers(-8, 8, (n, 3)) / 8
        b = a + rng.integers(0, 6, (n, 3)) / 8
        flat = rng.random(n) < 0.3
        b[flat, rng.integers(0, 3)] = a[flat, 0]  # some collapse to a plane
        out = []
        for lo, hi in zip(np.minimum(a, b), np.maximum(a, b)):
            out.append(_box_tris(lo, hi))
        return np.concatenate(out)
    if kind == "quads":
        n = 1 + p["count"] % 16
        axis = rng.integers(0, 3, n)
        o = _grid_point(p["at"]) + rng.integers(-4, 4, (n, 3)) / 4
        size = rng.integers(1, 5, (n, 2)) / 4
        tris = []
        for k in range(n):
            u, v = (axis[k] + 1) % 3, (axis[k] + 2) % 3
            a = o[k].copy()
            b, c, d = a.copy(), a.copy(), a.copy()
            b[u] += size[k, 0]
            c[u] += size[k, 0]
            c[v] += size[k, 1]
            d[v] += size[k, 1]
            tris += [[a, b, c], [a, c, d]]
        return np.array(tris)
    raise ValueError(f"unknown part kind {kind!r}; known: {', '.join(KINDS + BOX_KINDS)}")


def build_scene(spec: list[dict], scale_exp: int = 0, offset=(0, 0, 0)) -> np.ndarray:
    """Float32 (N, 3, 3) triangles of a spec, scaled by 10^scale_exp and moved by offset."""
    done: list[np.ndarray] = []
    for p in spec:
        t = _part(p, done)
        if len(t):
            done.append(np.asarray(t, np.float64).reshape(-1, 3, 3))
    if not done:
        return np.zeros((0, 3, 3), np.float32)
    tris = np.concatenate(done) * 10.0 ** scale_exp + np.asarray(offset, np.float64)
    return tris.astype(np.float32)


# Instanced scenes: meshes made of parts (above), placed by instances whose
# matrices are drawn from these kinds. "grid" moves by eighths only and
# "turn" turns by quarter turns (exact in float: neighbouring instances
# share faces and edges exactly, as tiled assets do); the others rotate at
# random, scale unevenly (1:8), mirror, shear, or scale by 10^e.
MATRIX_KINDS = ("grid", "turn", "rotate", "stretch", "mirror", "shear", "scale")


def instance_matrix(m: dict) -> np.ndarray:
    """The 3 x 4 world-from-object matrix of an instance spec: {"kind",
    "seed", "at" (eighths), "e" (a power of ten, for "scale")}."""
    rng = np.random.default_rng(m.get("seed", 0))
    at = _grid_point(m.get("at", (0, 0, 0)))
    kind = m["kind"]
    if kind == "grid":
        a = np.eye(3)
    elif kind == "turn":
        a = np.eye(3)
        for axis in rng.integers(0, 3, size=int(rng.integers(1, 4))):
            c = [(1, 2), (2, 0), (0, 1)][axis]
            q = np.eye(3)
            q[c[0], c[0]] = q[c[1], c[1]] = 0.0
            q[c[0], c[1]], q[c[1], c[0]] = -1.0, 1.0
            a = q @ a
    elif kind in ("rotate", "stretch", "mirror", "shear"):
        a = _rotation(rng)
        if kind == "stretch":
            a = a @ np.diag(rng.uniform(0.25, 2.0, 3))
        elif kind == "mirror":
            a = a @ np.diag([1.0, -1.0, 1.0])
        elif kind == "shear":
            a = a @ np.array([[1.0, rng.uniform(-1, 1), 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    elif kind == "scale":
        a = np.eye(3) * 10.0 ** int(m.get("e", 0))
    else:
        raise ValueError(f"unknown instance kind {kind!r}; known: {', '.join(MATRIX_KINDS)}")
    return np.hstack([a, at.reshape(3, 1)])


def build_instanced_scene(spec: dict):
    """(meshes, mesh_index, matrices) of an instanced spec: {"meshes": [a
    part list per mesh], "instances": [{"mesh": i, **instance_matrix's}]}.
    Meshes without triangles are dropped with their instances."""
    meshes, keep = [], {}
    for i, parts in enumerate(spec["meshes"]):
        tris = build_scene(parts)
        if len(tris):
            keep[i] = len(meshes)
            meshes.append(tris)
    inst = [m for m in spec["instances"] if m["mesh"] in keep]
    mats = np.array([instance_matrix(m) for m in inst]).reshape(-1, 3, 4)
    return meshes, np.array([keep[m["mesh"]] for m in inst], np.int64), mats

"""The exact first hit of a ray: ray/triangle intersection decided in exact
rational arithmetic on the values the tracers were given, for the oracle's
verdict on every ray where a tree and Embree disagree (oracle.compare).

Two stages per ray. A double-precision filter over the scene's triangles
with a proven error bound on each quantity it computes: a box test (groups
of consecutive triangles, then each triangle) widened far beyond its
rounding, then Moller and Trumbore's barycentric numerators, determinant and
distance (triple products), each with a forward error bound carried from
the inputs' own (an instanced vertex is a matrix product in double). A
triangle whose barycentric signs certainly conflict is missed; one whose t
interval certainly lies outside the segment, or beyond a certain hit's,
is not first. The few triangles left are decided in integers: every input
is a float, a dyadic rational n / 2^e, so scaled by a common power of two
it is an integer, and the edge functions d . (a_i x a_j), a_i = v_i - o,
and the volume a0 . (a1 x a2) are then exact (Python's unbounded ints: what
fractions.Fraction would compute, without its gcd on every step); t is
their Fraction.

What is exact here is a convention as much as arithmetic in one case: a ray
that lies exactly in a triangle's plane has no point where it crosses it,
and it does not hit it (neither do the trees; Embree's test rejects it too,
det = 0). A tracer that reports a hit on such a triangle is neither right
nor wrong: `UNDECIDED` (the ray touches the triangle along a segment, or
passes beside it in its plane - which one is not decided here). A
zero-area triangle is never hit.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

# Per answer: the answer is the exact first hit (or, a miss, there is none);
# it is not; or it is a hit on a triangle the ray lies in (module docstring).
WRONG, RIGHT, UNDECIDED = 0, 1, 2

# Unit roundoff of double precision.
_U = 2.0 ** -53
# The filter's bounds: each triple product's rounding is at most about 6 u
# of the sum of its terms' magnitudes (two products and a difference per
# cross component, three products and two sums in the dot); 16 u leaves
# room. The absolute term covers underflow in any of the operations.
_TRIPLE_ROUNDINGS = 16.0
_TINY = 2.0 ** -1000
# The box test's margin, relative to the coordinates' magnitude: far above
# the slab test's own double rounding (a few u), so a box it rejects the
# exact ray misses.
_BOX_MARGIN = 1e-7
# Consecutive triangles per box of the box test's first level.
_GROUP = 64


def _dyadic(x: float) -> tuple[int, int]:
    """The float x as n / 2^e exactly (e >= 0)."""
    p, q = float(x).as_integer_ratio()
    return p, q.bit_length() - 1


def _dyadic_sum(terms) -> tuple[int, int]:
    """The sum of dyadic numbers (n, e), exactly."""
    e = max(t[1] for t in terms)
    return sum(n << (e - k) for n, k in terms), e


class ExactScene:
    """The triangles as given, for exact tests: doubles for the filter (with
    a bound on how far each coordinate may be from the exact one) and, per
    triangle on demand, the exact coordinates as dyadic numbers (n, e):
    n / 2^e."""

    def __init__(self, approx: np.ndarray, error: np.ndarray, exact_vertices):
        self.approx = approx
        self.error = error
        self._exact_vertices = exact_vertices
        self._cache: dict[int, tuple] = {}
        # Each exact triangle's box (the error bounds), with a margin for
        # the rounding of its corners; and
        # the boxes of groups of _GROUP consecutive triangles (input order is
        # mostly spatially coherent: a mesh, an instance), tested first.
        lo, hi = (approx - error).min(axis=1), (approx + error).max(axis=1)
        pad = _BOX_MARGIN * np.maximum(np.abs(lo), np.abs(hi)).max(axis=1, keepdims=True) + _TINY
        self.box_lo, self.box_hi = lo - pad, hi + pad
        n = len(approx)
        groups = -(-n // _GROUP)
        fill = groups * _GROUP - n
        self.group_lo = np.concatenate([self.box_lo, np.full((fill, 3), np.inf)]).reshape(
            groups, _GROUP, 3).min(axis=1)
        self.group_hi = np.concatenate([self.box_hi, np.full((fill, 3), -np.inf)]).reshape(
            groups, _GROUP, 3).max(axis=1)

    @classmethod
    def triangles(cls, triangles) -> "ExactScene":
        """The (T, 3, 3) float32 triangles a flat tree and Embree trace."""
        tris = np.ascontiguousarray(triangles, np.float32)

        def exact(k):
            return tuple(tuple(_dyadic(x) for x in v) for v in tris[k].tolist())
        return cls(tris.astype(np.float64), np.zeros(tris.shape), exact)

    @classmethod
    def instanced(cls, meshes, mesh_index, matrices) -> "ExactScene":
        """Instances as given to build_instanced: the exact world triangle is
        the (float64) matrix times the (float32) mesh vertex plus the
        translation, in rationals - what the two-level trace tests in object
        space, exactly. The triangles in flatten()'s order."""
        mats = np.asarray(matrices, np.float64)
        if mats.ndim != 3 or mats.shape[1:] not in ((3, 4), (4, 4)):
            raise ValueError(f"matrices must have shape (M, 3, 4) or (M, 4, 4), got {mats.shape}")
        mats = mats[:, :3, :]
        idx = np.asarray(mesh_index, np.int64)
        if len(idx) != len(mats):
            raise ValueError(f"{len(mats)} matrices for {len(idx)} instances: one per instance")
        meshes = [np.ascontiguousarray(m, np.float32) for m in meshes]
        parts, errs, owner = [], [], []
        for i, (mesh, m) in enumerate(zip(idx, mats)):
            v = meshes[mesh].astype(np.float64)
            parts.append(v @ m[:, :3].T + m[:, 3])
            # Each world coordinate is a sum of three products and a
            # translation in double: within 4 u of the sum of magnitudes
            # (generously 8 u).
            errs.append(8 * _U * (np.abs(v) @ np.abs(m[:, :3]).T + np.abs(m[:, 3])))
            owner.append(np.stack([np.full(len(v), i), np.arange(len(v))], axis=1))
        if not parts:
            z = np.zeros((0, 3, 3))
            return cls(z, z, lambda k: None)
        owner = np.concatenate(owner)
        exact_mats = {}

        def exact(k):
            inst, tri = (int(x) for x in owner[k])
            if inst not in exact_mats:
                exact_mats[inst] = [[_dyadic(x) for x in row] for row in mats[inst].tolist()]
            m = exact_mats[inst]
            verts = []
            for v in meshes[idx[inst]][tri].tolist():
                vi = [_dyadic(x) for x in v]
                verts.append(tuple(_dyadic_sum([(m[r][j][0] * vi[j][0], m[r][j][1] + vi[j][1])
                                                for j in range(3)] + [m[r][3]])
                                   for r in range(3)))
            return tuple(verts)
        return cls(np.concatenate(parts), np.concatenate(errs), exact)

    def exact(self, k: int) -> tuple:
        got = self._cache.get(k)
        if got is None:
            got = self._cache[k] = self._exact_vertices(k)
        return got


def _dot_cross(x, y, z):
    """x . (y x z) per row of (N, 3) arrays, written out (no temporaries of
    shape (N, 3))."""
    return (x[:, 0] * (y[:, 1] * z[:, 2] - y[:, 2] * z[:, 1])
            + x[:, 1] * (y[:, 2] * z[:, 0] - y[:, 0] * z[:, 2])
            + x[:, 2] * (y[:, 0] * z[:, 1] - y[:, 1] * z[:, 0]))


def _dot_cross_abs(x, y, z):
    """|x| . (|y| x |z|) with every product's sign made positive (of
    non-negative inputs): bounds the magnitude of each term of _dot_cross."""
    return (x[:, 0] * (y[:, 1] * z[:, 2] + y[:, 2] * z[:, 1])
            + x[:, 1] * (y[:, 2] * z[:, 0] + y[:, 0] * z[:, 2])
            + x[:, 2] * (y[:, 0] * z[:, 1] + y[:, 1] * z[:, 0]))


def _triple(x, y, z, ex, ey, ez):
    """x . (y x z) in double, and a bound on its distance from the exact
    value of the exact x, y, z, given bounds ex, ey, ez on how far the
    inputs are from them (componentwise)."""
    ax, ay, az = np.abs(x), np.abs(y), np.abs(z)
    ayy, azz = ay + ey, az + ez
    # The inputs' errors carried through (telescoped: every term positive),
    # plus the rounding of the double computation on the perturbed values.
    big = _dot_cross_abs(ax + ex, ayy, azz)
    moved = _dot_cross_abs(ex, ayy, azz) + _dot_cross_abs(ax, ey, azz) + \
        _dot_cross_abs(ax, ay, ez)
    return _dot_cross(x, y, z), (moved + _TRIPLE_ROUNDINGS * _U * big) * (1 + 64 * _U) + _TINY


def _boxes_reached(blo, bhi, o, d, lo: float, hi: float) -> np.ndarray:
    """Which boxes the ray's segment [lo, hi] may meet (a superset: the
    double slab test widened far beyond its rounding)."""
    enter = np.full(len(blo), -np.inf)
    leave = np.full(len(blo), np.inf)
    ok = np.ones(len(blo), bool)
    for k in range(3):
        if d[k] == 0:
            ok &= (blo[:, k] <= o[k]) & (o[k] <= bhi[:, k])
            continue
        t1, t2 = (blo[:, k] - o[k]) / d[k], (bhi[:, k] - o[k]) / d[k]
        enter = np.maximum(enter, np.minimum(t1, t2))
        leave = np.minimum(leave, np.maximum(t1, t2))
    # Each slab distance is two roundings from the exact one (relative: a
    # difference and a quotient); widened by far more.
    with np.errstate(invalid="ignore"):
        enter = enter - _BOX_MARGIN * np.abs(enter) - _TINY
        leave = leave + _BOX_MARGIN * np.abs(leave) + _TINY
        return ok & (enter <= leave) & (leave >= lo) & (enter <= hi)


def _candidates(scene: ExactScene, o, d, lo: float, hi: float) -> np.ndarray:
    """The triangles the exact ray may meet first within [lo, hi] (closed:
    a superset of the open segment's); every other one it certainly misses,
    meets outside the segment or meets after a certain hit."""
    groups = np.flatnonzero(_boxes_reached(scene.group_lo, scene.group_hi, o, d, lo, hi))
    idx = (groups[:, None] * _GROUP + np.arange(_GROUP)).ravel()
    idx = idx[idx < len(scene.approx)]
    idx = idx[_boxes_reached(scene.box_lo[idx], scene.box_hi[idx], o, d, lo, hi)]
    if not len(idx):
        return idx
    # Moller and Trumbore's form: the origin's offset s appears once in each
    # product, so a far origin costs only linearly in the bound (the edge
    # functions d . (a_i x a_j) would carry it twice).
    v = scene.approx[idx]
    ev = scene.error[idx] * (1 + 2 * _U)
    e1, e2, s = v[:, 1] - v[:, 0], v[:, 2] - v[:, 0], o - v[:, 0]
    ee1 = ev[:, 1] + ev[:, 0] + 2 * _U * np.abs(e1)
    ee2 = ev[:, 2] + ev[:, 0] + 2 * _U * np.abs(e2)
    es = ev[:, 0] + 2 * _U * np.abs(s)
    dd = np.broadcast_to(d, (len(idx), 3))
    zero = np.zeros((len(idx), 3))
    det, edet = _triple(e1, dd, e2, ee1, zero, ee2)   # e1 . (d x e2)
    bu, eu = _triple(s, dd, e2, es, zero, ee2)        # s . (d x e2)
    bv, ev_ = _triple(dd, s, e1, zero, es, ee1)       # d . (s x e1)
    num, enum = _triple(e2, s, e1, ee2, es, ee1)      # e2 . (s x e1)
    bw = det - bu - bv
    ebw = (edet + eu + ev_) * (1 + 4 * _U) + 3 * _U * (np.abs(det) + np.abs(bu) + np.abs(bv)) \
        + _TINY
    # Barycentric numerators (of vertices 0, 1, 2) over det.
    w, ew = np.stack([bw, bu, bv], axis=1), np.stack([ebw, eu, ev_], axis=1)
    with np.errstate(invalid="ignore", over="ignore"):
        finite = np.isfinite(w).all(axis=1) & np.isfinite(ew).all(axis=1) & \
            np.isfinite(det) & np.isfinite(edet) & np.isfinite(num) & np.isfinite(enum)
        sign = np.where(w > ew, 1, np.where(w < -ew, -1, 0))
        sdet = np.where(det > edet, 1, np.where(det < -edet, -1, 0))
        miss = ((sign > 0).any(axis=1) & (sign < 0).any(axis=1)) | \
            ((sdet != 0) & (sign == -sdet[:, None]).any(axis=1))
        hit = (sdet != 0) & (sign == sdet[:, None]).all(axis=1)
        # t = num / det on an interval, where det's sign is certain.
        big_d, small_d = np.abs(det) + edet, np.abs(det) - edet
        nn = np.where(sdet < 0, -num, num)
        t_lo = np.where(nn - enum >= 0, (nn - enum) / big_d, (nn - enum) / small_d)
        t_hi = np.where(nn + enum >= 0, (nn + enum) / small_d, (nn + enum) / big_d)
        t_lo = t_lo - 4 * _U * np.abs(t_lo) - _TINY
        t_hi = t_hi + 4 * _U * np.abs(t_hi) + _TINY
        known_t = finite & (sdet != 0) & np.isfinite(t_lo) & np.isfinite(t_hi)
        outside = known_t & ((t_hi < lo) | (t_lo > hi))
        inside = known_t & hit & finite & (t_lo > lo) & (t_hi < hi)
    drop = finite & (miss | outside)
    if inside.any():
        drop |= known_t & (t_lo > t_hi[inside].min())
    return idx[~drop]


def _exact_test(verts, o, d):
    """("hit", t as a Fraction), ("miss", None) or ("in_plane", None): the
    ray (o, d) against the triangle, every coordinate a dyadic (n, e), in
    integers at the smallest common power-of-two scale."""
    e = max(max(c[1] for c in v) for v in (*verts, o))
    ed = max(c[1] for c in d)
    ox, oy, oz = (n << (e - k) for n, k in o)
    dx, dy, dz = (n << (ed - k) for n, k in d)
    a = [[(n << (e - k)) - oc for (n, k), oc in zip(v, (ox, oy, oz))] for v in verts]
    (ax, ay, az), (bx, by, bz), (cx, cy, cz) = a
    # The edge functions d . (a_i x a_j) and the volume a0 . (a1 x a2).
    w0 = dx * (by * cz - bz * cy) + dy * (bz * cx - bx * cz) + dz * (bx * cy - by * cx)
    w1 = dx * (cy * az - cz * ay) + dy * (cz * ax - cx * az) + dz * (cx * ay - cy * ax)
    w2 = dx * (ay * bz - az * by) + dy * (az * bx - ax * bz) + dz * (ax * by - ay * bx)
    det = w0 + w1 + w2
    num = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
    if det == 0:
        e1 = (bx - ax, by - ay, bz - az)
        e2 = (cx - ax, cy - ay, cz - az)
        area = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0])
        if area == (0, 0, 0) or num != 0:
            return "miss", None  # zero area, or parallel beside the plane
        return "in_plane", None
    if (det > 0 and min(w0, w1, w2) < 0) or (det < 0 and max(w0, w1, w2) > 0):
        return "miss", None
    # t = num / det: num is at scale 2^(3 e), det at 2^(2 e + ed).
    t = Fraction(num, det)
    return "hit", t * (1 << (ed - e)) if ed >= e else t / (1 << (e - ed))


class RayVerdict:
    """One ray's exact answer within its segment: the triangles hit first
    on the open segment (lo, hi) and on the closed one [lo, hi], the exact
    t of each, and the triangles the ray lies in the plane of (of those it
    may touch)."""

    def __init__(self, scene: ExactScene, origin, direction, lo: float, hi: float):
        o64 = np.asarray(origin, np.float32).astype(np.float64)
        d64 = np.asarray(direction, np.float32).astype(np.float64)
        o = [_dyadic(x) for x in np.asarray(origin, np.float32).tolist()]
        d = [_dyadic(x) for x in np.asarray(direction, np.float32).tolist()]
        # The segment's ends as both tracers take them: float32.
        lo32, hi32 = float(np.float32(lo)), float(np.float32(hi))
        flo = Fraction(lo32)
        fhi = None if np.isinf(hi32) else Fraction(hi32)
        self.t: dict[int, Fraction] = {}
        self.in_plane: set[int] = set()
        for k in _candidates(scene, o64, d64, lo32, hi32).tolist():
            kind, t = _exact_test(scene.exact(k), o, d)
            if kind == "hit":
                self.t[k] = t
            elif kind == "in_plane":
                self.in_plane.add(k)
        self.first_open = self._first(lambda t: flo < t and (fhi is None or t < fhi))
        self.first_closed = self._first(lambda t: flo <= t and (fhi is None or t <= fhi))

    def _first(self, within) -> set[int]:
        ts = {k: t for k, t in self.t.items() if within(t)}
        if not ts:
            return set()
        best = min(ts.values())
        return {k for k, t in ts.items() if t == best}

    def verdict(self, prim: int, closed: bool = False) -> int:
        """RIGHT, WRONG or UNDECIDED for the answer `prim` (-1: a miss), on
        the open segment (ours) or the closed one (Embree's)."""
        first = self.first_closed if closed else self.first_open
        if prim < 0:
            return RIGHT if not first else WRONG
        if prim in self.in_plane:
            return UNDECIDED
        return RIGHT if prim in first else WRONG

    def first_hit(self):
        """(smallest index of the triangles hit first on the open segment,
        its exact t), or (-1, None)."""
        if not self.first_open:
            return -1, None
        k = min(self.first_open)
        return k, self.t[k]

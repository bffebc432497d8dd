"""Embree (through `embreex`) as the reference for closest hits, and the
agreement measure used by tests, the benchmark and the add-on."""

from __future__ import annotations

import time

import numpy as np

from . import exact

# The oracle's public API, used by the add-on, the tests and the benchmarks.
__all__ = ["EmbreeTracer", "available", "compare", "edge_distance", "exact_first_hit",
           "foreign_embree_library", "instanced_scene", "judge", "plane_distance"]


def available() -> bool:
    try:
        import embreex  # noqa: F401
    except ImportError:
        return False
    return True


def foreign_embree_library():
    """Name of an Embree library whose symbols the host process exports, if any.

    Some Linux distributions' Blender builds (Debian's 3.4, for one) link a
    shared libembree3 into the executable. Its `rtc*` symbols are then global,
    embreex's bundled Embree 4 binds to them and crashes on the first query.
    Libraries loaded privately (the bpy module's own Embree) do not clash.
    """
    import ctypes
    import os

    try:
        ctypes.CDLL(None).rtcNewDevice
    except (AttributeError, OSError):
        return None
    try:
        with open("/proc/self/maps") as maps:
            paths = [line.rsplit(" ", 1)[-1] for line in maps.read().splitlines()]
    except OSError:
        paths = []
    names = [os.path.basename(p) for p in paths
             if os.path.basename(p).startswith("libembree") and "embreex" not in p]
    return names[0] if names else "Embree library"


class EmbreeTracer:
    """Closest-hit queries on Embree, returning the layout of Tree.intersect."""

    def __init__(self, triangles: np.ndarray):
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        tris = np.ascontiguousarray(triangles, dtype=np.float32)
        start = time.perf_counter()
        self.scene = rtcore_scene.EmbreeScene()
        vertices = tris.reshape(-1, 3)
        faces = np.arange(len(vertices), dtype=np.int32).reshape(-1, 3)
        self._mesh = TriangleMesh(self.scene, vertices, faces)
        # embreex commits the scene (builds Embree's BVH) on its first query:
        # one ray here puts that build in build_seconds, not in the first trace.
        self.scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32), output=1)
        self.build_seconds = time.perf_counter() - start
        self.last_seconds = 0.0

    def intersect(self, origins, directions, tmax=None) -> dict:
        o = np.ascontiguousarray(origins, dtype=np.float32)
        d = np.ascontiguousarray(directions, dtype=np.float32)
        kwargs = {}
        if tmax is not None:
            # A writable copy: embreex refuses read-only buffers.
            kwargs["dists"] = np.array(np.broadcast_to(np.asarray(tmax, np.float32), (len(o),)))
        start = time.perf_counter()
        r = self.scene.run(o, d, output=1, **kwargs)
        self.last_seconds = time.perf_counter() - start
        prim = np.asarray(r["primID"], dtype=np.int32)
        hit = prim >= 0
        t = np.where(hit, np.asarray(r["tfar"], np.float32), np.float32(np.inf))
        return {"t": t, "prim": prim,
                "u": np.where(hit, r["u"], 0).astype(np.float32),
                "v": np.where(hit, r["v"], 0).astype(np.float32)}


def _hit_rows(triangles, prim, origins, directions):
    """The rays that hit (prim >= 0): the mask, and their triangles, origins
    and directions in double precision."""
    ok = prim >= 0
    return (ok, triangles[prim[ok]].astype(np.float64), origins[ok].astype(np.float64),
            directions[ok].astype(np.float64))


def edge_distance(triangles: np.ndarray, prim: np.ndarray, origins: np.ndarray,
                  directions: np.ndarray, per_edge: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance (double precision) from each ray's crossing of the plane
    of triangle prim[i] to that triangle's boundary (negative: outside), and
    the magnitude of the coordinates involved. NaN where prim < 0.
    `per_edge`: the distances to each of its three lines instead, (N, 3),
    column j the edge from vertex j to vertex j + 1."""
    dist = np.full(len(prim), np.nan)
    scale = np.full(len(prim), np.nan)
    ok, tri, o, d = _hit_rows(triangles, prim, origins, directions)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    det = np.where(det == 0, np.finfo(np.float64).tiny, det)
    s = o - tri[:, 0]
    u = np.einsum("ij,ij->i", s, p) / det
    v = np.einsum("ij,ij->i", d, np.cross(s, e1)) / det
    bary = np.stack([1 - u - v, u, v], axis=1)
    # The barycentric coordinate of vertex i times the height over the
    # opposite edge is the distance to that edge.
    twice_area = np.linalg.norm(np.cross(e1, e2), axis=1)
    opposite = np.stack([np.linalg.norm(tri[:, 2] - tri[:, 1], axis=1),
                         np.linalg.norm(e2, axis=1), np.linalg.norm(e1, axis=1)], axis=1)
    heights = twice_area[:, None] / np.maximum(opposite, 1e-300)
    dist[ok] = (bary * heights).min(axis=1)
    scale[ok] = np.maximum(np.abs(tri).max(axis=(1, 2)), np.abs(o).max(axis=1))
    if per_edge:
        # Column j: the edge from vertex j to vertex j + 1 (opposite vertex j + 2).
        edges = np.full((len(prim), 3), np.nan)
        edges[ok] = (bary * heights)[:, [2, 0, 1]]
        return edges, scale
    return dist, scale


def plane_distance(triangles: np.ndarray, prim: np.ndarray, origins: np.ndarray,
                   directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ray parameter t (double precision) at which each ray crosses the
    plane of triangle prim[i], and the float32 rounding scale of that t: how
    far a single-precision computation of it may honestly be off (a few ulps
    of the coordinates involved, divided by the ray's speed towards the
    plane). NaN where prim < 0 or the ray runs parallel to the plane."""
    t = np.full(len(prim), np.nan)
    err = np.full(len(prim), np.nan)
    ok, tri, o, d = _hit_rows(triangles, prim, origins, directions)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    nd = np.einsum("ij,ij->i", n, d)
    with np.errstate(divide="ignore", invalid="ignore"):
        t[ok] = np.einsum("ij,ij->i", n, tri[:, 0] - o) / nd
        scale = np.maximum(np.abs(tri).max(axis=(1, 2)), np.abs(o).max(axis=1))
        err[ok] = np.finfo(np.float32).eps * scale / np.abs(nd)
    return t, err


def speed_of(directions) -> np.ndarray:
    """|d| per ray, in double."""
    return np.linalg.norm(np.asarray(directions, np.float64), axis=1)


def compare(ours: dict, ref: dict, rel_tol: float = 1e-4, *, triangles=None, origins=None,
            directions=None, edge_ulps: float = 8.0, tmin=None, tmax=None, slack=None,
            scene=None) -> dict:
    """How far two hit sets agree, and, given the triangles and rays, an
    exact verdict on every ray where they do not. Every ray lands in exactly
    one of these classes (their counts sum to "rays"):

    `agree` - both miss, or both hit the same primitive, or both hit at the
    same distance within rel_tol (two primitives tie at a shared edge or
    coincide), or both hit copies of one triangle (the same vertices bit for
    bit: "duplicates"; coincident instances flatten to such copies).

    The rest ("disagreeing") are judged in exact rational arithmetic
    (bsplab.exact): the exact first hit of the float32 ray on the scene as
    given - `scene` (an exact.ExactScene; for an instanced scene
    instanced_scene(), its world triangles exactly the matrices times the
    mesh vertices), by default the float32 `triangles` themselves - on our
    open segment tmin < t < tmax, and on Embree's closed tnear <= t <= tfar.

    `embree_wrong` - our answer is the exact first hit (or, a miss, there is
    none), and Embree's is not, even by its own closed segment: Embree's
    float rounding, which grows with the origin's distance from the
    triangle, or (instanced) the rounding of the flattened scene it was
    given, decided the ray.

    Of the others, the rounding classes: a float32 test on float input may
    rightly decide these either way, whatever the exact answer -
    `grazing`: the ray passes within edge_ulps single-precision ulps (of
    the coordinates' magnitude; computed in double precision) of the
    boundary of a triangle one side hit, or within as many roundings of where
    it crosses its plane (for a ray almost in the plane a long way), or both
    hit triangles at distances equal within the coordinates' rounding;
    `at_ends`: the triangle one side hit lies within edge_ulps roundings of
    the segment's start (tmin, default 0: a ray that starts on a surface) or
    end (tmax: a shadow ray that ends on one), where Embree's closed segment
    and our open one differ; `degenerate`: a side hit a triangle of zero
    area. `slack` (per ray, world units: how far a two-level trace's ray
    may be from the world ray, InstancedTree.transform_slack) widens the
    grazing and end tolerances.

    `bsplab_wrong` - our answer is exactly not the first hit, beyond
    rounding. `undecided` - the rest: our hit is on a triangle the ray lies
    exactly in the plane of (it has no crossing point to judge:
    exact.UNDECIDED), or both answers are right by their own segment's rule.
    Without triangles every disagreeing ray is undecided.

    Counts under each name; index arrays: "disagreeing", "embree_wrong_rays",
    "bsplab_wrong_rays", "undecided_rays" and "failing" (bsplab_wrong and
    undecided together: the rays whose answer nothing vouches for, which a
    test asserts there are none of)."""
    pa, pb = ours["prim"], ref["prim"]
    ta, tb = ours["t"].astype(np.float64), ref["t"].astype(np.float64)
    both_miss = (pa < 0) & (pb < 0)
    both_hit = (pa >= 0) & (pb >= 0)
    same_prim = both_hit & (pa == pb)
    with np.errstate(invalid="ignore"):
        close_t = both_hit & (np.abs(ta - tb) <= rel_tol * np.maximum(np.abs(tb), 1e-30))
    # Two indices of one triangle (a duplicate: the same three vertices, bit
    # for bit, in any order - coincident instances flatten to such copies)
    # are one surface: either is the right answer, whatever each side's
    # rounding of t on it.
    same_surface = np.zeros(len(pa), bool)
    if triangles is not None:
        rows = np.flatnonzero(both_hit & ~same_prim & ~close_t)
        if len(rows):
            tri = np.ascontiguousarray(triangles, np.float32)

            def vertex_sets(p):  # each triangle's vertices as bytes, sorted
                v = np.ascontiguousarray(tri[p]).view(np.dtype((np.void, 12))).reshape(-1, 3)
                return np.sort(v, axis=1)
            same_surface[rows] = (vertex_sets(pa[rows]) == vertex_sets(pb[rows])).all(axis=1)
    agree = both_miss | same_prim | close_t | same_surface
    bad = np.flatnonzero(~agree)
    grazing = np.zeros(len(bad), bool)
    at_ends = np.zeros(len(bad), bool)
    degenerate = np.zeros(len(bad), bool)
    if len(bad) and triangles is not None:
        o, d = origins[bad], directions[bad]
        lo = np.zeros(len(bad)) if tmin is None else \
            np.broadcast_to(np.asarray(tmin, np.float64), (len(pa),))[bad]
        hi = np.full(len(bad), np.inf) if tmax is None else \
            np.broadcast_to(np.asarray(tmax, np.float64), (len(pa),))[bad]
        moved = np.zeros(len(bad)) if slack is None else \
            np.broadcast_to(np.asarray(slack, np.float64), (len(pa),))[bad]
        for prims in (pa[bad], pb[bad]):
            with np.errstate(all="ignore"):
                dist, scale = edge_distance(triangles, prims, o, d)
                t, err = plane_distance(triangles, prims, o, d)
            # Where the ray crosses the plane is only known to err (in t):
            # for a ray almost in the plane that is a long way along it.
            along = err * np.linalg.norm(d.astype(np.float64), axis=1)
            with np.errstate(all="ignore"):
                grazing |= np.abs(dist) <= edge_ulps * (np.finfo(np.float32).eps * scale + along) \
                    + moved
                tol = edge_ulps * (err + np.finfo(np.float32).eps * np.abs(t)) + moved / speed_of(d)
                at_ends |= (np.abs(t - lo) <= tol) | (np.abs(t - hi) <= tol)
        at_ends &= ~grazing
        # A zero-area triangle (in exact arithmetic) is a segment or a point:
        # we never hit one; Embree sometimes does.
        for prims in (pa[bad], pb[bad]):
            ok = prims >= 0
            t = triangles[prims[ok]].astype(np.float64)
            area = np.abs(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])).sum(axis=1)
            degenerate[np.flatnonzero(ok)[area == 0]] = True
        degenerate &= ~(grazing | at_ends)
        # Two triangles hit at distances within the rounding of the
        # coordinates (coincident or touching surfaces near the origin,
        # where a relative tolerance on t is too tight).
        both = (pa[bad] >= 0) & (pb[bad] >= 0)
        if both.any():
            ta_, tb_ = ta[bad][both], tb[bad][both]
            scale = np.maximum(np.abs(triangles[pa[bad][both]]).max(axis=(1, 2)),
                               np.abs(triangles[pb[bad][both]]).max(axis=(1, 2)))
            scale = np.maximum(scale, np.abs(o[both]).max(axis=1)).astype(np.float64)
            speed = np.linalg.norm(d[both].astype(np.float64), axis=1)
            tie = np.abs(ta_ - tb_) * speed <= edge_ulps * np.finfo(np.float32).eps * scale \
                + moved[both]
            near = np.zeros(len(bad), bool)
            near[np.flatnonzero(both)[tie]] = True
            grazing |= near & ~(at_ends | degenerate)
    embree_wrong = np.zeros(len(bad), bool)
    bsplab_wrong = np.zeros(len(bad), bool)
    if len(bad) and triangles is not None:
        ours_v, theirs_v = judge(scene if scene is not None else exact.ExactScene.triangles(
            triangles), pa[bad], pb[bad], origins[bad], directions[bad], lo, hi)
        embree_wrong = (ours_v == exact.RIGHT) & (theirs_v == exact.WRONG)
        grazing &= ~embree_wrong
        at_ends &= ~embree_wrong
        degenerate &= ~embree_wrong
        bsplab_wrong = (ours_v == exact.WRONG) & ~(grazing | at_ends | degenerate)
    undecided = ~(embree_wrong | grazing | at_ends | degenerate | bsplab_wrong)
    n = len(pa)
    return {
        "rays": n,
        "agree": int(agree.sum()),
        "agreement": float(agree.mean()) if n else 1.0,
        "same_prim": int(same_prim.sum()),
        "ties": int((close_t & ~same_prim).sum()),
        "duplicates": int(same_surface.sum()),
        "hit_only_ours": int(((pa >= 0) & (pb < 0)).sum()),
        "hit_only_ref": int(((pa < 0) & (pb >= 0)).sum()),
        "different": int((both_hit & ~same_prim & ~close_t & ~same_surface).sum()),
        "embree_wrong": int(embree_wrong.sum()),
        "grazing": int(grazing.sum()),
        "at_ends": int(at_ends.sum()),
        "degenerate": int(degenerate.sum()),
        "bsplab_wrong": int(bsplab_wrong.sum()),
        "undecided": int(undecided.sum()),
        "disagreeing": bad,
        "embree_wrong_rays": bad[embree_wrong],
        "bsplab_wrong_rays": bad[bsplab_wrong],
        "undecided_rays": bad[undecided],
        "failing": bad[bsplab_wrong | undecided],
    }


def judge(scene, ours, theirs, origins, directions, tmin, tmax) -> tuple[np.ndarray, np.ndarray]:
    """Per ray, the exact verdict (exact.RIGHT, WRONG or UNDECIDED) on our
    answer `ours` (prim, -1 a miss) on the open segment tmin < t < tmax, and
    on Embree's `theirs` on the closed one, against `scene` (an
    exact.ExactScene)."""
    ours_v = np.zeros(len(ours), np.int8)
    theirs_v = np.zeros(len(ours), np.int8)
    lo = np.broadcast_to(np.asarray(0.0 if tmin is None else tmin, np.float64), (len(ours),))
    hi = np.broadcast_to(np.asarray(np.inf if tmax is None else tmax, np.float64), (len(ours),))
    for i in range(len(ours)):
        ray = exact.RayVerdict(scene, origins[i], directions[i], lo[i], hi[i])
        ours_v[i] = ray.verdict(int(ours[i]))
        theirs_v[i] = ray.verdict(int(theirs[i]), closed=True)
    return ours_v, theirs_v


def instanced_scene(tree) -> "exact.ExactScene":
    """The exact world triangles of a two-level tree's instances (the scene
    as given: float64 matrices times the float32 mesh vertices), in the
    order of its flatten(): compare's `scene` for an instanced trace."""
    return exact.ExactScene.instanced([t.triangles for t in tree.meshes], tree.mesh_index,
                                      tree.matrices)


# Rays closer than this (the cosine of their angle to the normal) to a
# triangle's plane are taken as lying in it by the leak check.
PARALLEL_COS = 1e-4


def leaks(ours: dict, ref: dict, *, triangles, origins, directions, tmax=None,
          rel_tol: float = 1e-4, edge_ulps: float = 8.0, slack=None) -> np.ndarray:
    """The rays that went through the surface: Embree hits, and we miss or
    hit farther (beyond rel_tol of its t). Not counted: rays that graze an
    open (unshared) edge of the triangle Embree hit, where a single-precision
    test may rightly miss, or a silhouette edge (a convex corner the ray only
    touches), hits on zero-area triangles, hits at the segment's
    start (t = 0: a ray leaving a surface) or end (tmax), and rays within
    PARALLEL_COS of the hit triangle's plane (a ray lying in it: where it
    crosses the plane is not decided by the float data), or of the plane of
    a triangle at the edge or vertex it passes through (seen along the ray
    that triangle is a segment, and whether the ray passes the surface there
    or through it is decided only by rounding). A shared edge is otherwise no
    excuse: one of its triangles must be hit whatever the rounding
    (mesh_edges). `slack` (per ray, world units) is how far our ray may be
    displaced (compare's): a hit that much farther along the ray's crossing
    of the plane is no leak, and so is a hit on a neighbour of Embree's
    triangle across an edge or vertex the ray passes within slack of
    (_across_shared_edge). Returns the indices."""
    from . import mesh_edges

    pa, pb = ours["prim"], ref["prim"]
    ta, tb = ours["t"].astype(np.float64), ref["t"].astype(np.float64)
    moved = np.zeros(len(pa)) if slack is None else \
        np.broadcast_to(np.asarray(slack, np.float64), (len(pa),))
    with np.errstate(invalid="ignore"):
        # The displacement along the ray, at the crossing of Embree's
        # triangle's plane: at most slack / (|d| cos) - bounded below by
        # PARALLEL_COS, beyond which the ray counts as in the plane anyway.
        cos = np.full(len(pa), 1.0)
        hit_ref = pb >= 0
        if slack is not None and hit_ref.any():
            t3 = np.asarray(triangles, np.float64)[pb[hit_ref]]
            nrm = np.cross(t3[:, 1] - t3[:, 0], t3[:, 2] - t3[:, 0])
            d64 = np.asarray(directions, np.float64)[hit_ref]
            cos[hit_ref] = np.abs(np.einsum("ij,ij->i", nrm, d64)) / np.maximum(
                np.linalg.norm(nrm, axis=1) * np.linalg.norm(d64, axis=1), 1e-300)
        along = moved / (speed_of(directions) * np.maximum(cos, PARALLEL_COS))
        farther = (pa < 0) | (ta > tb + rel_tol * np.maximum(np.abs(tb), 1e-30) + along)
    idx = np.flatnonzero((pb >= 0) & farther)
    if not len(idx):
        return idx
    tris = np.asarray(triangles, np.float32)
    prim = pb[idx]
    o, d = origins[idx], directions[idx]
    with np.errstate(all="ignore"):
        dist, scale = edge_distance(tris, prim, o, d, per_edge=True)
        t, err = plane_distance(tris, prim, o, d)
        along = err * np.linalg.norm(d.astype(np.float64), axis=1)
        # Within the slack of an edge too: the displaced ray, in the plane
        # of Embree's triangle, is at most slack / cos off (cos bounded below
        # as above).
        shift = moved[idx] / np.maximum(cos[idx], PARALLEL_COS)
        near = np.abs(dist) <= (edge_ulps * (np.finfo(np.float32).eps * scale + along)
                                + shift)[:, None]
    # Excused: near an edge the ray does not cross the surface through - an
    # open edge, or a silhouette edge (mesh_edges.crosses_surface).
    groups, ids, shared = mesh_edges.edge_tables(tris)
    excused = np.zeros(len(idx), bool)
    for row, edge in zip(*np.nonzero(near)):
        if not excused[row] and not mesh_edges.crosses_surface(
                tris, groups, ids, int(prim[row]), int(edge), d[row], PARALLEL_COS,
                slack=float(moved[idx[row]])):
            excused[row] = True
    # Near two edges: through their common vertex, which may be a corner
    # the ray only touches.
    for row in np.flatnonzero(~excused & (near.sum(axis=1) >= 2)):
        j = [e for e in range(3) if near[row, e]]
        vertex = (j[1] if j[1] == j[0] + 1 else j[0]) if len(j) == 2 else 0
        excused[row] = len(j) == 3 or mesh_edges.touching_vertex(
            tris, shared, int(prim[row]), vertex, d[row], PARALLEL_COS)
    t3 = tris[prim].astype(np.float64)
    excused |= np.abs(np.cross(t3[:, 1] - t3[:, 0], t3[:, 2] - t3[:, 0])).sum(axis=1) == 0
    # Embree's float t is off where its triangle is nearly parallel to the
    # ray (the sheared depths cancel): a fuzzed fan's grazing sliver had it
    # 1.2e-4 short of the double-precision distance of its own plane, which
    # ours matched to 3e-9. A hit no farther than that distance (within
    # rel_tol) lies where Embree's triangle really is: no leak.
    with np.errstate(invalid="ignore"):
        excused |= (pa[idx] >= 0) & (ta[idx] <= t + rel_tol * np.abs(t))
    hi = np.full(len(idx), np.inf) if tmax is None else \
        np.broadcast_to(np.asarray(tmax, np.float64), (len(pa),))[idx]
    n = np.cross(t3[:, 1] - t3[:, 0], t3[:, 2] - t3[:, 0])
    d64 = d.astype(np.float64)
    with np.errstate(all="ignore"):
        tol = edge_ulps * (err + np.finfo(np.float32).eps * np.abs(t))
        excused |= (np.abs(t) <= tol) | (np.abs(t - hi) <= tol)
        cos = np.abs(np.einsum("ij,ij->i", n, d64)) / (
            np.linalg.norm(n, axis=1) * np.linalg.norm(d64, axis=1))
        excused |= ~(cos > PARALLEL_COS)
    if slack is not None:
        excused |= _across_shared_edge(tris, pa[idx], prim, o, d, ta[idx], tb[idx],
                                       moved[idx], rel_tol, edge_ulps, ~excused)
    # Decided exactly: in rational arithmetic the float ray misses Embree's
    # triangle and enters a neighbour of it (a triangle sharing a vertex)
    # first, where our hit is. Embree's float test then accepted a triangle
    # the ray passes by, and ours is the exact answer. (A fuzzed box edge: the
    # ray 8e-8 outside Embree's face in barycentric terms, and the neighbour
    # face it does enter 2e-4 farther along the grazing ray, where our test
    # put it.) Only without a slack: a displaced ray has no one exact answer.
    if slack is None:
        for row in np.flatnonzero(~excused & (pa[idx] >= 0)):
            excused[row] = _exactly_past_embrees_triangle(
                tris, int(pa[idx[row]]), int(pb[idx[row]]), origins[idx[row]],
                directions[idx[row]], float(ta[idx[row]]), rel_tol)
    return idx[~excused]


def _exactly_past_embrees_triangle(tris, ours: int, theirs: int, origin, direction,
                                   t_ours: float, rel_tol: float) -> bool:
    """True when the exact float ray misses Embree's triangle `theirs`, and of
    it and its neighbours (every triangle sharing a vertex with it) the one
    it meets first is `ours`, at our t (within rel_tol)."""
    if exact_hit_t(tris[theirs], origin, direction) is not None:
        return False
    corners = tris[theirs]
    shares = (tris[:, :, None, :] == corners[None, None, :, :]).all(axis=3).any(axis=(1, 2))
    if not shares[ours]:
        return False
    first, first_t = None, None
    for j in np.flatnonzero(shares):
        t = exact_hit_t(tris[j], origin, direction)
        if t is not None and (first_t is None or t < first_t):
            first, first_t = int(j), t
    return first == ours and abs(float(first_t) - t_ours) <= rel_tol * max(abs(float(first_t)),
                                                                         1e-30)


def exact_first_hit(triangles, origin, direction, tmin: float = 0.0, tmax: float = np.inf):
    """The first triangle the ray meets on the open segment tmin < t < tmax,
    exactly (bsplab.exact: a proven double-precision filter, then integers),
    and its t as a Fraction; the smallest index of a tie; (-1, None) when it
    meets none."""
    return exact.RayVerdict(exact.ExactScene.triangles(triangles), origin, direction,
                            tmin, tmax).first_hit()


def exact_hit_t(triangle, origin, direction):
    """Where the ray meets the triangle, computed exactly in rational
    arithmetic from the float32 values both tracers were given (edges and
    vertices included), or None when it misses (or runs in its plane)."""
    from fractions import Fraction

    def rational(values):
        return [Fraction(float(x)) for x in np.asarray(values, np.float32).ravel()]

    v0, v1, v2 = (rational(v) for v in np.asarray(triangle, np.float32))
    o, d = rational(origin), rational(direction)

    def sub(a, b):
        return [x - y for x, y in zip(a, b)]

    def cross(a, b):
        return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]

    def dot(a, b):
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]

    e1, e2 = sub(v1, v0), sub(v2, v0)
    p = cross(d, e2)
    det = dot(e1, p)
    if det == 0:
        return None
    s = sub(o, v0)
    u = dot(s, p) / det
    q = cross(s, e1)
    v = dot(d, q) / det
    t = dot(e2, q) / det
    if u < 0 or v < 0 or u + v > 1 or t <= 0:
        return None
    return t


def _across_shared_edge(tris, ours, theirs, o, d, ta, tb, slack, rel_tol, edge_ulps, rows):
    """Per ray (where `rows`): our hit on a neighbour of Embree's triangle is
    the displaced ray's honest hit. The world ray passes within `slack` (plus
    the flattened scene's own rounding) of an edge or vertex the two triangles
    share, so a ray displaced by slack may cross to our side of it, and there
    meet our triangle where its plane is: at most slack / (|d| cos) farther
    along the ray, cos that of our triangle, which is large where it is
    grazing (a box's face seen edge-on, fuzzed mirrored instance)."""
    out = np.zeros(len(ours), bool)
    eps = np.finfo(np.float32).eps
    for row in np.flatnonzero(rows & (ours >= 0) & (ours != theirs)):
        a, b = tris[ours[row]].astype(np.float64), tris[theirs[row]].astype(np.float64)
        common = [v for v in a if (b == v).all(axis=1).any()]
        if not common:
            continue
        o64, d64 = o[row].astype(np.float64), d[row].astype(np.float64)
        p, q = common[0], common[-1]
        dist = _line_segment_distance(o64, d64, p, q)
        scale = max(np.abs(a).max(), np.abs(b).max(), np.abs(o64).max())
        n = np.cross(a[1] - a[0], a[2] - a[0])
        speed = np.linalg.norm(d64)
        cos = abs(n @ d64) / max(np.linalg.norm(n) * speed, 1e-300)
        reach = slack[row] + edge_ulps * eps * scale
        out[row] = dist <= reach and ta[row] <= (
            tb[row] + rel_tol * abs(tb[row]) + reach / (speed * max(cos, PARALLEL_COS)))
    return out


def _line_segment_distance(o, d, p, q) -> float:
    """Distance (double precision) from the line o + t d to the segment pq
    (a point where p == q)."""
    e = q - p
    ee, dd, de = e @ e, d @ d, d @ e
    w = o - p
    den = dd * ee - de * de
    # The segment's parameter of the lines' closest approach, clamped; the
    # line's nearest point to that point of the segment then follows.
    s = 0.0 if ee == 0 or den <= 1e-300 * dd * ee else \
        float(np.clip((dd * (w @ e) - de * (w @ d)) / den, 0.0, 1.0))
    x = p + s * e
    t = (x - o) @ d / dd
    return float(np.linalg.norm(o + t * d - x))

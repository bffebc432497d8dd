"""Instanced scenes in two levels: one tree per unique mesh (any method of the
registry, built in the mesh's object space and shared by all its instances)
and a top level - a BVH over the instances' world boxes. See
docs/instances.md."""

from __future__ import annotations

import numpy as np

from . import _core, checks, method_table
from .method_table import NOT_TREE_OPTIONS, OPTIONS, TOP_OPTIONS
from .tree import COUNTERS, Tree, build

# The instanced trace's counters beyond a tree's (COUNTERS, which here hold
# the bottom trees' sums over the instances entered): the top level's node
# visits and the instances whose tree the ray entered.
TOP_COUNTERS = ("top_steps", "instance_visits")
# The transform's rounding in the oracle's tolerance (transform_slack): half
# an ulp of the object-space origin and direction each, carried back by the
# matrix - bounded with room to spare.
TRANSFORM_ULPS = 4.0


def _matrices(value, n: int | None) -> np.ndarray:
    """(n, 3, 4) float64 world-from-object matrices; (n, 4, 4) ones must end
    in the row 0 0 0 1 (affine)."""
    try:
        m = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError("matrices must be an array of shape (M, 3, 4) or (M, 4, 4)") from None
    if m.ndim != 3 or m.shape[1:] not in ((3, 4), (4, 4)):
        raise ValueError(f"matrices must have shape (M, 3, 4) or (M, 4, 4), got {m.shape}")
    if n is not None and len(m) != n:
        raise ValueError(f"matrices has {len(m)} rows but mesh_index {n}: one matrix per instance")
    if m.shape[1] == 4:
        last = m[:, 3, :]
        bad = np.flatnonzero(~np.all(last == (0.0, 0.0, 0.0, 1.0), axis=1))
        if len(bad):
            raise ValueError(f"instance {bad[0]}: its matrix's last row is {last[bad[0]].tolist()}, "
                             "not 0 0 0 1: only affine matrices place a mesh")
        m = m[:, :3, :]
    bad = np.flatnonzero(~np.isfinite(m).reshape(len(m), -1).all(axis=1))
    if len(bad):
        raise ValueError(f"instance {bad[0]}: its matrix has a non-finite entry (NaN or inf)")
    return np.ascontiguousarray(m)


class InstancedTree:
    """Instances of shared mesh trees under a top-level BVH."""

    # The kind of structure, beside a flat Tree's "bsp" and "bvh": what the
    # interfaces branch on (never on which attributes an object has).
    structure = "two_level"

    def __init__(self, scene, meshes: list[Tree], mesh_index: np.ndarray, matrices: np.ndarray,
                 method: str, options: dict, top: str, top_options: dict):
        self._scene = scene
        self.meshes = list(meshes)  # keeps the bottom trees alive: the scene points at them
        self.mesh_index = mesh_index
        self.matrices = matrices
        self.method = method  # every mesh tree's (build_instanced checks it)
        self.options = dict(options)
        self.top = top  # the top level's structure
        self.top_options = dict(top_options)
        self._normal_matrices = None
        self._top_arrays = None
        self._bounds = None
        self._bottom_stats = None
        sizes = np.array([len(t.triangles) for t in self.meshes], np.int64)
        # Where each instance's triangles start in the flattened scene, and
        # how many it holds.
        ends = np.cumsum(sizes[mesh_index]).astype(np.int64)
        self.flat_offsets = np.concatenate([[0], ends[:-1]]).astype(np.int64)
        self.flat_triangles = int(ends[-1]) if len(ends) else 0

    @property
    def stats(self) -> dict:
        s = self._scene.stats()
        if self._bottom_stats is None:  # the mesh trees do not change: read them once
            self._bottom_stats = [t.stats for t in self.meshes]
        bottom = self._bottom_stats
        s["method"] = self.method  # the mesh trees'
        s["top_method"] = self.top
        # The mesh trees share their options: the quality that built them.
        s["build_quality"] = bottom[0]["build_quality"] if bottom else None
        s["bottom_bytes"] = int(sum(b["bytes"] for b in bottom))
        s["bottom_nodes"] = int(sum(b["nodes"] for b in bottom))
        s["bottom_build_seconds"] = float(sum(b["build_seconds"] for b in bottom))
        s["mesh_triangles"] = int(sum(b["triangles"] for b in bottom))
        s["bytes"] = s["bottom_bytes"] + s["top_bytes"]
        # What the flattened scene's tree would hold, about: each instance's
        # mesh tree once per instance (a flat tree of the same method holds
        # within a few percent of that; bench-instanced measures it).
        per_mesh = np.array([b["bytes"] for b in bottom], np.int64)
        s["flat_bytes_estimate"] = int(per_mesh[self.mesh_index].sum()) if len(self.mesh_index) else 0
        s["top_bytes_per_instance"] = s["top_bytes"] / max(1, s["instances"])
        return s

    def instance_of(self, flat_prim) -> np.ndarray:
        """The instance of each index into flatten()'s triangles, -1 for -1
        (a miss, as intersect()'s and Embree's prim say it). Any other index
        outside 0..flat_triangles - 1 is an error naming it."""
        try:
            p = np.asarray(flat_prim)
        except (TypeError, ValueError):
            raise TypeError("flat_prim must be integers (indices into flatten()'s triangles)") \
                from None
        if p.size and not np.issubdtype(p.dtype, np.integer):
            raise TypeError(f"flat_prim must be integers (indices into flatten()'s triangles), "
                            f"got {p.dtype}")
        p = p.astype(np.int64)
        bad = np.flatnonzero((p.reshape(-1) < -1) | (p.reshape(-1) >= self.flat_triangles))
        if len(bad):
            k = int(bad[0])
            raise ValueError(f"flat_prim[{k}] = {int(p.reshape(-1)[k])} is out of range: the "
                             f"flattened scene has {self.flat_triangles} triangles "
                             f"(0..{self.flat_triangles - 1}; -1: a miss)")
        inst = np.searchsorted(self.flat_offsets, p, side="right") - 1
        return np.where(p >= 0, inst, -1)

    def transform_slack(self, origins, directions, t, instances) -> np.ndarray:
        """How far (world units) a ray traced in instance i's object space
        may be from the world ray at distance t: the origin and direction
        rounded to float there (half an ulp each, relative to A^-1 (o - b)
        and A^-1 d), carried back by A, so at most
        TRANSFORM_ULPS eps cond(A) (|o| + |b| + t |d|). 0 where instance < 0.
        The oracle's `slack` for an instanced trace (docs/instances.md)."""
        o = np.asarray(origins, np.float64)
        d = np.asarray(directions, np.float64)
        inst = np.asarray(instances, np.int64)
        tt = np.where(np.isfinite(t), np.abs(np.asarray(t, np.float64)), 0.0)
        out = np.zeros(len(o))
        ok = inst >= 0
        if ok.any():
            m = self.matrices[inst[ok]]
            cond = np.linalg.cond(m[:, :, :3])
            out[ok] = TRANSFORM_ULPS * np.finfo(np.float32).eps * cond * (
                np.linalg.norm(o[ok], axis=1) + np.linalg.norm(m[:, :, 3], axis=1)
                + tt[ok] * np.linalg.norm(d[ok], axis=1))
        return out

    def _top(self) -> dict:
        if self._top_arrays is None:
            self._top_arrays = self._scene.top_arrays()
        return self._top_arrays

    def top_boxes(self, max_depth: int | None = None) -> dict:
        """The top level's node boxes in world units, root first, level by
        level down to `max_depth` (None: all): "lo", "hi" (B, 3) float32,
        per box "node", "depth", "leaf" (bool) and "instances" (a leaf's
        instance indices - usually one; instances whose boxes the binning
        cannot tell apart share a leaf - and an empty array for an interior
        node)."""
        a = self._top()
        limit = None if max_depth is None else checks.number(max_depth, "max_depth", low=0,
                                                             integer=True)
        rows, depth = [], []
        level = [0] if len(a["lo"]) else []
        d = 0
        while level and (limit is None or d <= limit):
            rows += level
            depth += [d] * len(level)
            level = [c for n in level if not a["leaf"][n] for c in (a["first"][n], a["first"][n] + 1)]
            d += 1
        rows = np.array(rows, np.int64)
        leaf = a["leaf"][rows].astype(bool) if len(rows) else np.zeros(0, bool)
        insts = [a["order"][a["first"][n]:a["first"][n] + a["count"][n]].astype(np.int64)
                 if a["leaf"][n] else np.zeros(0, np.int64) for n in rows]
        return {"lo": a["lo"][rows], "hi": a["hi"][rows], "node": rows,
                "depth": np.array(depth, np.int64), "leaf": leaf, "instances": insts}

    def trace_path(self, origin, direction, tmin=0.0, tmax=np.inf) -> dict:
        """One ray's walk through both levels, as intersect() traces it: the
        same hit bit for bit ("t", "prim", "u", "v", "instance", "flat_prim")
        and counts ("top_steps", "instance_visits", and the bottom trees'
        "steps", "tests", "box_tests", ...). "top": per top-level node
        visited, in order, "node", "t_range" and "box_lo", "box_hi" (world
        units); "instances": per instance entered, in order, {"instance",
        "mesh", "origin", "direction" (the ray in object space), "path" (the
        mesh tree's Tree.trace_path of it)}. The core's own walk (the
        single-ray trace's, recording), not a replay of it."""
        from .tree import _finite_vector
        o = _finite_vector(origin, "origin")
        d = _finite_vector(direction, "direction")
        if not d.any():
            raise ValueError("direction must not be zero")
        lo, hi = (float(x[0]) for x in checks.ray_ranges(tmin, tmax, 1))
        return _core.trace_path_instanced(self._scene, o, d, lo, hi)

    def _instance(self, instance) -> int:
        return checks.number(instance, "instance", low=0, high=len(self.mesh_index) - 1,
                             integer=True)

    def to_world(self, instance, points) -> np.ndarray:
        """Object-space points (..., 3) of `instance`'s mesh in world units."""
        m = self.matrices[self._instance(instance)]
        p = np.asarray(points, np.float64)
        return (p @ m[:, :3].T + m[:, 3]).astype(np.float32)

    def to_object(self, instance, points) -> np.ndarray:
        """World points (..., 3) in `instance`'s object space, by the core's
        own inverse (the one its rays are carried by), in double."""
        inv = self._top()["object_from_world"].reshape(-1, 3, 4)[self._instance(instance)]
        return np.asarray(points, np.float64) @ inv[:, :3].T + inv[:, 3]

    def instance_at(self, point):
        """The instance whose mesh tree's box holds the world point (e.g.
        the 3D cursor) - of several, the smallest box's - or None. All
        instances at once (the overlay asks on every redraw): the point
        carried into each object space by the core's inverses."""
        p = np.asarray(point, np.float64).reshape(3)
        if not len(self.mesh_index):
            return None
        inv = self._top()["object_from_world"].reshape(-1, 3, 4)
        q = inv[:, :, :3] @ p + inv[:, :, 3]
        lo, hi = (np.asarray(b, np.float64)[self.mesh_index] for b in self._mesh_bounds())
        inside = np.flatnonzero(((q >= lo) & (q <= hi)).all(axis=1))
        if not len(inside):
            return None
        volume = (np.prod(np.maximum(hi[inside] - lo[inside], 1e-30), axis=1)
                  * np.abs(np.linalg.det(self.matrices[inside][:, :, :3])))
        return int(inside[np.argmin(volume)])

    def _mesh_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Each mesh tree's box in object space: (meshes, 3) lo and hi."""
        if self._bounds is None:
            b = [tuple(np.asarray(c, np.float64) for c in t.bounds) for t in self.meshes]
            self._bounds = (np.array([x[0] for x in b]).reshape(-1, 3),
                            np.array([x[1] for x in b]).reshape(-1, 3))
        return self._bounds

    def instance_split_polygons(self, instance, max_depth: int, **kwargs) -> dict:
        """`instance`'s mesh tree's split_polygons, in world units: the
        instance's own tree drawn in place ("plane" carried to the world,
        n unit, n.x = d)."""
        i = self._instance(instance)
        out = self.meshes[self.mesh_index[i]].split_polygons(max_depth, **kwargs)
        out["vertices"] = self.to_world(i, out["vertices"])
        m = self.matrices[i]
        plane = np.asarray(out["plane"], np.float64)
        if len(plane):
            n = plane[:, :3] @ np.linalg.inv(m[:, :3])  # rows: A^-T n
            d = plane[:, 3] + n @ m[:, 3]
            norm = np.maximum(np.linalg.norm(n, axis=1), 1e-300)
            out["plane"] = np.column_stack([n / norm[:, None], d / norm])
        return out

    def instance_leaf_cells(self, instance, max_depth=None, **kwargs) -> dict:
        """`instance`'s mesh tree's leaf_cells, their vertices in world units."""
        i = self._instance(instance)
        out = self.meshes[self.mesh_index[i]].leaf_cells(max_depth, **kwargs)
        out["vertices"] = self.to_world(i, out["vertices"])
        return out

    def instance_node_boxes(self, instance, max_depth: int, **kwargs) -> dict:
        """A BVH mesh tree's node_boxes for `instance`, each box as its 8
        corners in world units ("corners" (B, 8, 3): a box under a rotation
        or shear is no longer axis-aligned), corner c = (x of c & 1, y of
        c & 2, z of c & 4)."""
        i = self._instance(instance)
        out = self.meshes[self.mesh_index[i]].node_boxes(max_depth, **kwargs)
        lo, hi = out["lo"].astype(np.float64), out["hi"].astype(np.float64)
        corners = np.stack([np.where([(c & 1) != 0, (c & 2) != 0, (c & 4) != 0], hi, lo)
                            for c in range(8)], axis=1)
        out["corners"] = self.to_world(i, corners)
        return out

    def hit_normals(self, hits: dict) -> np.ndarray:
        """(N, 3) float32 unit world normals of the hits (zeros on a miss):
        the object-space geometric normal carried by the inverse transpose
        of the instance's matrix (a mirroring matrix flips it, as it flips
        the flattened triangle's winding)."""
        inst, prim = hits["instance"], hits["prim"]
        out = np.zeros((len(inst), 3), np.float32)
        hit = np.flatnonzero(inst >= 0)
        if not len(hit):
            return out
        if self._normal_matrices is None:
            # A^-T from the core's inverse, times the sign of det A: a mirror
            # turns the winding, so the flattened triangle's normal is then
            # the opposite of the carried one. Once per scene, per instance.
            inv = self._top()["object_from_world"].reshape(-1, 3, 4)[:, :, :3]
            m = self.matrices[:, :, :3]
            det = (m[:, 0, 0] * (m[:, 1, 1] * m[:, 2, 2] - m[:, 1, 2] * m[:, 2, 1])
                   - m[:, 0, 1] * (m[:, 1, 0] * m[:, 2, 2] - m[:, 1, 2] * m[:, 2, 0])
                   + m[:, 0, 2] * (m[:, 1, 0] * m[:, 2, 1] - m[:, 1, 1] * m[:, 2, 0]))
            self._normal_matrices = (inv.transpose(0, 2, 1)
                                     * np.sign(det)[:, None, None]).astype(np.float32)
        n = np.zeros((len(hit), 3), np.float32)
        meshes = self.mesh_index[inst[hit]]
        for mesh in np.unique(meshes):
            rows = np.flatnonzero(meshes == mesh)
            n[rows] = self.meshes[mesh].face_normals()[prim[hit[rows]]]
        w = np.einsum("nij,nj->ni", self._normal_matrices[inst[hit]], n)
        out[hit] = w / np.maximum(np.linalg.norm(w, axis=1, keepdims=True), 1e-30)
        return out

    def flatten(self) -> np.ndarray:
        """The (T, 3, 3) float32 world triangles of every instance in order
        (each mesh's triangles in input order): the scene a flat tree, and
        Embree, would trace. Transformed in double, rounded once."""
        from .instanced_scenes import flatten
        return flatten([t.triangles for t in self.meshes], self.mesh_index, self.matrices)

    def intersect(self, origins, directions, tmin=0.0, tmax=np.inf, *, threads=0, cull=False,
                  counters=True, packets=False, ray_order="auto", progress=None) -> dict:
        """Closest hits: as Tree.intersect's ("prim" the triangle's index in
        its mesh), plus "instance" (-1 on a miss) and "flat_prim" (the index
        in flatten()'s triangles). With counters, COUNTERS hold the bottom
        trees' sums over the instances entered, TOP_COUNTERS the top level's.
        `packets=True` (with counters=False) gives the same hits: groups of
        consecutive rays walk the top level together and go through each
        mesh tree's packet kernel together (a BVH mesh tree traces its
        packets one ray at a time, as Tree.intersect does); fast when
        consecutive rays are coherent (render's tiles). Bit for bit but on
        rays lying in a triangle's plane, where a mesh tree's answer may
        depend on the segment's end (docs/instances.md). `ray_order` (the
        single-ray hits-only path, counters=False and packets=False): as
        Tree.intersect's, "spatial" traces an incoherent batch of 4,096 rays
        or more sorted by the rays' origins and directions (unless every mesh
        tree is a BVH, which keeps the given order as Tree.intersect's
        does), "auto" (the default) when a probe of the rays also walks at
        least 16 nodes a ray (the top level's and the mesh trees' together;
        8 when traced on one thread),
        "given" in the caller's order; the same hits in every order, in the
        caller's order. Leaf
        culling (`cull=True`) is not offered in two levels."""
        cull, counters, packets = checks.trace_flags(cull, counters, packets)
        order = checks.ray_order(ray_order)
        if cull:
            raise ValueError("cull=True: leaf culling is not offered for instanced scenes "
                             "(trace their flattened scene to cull)")
        o, d = checks.rays(origins, directions)
        n = len(o)
        lo, hi = checks.ray_ranges(tmin, tmax, n)
        progress = checks.progress(progress)
        out = {"t": np.empty(n, np.float32), "prim": np.empty(n, np.int32),
               "u": np.empty(n, np.float32), "v": np.empty(n, np.float32),
               "instance": np.empty(n, np.int32)}
        names = COUNTERS + TOP_COUNTERS
        if counters:
            out.update({name: np.empty(n, np.uint32) for name in names})
        _core.intersect_instanced(self._scene, o, d, lo, hi, out["t"], out["prim"], out["u"],
                                  out["v"], out["instance"], *(out.get(k) for k in names),
                                  checks.threads(threads), packets, progress, order)
        hit = out["instance"] >= 0
        out["flat_prim"] = np.where(hit, self.flat_offsets[np.maximum(out["instance"], 0)]
                                    + out["prim"], -1).astype(np.int64)
        return out

    def __repr__(self) -> str:
        s = self._scene.stats()
        return (f"<bsplab.InstancedTree {self.method} meshes, {self.top} top level: "
                f"{s['meshes']} meshes, {s['instances']} instances, "
                f"{s['instanced_triangles']} instanced triangles>")


def check_instance_matrices(matrices) -> np.ndarray:
    """The instances' world-from-object matrices, (M, 3, 4) or (M, 4, 4)
    affine, checked as build_instanced checks them - shape, finite, not
    singular (the core's rule: |det A| > 1e-12 |A|^3) - without building
    anything: a caller that builds the mesh trees itself (the add-on) learns
    of a bad instance before the long part. Returns them as (M, 3, 4)
    float64; raises ValueError naming the first bad instance."""
    m = _matrices(matrices, None)
    _core.check_instance_matrices(m)
    return m


def build_instanced(meshes, mesh_index, matrices, method: str | None = None, *,
                    top: str = "bvh", threads=0, progress=None, **options) -> InstancedTree:
    """An instanced scene: `meshes` a list of (N, 3, 3) triangle arrays (or
    (vertices, indices) pairs, or already built Trees, which are shared, not
    rebuilt), `mesh_index` (M,) the mesh of each instance (at least one),
    `matrices` (M, 3, 4) or (M, 4, 4) affine world-from-object matrices.
    Each mesh given as triangles gets a tree built by `method` with `options`
    (the registry's); the top level is a BVH (`top="bvh"`, its options the
    registry's "top" group, method_table.TOP_OPTIONS: top_bins,
    top_traversal_cost, top_intersect_cost).

    A scene's mesh trees share one method, which stats["method"] and the
    repr name: `method=None` takes the given Trees' (kd when every mesh is
    triangles), and a given Tree of another method than `method` is an
    error, not a scene misdescribed. A given Tree is used as built, so an
    option it was built otherwise with (k=5 given, k=6 built) is an error
    naming the option, not ignored; options that shape no tree (threads,
    memory_limit_mb: method_table.NOT_TREE_OPTIONS) are not compared.
    Errors name the instance (a singular or non-finite matrix, a mesh index
    out of range) or the mesh (one with no triangles)."""
    checks.choice(top, "top", ("bvh",))
    if not isinstance(meshes, (list, tuple)) or not meshes:
        raise ValueError("meshes must be a non-empty list of triangle arrays or Trees")
    idx = np.asarray(mesh_index)
    if idx.ndim != 1 or not (np.issubdtype(idx.dtype, np.integer) or len(idx) == 0):
        raise TypeError(f"mesh_index must be a 1-d array of integers, got {idx.dtype} {idx.shape}")
    if not len(idx):
        # As a tree needs a triangle (bsplab.build refuses none), a scene
        # needs an instance.
        raise ValueError("mesh_index is empty: there are no instances to build a scene of")
    if idx.min() < 0 or idx.max() >= len(meshes):
        i = int(np.flatnonzero((idx < 0) | (idx >= len(meshes)))[0])
        raise ValueError(f"instance {i}: mesh index {int(idx[i])} is out of range "
                         f"({len(meshes)} meshes)")
    idx = np.ascontiguousarray(idx, dtype=np.uint32)
    m = _matrices(matrices, len(idx))
    _core.check_instance_matrices(m)  # before the mesh trees: a bad instance fails at once
    given = [(i, t) for i, t in enumerate(meshes) if isinstance(t, Tree)]
    method = _scene_method(method, given)
    # The top level's options (the registry's "top" group), checked against
    # their schemas; the rest are the mesh trees'.
    top_opts = {name: checks.option(OPTIONS[name], options.pop(name, default), None)
                for name, default in TOP_OPTIONS.items()}
    checked = checks.build_options(method_table.get(method), options)  # names a bad one
    for i, t in given:
        for name in options:
            if name not in NOT_TREE_OPTIONS and t.options.get(name) != checked[name]:
                raise ValueError(
                    f"option {name}={checked[name]!r}: mesh {i} is a Tree built with "
                    f"{name}={t.options.get(name)!r}, and a given Tree is used as built (the "
                    "options build the meshes given as triangles)")
    progress = checks.progress(progress)
    trees = []
    for i, t in enumerate(meshes):
        if not isinstance(t, Tree):
            try:
                t = build(t, method, progress=progress, threads=threads, **options)
            except (TypeError, ValueError) as e:
                raise type(e)(f"mesh {i}: {e}") from None
        trees.append(t)
    scene = _core.build_instanced([t._tree for t in trees], idx, m,
                                  {**top_opts, "threads": checks.threads(threads)}, progress)
    return InstancedTree(scene, trees, idx, m, method, options, top, top_opts)


def _scene_method(method, given) -> str:
    """The one method of a scene's mesh trees: `method`, or (None) the given
    Trees' or kd; a given Tree of another method is an error."""
    if method is None:
        methods = sorted({t.method for _, t in given})
        if len(methods) > 1:
            raise ValueError(f"the given Trees are of methods {', '.join(methods)}: a scene's "
                             "mesh trees share one method")
        method = methods[0] if methods else "kd"
    method_table.get(method)  # an unknown method named
    for i, t in given:
        if t.method != method:
            raise ValueError(f"mesh {i} is a {t.method} tree, not {method}: a scene's mesh trees "
                             f"share one method (pass method={t.method!r}, or mesh {i}'s "
                             f"triangles to build its tree by {method})")
    return method

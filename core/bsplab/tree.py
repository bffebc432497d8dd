"""Building trees and tracing rays: the checked Python face of the core."""

from __future__ import annotations

import numpy as np

from . import _core, checks, polygons
from . import method_table as _methods

# The per-ray counters intersect() returns unless asked for hits only, in
# the core's argument order.
# "box_tests" (ray-box tests) is a BVH's, 0 on kd and BSP trees.
COUNTERS = ("steps", "general_steps", "tests", "culled", "box_tests")

# The node kinds of the "kind" arrays (split_polygons, leaf_cells,
# trace_path), by code: the core's NodeKind. "box" is a BVH's interior node
# (its leaves are "leaf").
KINDS = ("x", "y", "z", "leaf", "general", "box")
# What trace_path's "test_result" codes mean: tested and missed (or no closer
# than the hit so far), tested and the closest hit so far, skipped by leaf
# culling, skipped because this ray tested the triangle in an earlier leaf.
TEST_RESULTS = ("miss", "hit", "culled", "seen")
# How many polygons / cells the drawing queries return unless told: about
# what a viewport overlay draws at interactive rates.
DRAWABLE = 100_000


class Tree:
    """An acceleration structure over a fixed set of triangles."""

    def __init__(self, core_tree, method: str, options: dict):
        self._tree = core_tree
        self.method = method
        self.options = dict(options)
        self._face_normals = None

    @property
    def structure(self) -> str:
        """What the tree is made of: "bvh" (a hierarchy of boxes) or "bsp"
        (split planes: kd and BSP trees)."""
        return self._tree.structure

    @property
    def triangles(self) -> np.ndarray:
        """The (N, 3, 3) float32 triangles, in input order: a read-only view,
        or, when the tree moved its coordinates into its local frame or
        scaled them (see `stats["offset"]`, `stats["scale"]`), an exact copy
        in the input's units."""
        tris, scale, offset = self._tree.triangles, self._tree.scale, self._tree.offset
        if scale == 1.0 and not any(offset):
            return tris
        return (tris.astype(np.float64) / scale + np.asarray(offset)).astype(np.float32)

    @property
    def bounds(self) -> tuple:
        """((x, y, z) lowest, (x, y, z) highest) corner of the live triangles."""
        scale, offset = self._tree.scale, self._tree.offset
        return tuple(tuple(float(np.float32(c / scale + o)) for c, o in zip(corner, offset))
                     for corner in self._tree.bounds)

    @property
    def stats(self) -> dict:
        s = self._tree.stats()
        s["scale"] = self._tree.scale
        s["offset"] = tuple(self._tree.offset)
        s["method"] = self.method
        s.update({f"option_{k}": v for k, v in self.options.items()})
        return s

    def face_normals(self) -> np.ndarray:
        """(N, 3) float32 (v1 - v0) x (v2 - v0) of the triangles, in input
        units, not normalised; computed once (an instanced scene's renders
        carry them to the world for every instance of the mesh)."""
        if self._face_normals is None:
            t = self.triangles
            self._face_normals = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]).astype(np.float32)
        return self._face_normals

    def node_bytes(self) -> bytes:
        """The raw node array; equal bytes mean an identical tree."""
        return self._tree.node_bytes()

    def intersect(self, origins, directions, tmin=0.0, tmax=np.inf, *, threads=0, cull=False,
                  counters=True, packets=False, ray_order="auto", progress=None) -> dict:
        """Closest hits of the rays; see docs/api.md for the returned arrays.
        `tmin`/`tmax` are scalars or per-ray arrays; None means the default
        (0, and inf: no limit).
        `cull` skips, in each leaf, the triangles whose box misses the box of
        the ray's segment there (when the tree keeps boxes: leaf_boxes). It
        is off by default: on our SAH trees, whose leaves hold 2-5 triangles,
        it removes many tests but rarely pays for itself (docs/cull_benchmark.md).
        `counters=False` traces on the hits-only path, compiled without the
        per-ray counters: the same t, prim, u, v bit for bit, and only those.
        `packets=True` (with counters=False, cull=False) traces consecutive
        rays together, as many as `cpu_features()["packet_width"]`: the same
        hits again, bit for bit, and faster when consecutive rays are coherent
        (camera rays in tile order: `Camera.rays(w, h, order="tiles")`).
        `ray_order` (the single-ray hits-only path of a kd or BSP tree; the
        BVH keeps the given order, docs/performance.md): "spatial" traces an
        incoherent batch of 4,096 rays or more - random or scattered rays,
        not a camera's nor rays cast from its hits in pixel order - sorted
        by the rays' origins and directions, so that neighbouring rays walk
        the same nodes (1.25-1.4x faster on random rays; docs/performance.md);
        "auto" (the default) does so when a probe of 128 of the rays walks at
        least 8 nodes a ray (4 when traced on one thread), since rays that
        mostly miss the scene walk too few for the sort to pay; "given"
        keeps the caller's order. The hits are the same in every order, bit
        for bit, and come back in the caller's order."""
        cull, counters, packets = checks.trace_flags(cull, counters, packets)
        order = checks.ray_order(ray_order)
        o, d = checks.rays(origins, directions)
        n = len(o)
        lo, hi = checks.ray_ranges(tmin, tmax, n)
        progress = checks.progress(progress)
        out = {
            "t": np.empty(n, np.float32),
            "prim": np.empty(n, np.int32),
            "u": np.empty(n, np.float32),
            "v": np.empty(n, np.float32),
        }
        if counters:
            out.update({name: np.empty(n, np.uint32) for name in COUNTERS})
        _core.intersect(self._tree, o, d, lo, hi, out["t"], out["prim"], out["u"], out["v"],
                        *(out.get(name) for name in COUNTERS),
                        checks.threads(threads), cull, progress, packets, order)
        return out

    def split_polygons(self, max_depth: int, root=None, max_polygons: int = DRAWABLE) -> dict:
        """The split plane of every interior node at most `max_depth` levels
        below `root` (a node index; None: the whole tree), clipped to the
        node's cell: a convex polygon in world units, level by level.
        Returns "vertices" (V, 3) float32 and "offsets" (P + 1,) (polygon i
        is vertices[offsets[i]:offsets[i+1]]), "triangles" (fan indices into
        vertices, for a filled batch), and per polygon "node", "depth" (0 at
        `root`), "kind" (codes of KINDS), "plane" (n, d of n.x = d). "cut"
        is True when `max_polygons` stopped the walk (the shallow levels are
        then whole). A node splitting a flat cell (zero thickness, e.g. a
        wall's own slab) has no polygon: its plane meets the cell in a
        segment."""
        depth = checks.number(max_depth, "max_depth", low=0, integer=True)
        limit = checks.number(max_polygons, "max_polygons", low=0, integer=True)
        out = _core.split_polygons(self._tree, depth, self._root(root), limit)
        out["triangles"] = polygons.fan_triangles(out["offsets"])
        return out

    def node_boxes(self, max_depth: int, root=None, max_boxes: int = DRAWABLE) -> dict:
        """A BVH's node boxes: every node at most `max_depth` levels below
        `root` (a node index; None: the whole tree), level by level, in world
        units. Returns "lo", "hi" (B, 3) float32 corners, per box "node",
        "depth" (0 at `root`), "leaf" (bool); "cut" is True when `max_boxes`
        stopped the walk (the shallow levels are then whole). A kd or BSP
        tree has no boxes: ValueError."""
        depth = checks.number(max_depth, "max_depth", low=0, integer=True)
        limit = checks.number(max_boxes, "max_boxes", low=0, integer=True)
        if self.structure != "bvh":
            raise ValueError(f"node_boxes: a {self.method} tree has split planes, not boxes "
                             "(use split_polygons or leaf_cells)")
        out = _core.node_boxes(self._tree, depth, self._root(root), limit)
        out["leaf"] = out["leaf"].astype(bool)
        out["node"] = out["node"].astype(np.int64)
        return out

    def leaf_cells(self, max_depth=None, root=None, max_cells: int = DRAWABLE) -> dict:
        """The cells of the leaves under `root` (None: the whole tree) - and,
        with `max_depth`, of the nodes at that depth below `root` instead of
        their leaves: cells that together tile root's cell. Each cell is a
        closed convex polyhedron: its faces are polygons cell_offsets[i] ..
        cell_offsets[i+1] of "vertices"/"offsets" (as in split_polygons),
        "edges" (E, 2) their outlines for a wireframe batch; per cell
        "node", "depth", "kind" (KINDS: "leaf", or the kind of a node cut
        off by max_depth). "cut": `max_cells` stopped the walk."""
        depth = -1 if max_depth is None else checks.number(max_depth, "max_depth", low=0,
                                                            integer=True)
        limit = checks.number(max_cells, "max_cells", low=0, integer=True)
        out = _core.node_cells(self._tree, depth, self._root(root), limit)
        out["edges"] = polygons.edge_pairs(out["offsets"])
        return out

    def node_at(self, point, max_depth=None):
        """(node index, depth) of the leaf - or of the node `max_depth`
        levels deep - whose cell holds the world point, e.g. the 3D cursor;
        None when the point is outside the tree's box. A point on a split
        plane belongs to the cell above it (below is n.x < d)."""
        p = _finite_vector(point, "point")
        depth = -1 if max_depth is None else checks.number(max_depth, "max_depth", low=0,
                                                            integer=True)
        node, at_depth = _core.node_at(self._tree, p, depth)
        return None if node < 0 else (node, at_depth)

    def trace_path(self, origin, direction, tmin=0.0, tmax=np.inf, *, cull=False) -> dict:
        """One ray's walk through the tree, as intersect() traces it: the same
        hit bit for bit ("t", "prim", "u", "v") and counts ("steps",
        "general_steps", "tests", "culled", "box_tests"). Per visited node, in
        visit order: "node", "depth", "kind" (KINDS), "t_range" (the ray's
        [t0, t1] in its cell, a BVH's: in its box), "plane" (n, d; NaN for
        leaves and BVH nodes), "box_lo", "box_hi" (a BVH node's box; NaN
        rows on kd and BSP trees). Per triangle
        reference of the visited leaves: "test_step" (its leaf's row above),
        "test_prim", "test_result" (codes of TEST_RESULTS), "test_t" (the
        distance of a hit, else NaN)."""
        if not isinstance(cull, (bool, np.bool_)):
            raise TypeError(f"cull must be True or False, got {cull!r}")
        o = _finite_vector(origin, "origin")
        d = _finite_vector(direction, "direction")
        if not d.any():
            raise ValueError("direction must not be zero")
        lo, hi = (float(x[0]) for x in checks.ray_ranges(tmin, tmax, 1))
        return _core.trace_path(self._tree, o, d, lo, hi, bool(cull))

    def _root(self, root) -> int:
        if root is None:
            return 0
        n = self._tree.stats()["nodes"]
        return checks.number(root, "root", low=0, high=n - 1, integer=True)

    def __repr__(self) -> str:
        s = self._tree.stats()
        return (f"<bsplab.Tree {self.method}: {s['triangles']} triangles, {s['nodes']} nodes, "
                f"{s['bytes'] / 2**20:.1f} MiB>")


def _finite_vector(value, name: str) -> np.ndarray:
    """Three finite float32 coordinates, as the core traces them."""
    try:
        v = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be three numbers (x, y, z)") from None
    if v.shape != (3,):
        raise ValueError(f"{name} must be three numbers (x, y, z), got shape {v.shape}")
    f = v.astype(np.float32)
    if not np.isfinite(f).all():
        raise ValueError(f"{name} must be finite (in float32), got {tuple(float(x) for x in v)}")
    return f


def build(triangles, method: str = "kd", *, progress=None, costs=None, **options) -> Tree:
    """Builds a tree of `method` over (N, 3, 3) triangles or (vertices, indices).

    costs="measured" takes traversal_cost, intersect_cost and general_cost
    from this machine's measured costs file (`bsplab.costs`); None (or
    "default") leaves them to the options and their defaults."""
    m = _methods.get(method)
    tris = checks.triangles(triangles)
    if checks.costs_choice(costs) == "measured":
        from . import costs as _costs
        options = {**options, **_costs.measured_options(m, options)}
    opts = checks.build_options(m, options)
    progress = checks.progress(progress)
    try:
        # One call: the core's registry finds the method, sets the checked
        # options by name (rbsp_set's "auto" resolved there too) and runs
        # the method's builder.
        core_tree = _core.build(tris, m.name, opts, progress)
    except MemoryError as e:
        # The core's "build needs more than ... (memory_limit_mb=...)": name the method.
        # A scene of many instances fits in far less as two levels.
        if str(e).startswith("build needs"):
            raise MemoryError(f"{method} {e}; a scene of instanced meshes needs far less built "
                              "in two levels (bsplab.build_instanced: one tree per mesh)") from None
        raise
    return Tree(core_tree, method, opts)

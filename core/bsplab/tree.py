"""Building trees and tracing rays: the checked Python face of the core."""

from __future__ import annotations

import numpy as np

from . import _core, checks
from . import method_table as _methods

# The per-ray counters intersect() returns unless asked for hits only, in
# the core's argument order.
COUNTERS = ("steps", "general_steps", "tests", "culled")


class Tree:
    """An acceleration structure over a fixed set of triangles."""

    def __init__(self, core_tree, method: str, options: dict):
        self._tree = core_tree
        self.method = method
        self.options = dict(options)

    @property
    def triangles(self) -> np.ndarray:
        """The (N, 3, 3) float32 triangles, in input order: a read-only view,
        or, when the tree scaled its coordinates (see `stats["scale"]`), an
        exact copy in the input's units."""
        tris, scale = self._tree.triangles, self._tree.scale
        return tris if scale == 1.0 else (tris.astype(np.float64) / scale).astype(np.float32)

    @property
    def bounds(self) -> tuple:
        """((x, y, z) lowest, (x, y, z) highest) corner of the live triangles."""
        scale = self._tree.scale
        return tuple(tuple(float(np.float32(c / scale)) for c in corner)
                     for corner in self._tree.bounds)

    @property
    def stats(self) -> dict:
        s = self._tree.stats()
        s["scale"] = self._tree.scale
        s["method"] = self.method
        s.update({f"option_{k}": v for k, v in self.options.items()})
        return s

    def node_bytes(self) -> bytes:
        """The raw node array; equal bytes mean an identical tree."""
        return self._tree.node_bytes()

    def intersect(self, origins, directions, tmin=0.0, tmax=np.inf, *, threads=0, cull=False,
                  counters=True, packets=False, progress=None) -> dict:
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
        (camera rays in tile order: `Camera.rays(w, h, order="tiles")`)."""
        for name, value in (("cull", cull), ("counters", counters), ("packets", packets)):
            if not isinstance(value, (bool, np.bool_)):
                raise TypeError(f"{name} must be True or False, got {value!r}")
        if packets and counters:
            raise ValueError("packets=True traces hits only: the counters are per-ray "
                             "single-ray quantities; pass counters=False")
        if packets and cull:
            raise ValueError("packets=True traces without leaf culling; pass cull=False")
        o, d = checks.rays(origins, directions)
        n = len(o)
        lo = checks.ray_range(tmin, "tmin", n, default=0.0)
        hi = checks.ray_range(tmax, "tmax", n, default=np.inf)
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
                        checks.threads(threads), bool(cull), progress, bool(packets))
        return out

    def __repr__(self) -> str:
        s = self._tree.stats()
        return (f"<bsplab.Tree {self.method}: {s['triangles']} triangles, {s['nodes']} nodes, "
                f"{s['bytes'] / 2**20:.1f} MiB>")


def core_options(method, opts: dict):
    """The checked options as the core's BuildOptions: the registry sets each
    by name (rbsp_set's "auto" resolved there too), and the method's
    strategy, plus_axes and kd_nodes."""
    return _core.options_for(method.name, opts)


def build(triangles, method: str = "kd", *, progress=None, **options) -> Tree:
    """Builds a tree of `method` over (N, 3, 3) triangles or (vertices, indices)."""
    m = _methods.get(method)
    tris = checks.triangles(triangles)
    opts = checks.build_options(m, options)
    progress = checks.progress(progress)
    try:
        core_tree = _core.build(tris, m.builder, core_options(m, opts), progress)
    except MemoryError as e:
        # The core's "build needs more than ... (memory_limit_mb=...)": name the method.
        if str(e).startswith("build needs"):
            raise MemoryError(f"{method} {e}") from None
        raise
    return Tree(core_tree, method, opts)

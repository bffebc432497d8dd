"""Preview rendering: camera rays through the tree, then per-pixel shading.

Tracing runs in the core (threads, GIL released, progress, cancel); the
shading of the hit buffers is cheap array work and stays in numpy."""

from __future__ import annotations

import time

import numpy as np

from . import _core, checks
from .camera import Camera, image_order, tile_order
from .tree import Tree

RENDER_MODES = ("shaded", "normal", "depth", "heat_steps", "heat_tests", "heat_culled",
                "heat_box_tests")
# The counter each heat mode shows. Box tests are a BVH's (ray-box tests);
# on a kd or BSP tree that map is all 0.
HEAT_COUNTERS = {"heat_steps": "steps", "heat_tests": "tests", "heat_culled": "culled",
                 "heat_box_tests": "box_tests"}
MAX_SIZE = 16384
BACKGROUND = np.array([0.05, 0.05, 0.06], np.float32)

# A perceptual dark-blue -> cyan -> yellow -> red ramp for cost heatmaps.
_RAMP = np.array([[0.05, 0.03, 0.25], [0.10, 0.35, 0.85], [0.10, 0.80, 0.80],
                  [0.55, 0.90, 0.25], [0.98, 0.85, 0.15], [0.90, 0.15, 0.10]], np.float32)


def heat_ramp(x: np.ndarray) -> np.ndarray:
    """Colours for values in [0, 1]."""
    x = np.clip(x, 0.0, 1.0) * (len(_RAMP) - 1)
    i = np.minimum(x.astype(np.int64), len(_RAMP) - 2)
    f = (x - i)[..., None].astype(np.float32)
    return _RAMP[i] * (1 - f) + _RAMP[i + 1] * f


def geometric_normals(triangles: np.ndarray, prim: np.ndarray) -> np.ndarray:
    """Unit normals of the hit triangles (zeros where prim < 0)."""
    n = np.zeros((len(prim), 3), np.float32)
    hit = prim >= 0
    tri = triangles[prim[hit]]
    g = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n[hit] = g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-30)
    return n


def shade(mode: str, hits: dict, directions: np.ndarray, triangles: np.ndarray,
          normals=None) -> np.ndarray:
    """(M, 3) colours of rays for one of RENDER_MODES. `normals`: the hits'
    unit normals where the caller has them (an instanced scene's, carried to
    the world); else those of triangles[prim]."""
    prim = hits["prim"]
    hit = prim >= 0
    rgb = np.broadcast_to(BACKGROUND, (len(prim), 3)).copy()
    if mode in HEAT_COUNTERS:
        cost = hits[HEAT_COUNTERS[mode]].astype(np.float32)
        top = max(float(cost.max(initial=0)), 1.0)
        return heat_ramp(cost / top)
    if not hit.any():
        return rgb
    if mode == "depth":
        t = hits["t"][hit]
        lo, hi = float(t.min()), float(t.max())
        rgb[hit] = (1.0 - (t - lo) / max(hi - lo, 1e-30))[:, None] * 0.9 + 0.1
        return rgb
    n = geometric_normals(triangles, prim) if normals is None else normals(hits)
    if mode == "normal":
        rgb[hit] = n[hit] * 0.5 + 0.5
        return rgb
    # Headlight: the light sits at the eye, so facing surfaces are bright.
    cos = np.abs(np.einsum("ij,ij->i", n[hit], directions[hit]))
    rgb[hit] = (0.15 + 0.8 * cos)[:, None] * np.array([0.92, 0.90, 0.85], np.float32)
    return rgb


def check_size(width, height) -> tuple[int, int]:
    for name, v in (("width", width), ("height", height)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            raise TypeError(f"{name} must be an integer, got {type(v).__name__}")
        if not 0 < v <= MAX_SIZE:
            raise ValueError(f"{name} must be in 1..{MAX_SIZE}, got {v}")
    return int(width), int(height)


def counting(mode: str, counters) -> bool:
    """Whether a render in `mode` traces on the counting path: `counters`
    None means only when the mode shows a counter (the heatmaps)."""
    if counters is None:
        return mode in HEAT_COUNTERS
    if not isinstance(counters, (bool, np.bool_)):
        raise TypeError(f"counters must be True, False or None, got {counters!r}")
    if not counters and mode in HEAT_COUNTERS:
        raise ValueError(f"mode {mode!r} shows the {HEAT_COUNTERS[mode]} counter: "
                         "it needs counters=True (or None)")
    return bool(counters)


def packeted(packets, counted: bool, cull: bool) -> bool:
    """Whether a render traces in ray packets: `packets` None means whenever
    it may (hits only, no culling)."""
    if packets is None:
        return not counted and not cull
    if not isinstance(packets, (bool, np.bool_)):
        raise TypeError(f"packets must be True, False or None, got {packets!r}")
    return bool(packets)


def trace_pixels(tree: Tree, camera: Camera, width: int, height: int, *, threads: int,
                 cull: bool, counted: bool, packets: bool, progress) -> tuple[dict, np.ndarray, float]:
    """The hits of the camera's rays in image order, the rays' directions and
    the trace's seconds. Packets trace the pixels tile by tile (coherent
    packets) and the hits go back to their pixels."""
    origins, directions = camera.rays(width, height)
    order = tile_order(width, height) if packets else slice(None)
    o, d = np.ascontiguousarray(origins[order]), np.ascontiguousarray(directions[order])
    start = time.perf_counter()
    traced = tree.intersect(o, d, threads=threads, cull=cull, counters=counted,
                            packets=packets, progress=progress)
    seconds = time.perf_counter() - start
    return (image_order(traced, order) if packets else traced), directions, seconds


def counter_stats(hits: dict | None) -> dict:
    """The render's per-ray counter statistics; None for each when the
    render traced on the hits-only path (not counted)."""
    if hits is None:
        return dict.fromkeys(("mean_steps", "mean_tests", "mean_culled", "mean_general_steps",
                              "mean_box_tests", "max_steps", "max_tests", "max_culled",
                              "max_box_tests"))
    return {
        "mean_steps": float(hits["steps"].mean()),
        "mean_tests": float(hits["tests"].mean()),
        "mean_culled": float(hits["culled"].mean()),
        "mean_general_steps": float(hits["general_steps"].mean()),
        "max_steps": int(hits["steps"].max()),
        "max_tests": int(hits["tests"].max()),
        # The heat_culled preview's colour bar runs up to it.
        "max_culled": int(hits["culled"].max()),
        # A BVH's ray-box tests (0 on kd and BSP trees); the heat_box_tests bar.
        "mean_box_tests": float(hits["box_tests"].mean()),
        "max_box_tests": int(hits["box_tests"].max()),
    }


def render(tree, camera: Camera, width: int, height: int, mode: str = "shaded", *,
           threads: int = 0, cull: bool | None = None, counters: bool | None = None,
           packets: bool | None = None, progress=None) -> tuple[np.ndarray, dict]:
    """Renders an (H, W, 4) float32 RGBA image (row 0 = top) and its statistics.
    `tree` is a bsplab.Tree or an InstancedTree (bsplab.build_instanced).
    `cull` (leaf culling) defaults to on for the heat_culled mode only.
    `counters` defaults to the heatmap modes only: shaded, normal and depth
    trace on the hits-only path (the same image) and leave the counter
    statistics None; counters=True counts them in the same single trace.
    `packets` defaults to on wherever it may (hits only, no culling): the
    pixels are traced tile by tile in ray packets, the same image."""
    from .instanced import InstancedTree
    if not isinstance(tree, (Tree, InstancedTree)):
        raise TypeError(f"tree must be a bsplab.Tree or InstancedTree, got {type(tree).__name__}")
    if not isinstance(camera, Camera):
        raise TypeError(f"camera must be a bsplab.Camera, got {type(camera).__name__}")
    width, height = check_size(width, height)
    progress = checks.progress(progress)
    if mode not in RENDER_MODES:
        raise ValueError(f"unknown render mode {mode!r}; modes: {', '.join(RENDER_MODES)}")
    counted = counting(mode, counters)
    if cull is None:
        cull = mode == "heat_culled"
    packets = packeted(packets, counted, bool(cull))
    hits, directions, seconds = trace_pixels(tree, camera, width, height, threads=threads,
                                             cull=cull, counted=counted, packets=packets,
                                             progress=progress)
    image = np.ones((height * width, 4), np.float32)
    if isinstance(tree, Tree):
        image[:, :3] = shade(mode, hits, directions, tree.triangles)
    else:  # an instanced scene: its hits' normals carried to the world
        image[:, :3] = shade(mode, hits, directions, None, normals=tree.hit_normals)
    n = width * height
    stats = {
        "seconds": seconds,
        "rays": n,
        "rays_per_second": n / seconds if seconds > 0 else float("inf"),
        "counters": counted,
        **counter_stats(hits if counted else None),
        "hits": int((hits["prim"] >= 0).sum()),
        "width": width,
        "height": height,
        "mode": mode,
        "cull": bool(cull),
        "packets": packets,
        # The instruction-set level the kernels ran at (bsplab.cpu_features()).
        "kernel": _core.cpu_features()["selected"],
    }
    return image.reshape(height, width, 4), stats

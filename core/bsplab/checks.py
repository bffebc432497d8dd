"""Input checks with messages that name the problem. They run before any
array reaches the compiled core, which trusts its inputs."""

from __future__ import annotations

import math
import numbers

import numpy as np

MAX_TRIANGLES = (1 << 30) - 1  # triangle ids share 32 bits with a 2-bit tag in the builder


def float_array(value, name: str, shape_tail: tuple[int, ...]) -> np.ndarray:
    """A C-contiguous float32 array of shape (N, *shape_tail), all finite."""
    arr = np.asarray(value)
    if arr.dtype == object or not (np.issubdtype(arr.dtype, np.floating)
                                   or np.issubdtype(arr.dtype, np.integer)):
        raise TypeError(f"{name} must be a float array, got dtype {arr.dtype}")
    if arr.ndim != 1 + len(shape_tail) or tuple(arr.shape[1:]) != shape_tail:
        want = "(N, " + ", ".join(map(str, shape_tail)) + ")"
        raise ValueError(f"{name} must have shape {want}, got {arr.shape}")
    arr = np.ascontiguousarray(arr, dtype=np.float32)
    finite = np.isfinite(arr)
    if not finite.all():
        bad = np.flatnonzero(~finite.reshape(len(arr), -1).all(axis=1))
        raise ValueError(f"{name} has {len(bad)} entries with NaN or infinite coordinates "
                         f"(first at index {bad[0]})")
    return arr


def triangles(value) -> np.ndarray:
    """(N, 3, 3) float32 triangles from an array or a (vertices, indices) pair."""
    if isinstance(value, tuple):
        if len(value) != 2:
            raise ValueError("a mesh tuple must be (vertices, indices)")
        verts = float_array(value[0], "vertices", (3,))
        idx = np.asarray(value[1])
        if not np.issubdtype(idx.dtype, np.integer):
            raise TypeError(f"indices must be an integer array, got dtype {idx.dtype}")
        if idx.ndim != 2 or idx.shape[1] != 3:
            raise ValueError(f"indices must have shape (N, 3), got {idx.shape}")
        if idx.size and (idx.min() < 0 or idx.max() >= len(verts)):
            raise ValueError(f"indices out of range for {len(verts)} vertices")
        tris = verts[idx]
    else:
        tris = float_array(value, "triangles", (3, 3))
    if len(tris) == 0:
        raise ValueError("there are no triangles to build a tree over")
    if len(tris) > MAX_TRIANGLES:
        raise ValueError(f"{len(tris)} triangles is more than the {MAX_TRIANGLES} supported")
    return np.ascontiguousarray(tris, dtype=np.float32)


def number(value, name: str, *, low=None, high=None, low_open=False, integer=False):
    """A real (or integer) option inside [low, high] (or (low, high])."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a number, got {type(value).__name__}")
    if integer and not float(value).is_integer():
        raise ValueError(f"{name} must be a whole number, got {value}")
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value}")
    if low is not None and (value < low or (low_open and value == low)):
        raise ValueError(f"{name} must be {'>' if low_open else '>='} {low}, got {value}")
    if high is not None and value > high:
        raise ValueError(f"{name} must be <= {high}, got {value}")
    return int(value) if integer else float(value)


def build_options(method, options: dict) -> dict:
    """The checked options of `method` (a method_table.Method), defaults filled in."""
    from .method_table import BSP_OPTIONS, COMMON_OPTIONS, MAX_K
    allowed = method.params
    unknown = sorted(set(options) - set(allowed))
    if unknown:
        raise TypeError(f"unknown build option(s) {', '.join(unknown)} for method "
                        f"{method.name!r}; its options are {', '.join(allowed)}")
    defaults = {**COMMON_OPTIONS, **BSP_OPTIONS, **method.defaults}
    o = {**{k: defaults[k] for k in allowed}, **options}
    out = {
        "traversal_cost": number(o["traversal_cost"], "traversal_cost", low=0, low_open=True,
                                 high=1e6),
        "intersect_cost": number(o["intersect_cost"], "intersect_cost", low=0, low_open=True,
                                 high=1e6),
        "empty_bonus": number(o["empty_bonus"], "empty_bonus", low=0, high=0.99),
        "max_depth": number(o["max_depth"], "max_depth", low=0, high=64, integer=True),
        "leaf_size": number(o["leaf_size"], "leaf_size", low=1, high=1 << 20, integer=True),
        "max_duplication": number(o["max_duplication"], "max_duplication", low=1, high=1000),
        "memory_limit_mb": number(o["memory_limit_mb"], "memory_limit_mb", low=0, low_open=True),
        "threads": threads(o["threads"]),
        "leaf_boxes": choice(o["leaf_boxes"], "leaf_boxes", ("none", "triangle", "clipped")),
    }
    if "k" in allowed:
        k = number(o["k"], "k", integer=True)
        if k < method.min_k or k > MAX_K:
            why = " (a '+' method counts the three axes among its K)" if method.plus_axes else ""
            raise ValueError(f"k must be in {method.min_k}..{MAX_K} for {method.name}{why}, "
                             f"got {k}")
        out["k"] = k
    if "seed" in allowed:
        out["seed"] = number(o["seed"], "seed", low=0, high=2**63 - 1, integer=True)
    if "alpha" in allowed:
        out["alpha"] = number(o["alpha"], "alpha", low=0, high=1e3)
    if "general_cost" in allowed:
        out["general_cost"] = number(o["general_cost"], "general_cost", low=0, low_open=True,
                                     high=1e6)
    if "rbsp_set" in allowed:
        kind = o["rbsp_set"]
        if kind not in ("auto", "spiral", "dop"):
            raise ValueError(f"rbsp_set must be 'auto', 'spiral' or 'dop', got {kind!r}")
        if kind == "dop" and out["k"] not in (3, 7, 9, 13):
            raise ValueError(f"the k-DOP direction sets have K = 3, 7, 9 or 13, got {out['k']}")
        out["rbsp_set"] = kind
    if "cluster_iterations" in allowed:
        out["cluster_iterations"] = number(o["cluster_iterations"], "cluster_iterations", low=1,
                                           high=500, integer=True)
        out["cluster_sample"] = number(o["cluster_sample"], "cluster_sample", low=1,
                                       high=1 << 24, integer=True)
    if "ize_candidates" in allowed:
        out["ize_candidates"] = number(o["ize_candidates"], "ize_candidates", low=1,
                                       high=1 << 20, integer=True)
    return out


def choice(value, name: str, allowed: tuple[str, ...]) -> str:
    if value not in allowed:
        raise ValueError(f"{name} must be one of {', '.join(allowed)}; got {value!r}")
    return value


def threads(value) -> int:
    return number(value, "threads", low=0, high=1024, integer=True)


def rays(origins, directions) -> tuple[np.ndarray, np.ndarray]:
    o = float_array(origins, "origins", (3,))
    d = float_array(directions, "directions", (3,))
    if len(o) != len(d):
        raise ValueError(f"origins ({len(o)}) and directions ({len(d)}) differ in length")
    zero = ~(d != 0).any(axis=1)
    if zero.any():
        raise ValueError(f"{int(zero.sum())} directions have zero length "
                         f"(first at index {int(np.flatnonzero(zero)[0])})")
    return o, d


def ray_range(value, name: str, n: int, default: float = 0.0) -> np.ndarray:
    """tmin/tmax as a length-1 (broadcast) or length-n float32 array; None
    means `default` (0 for tmin, inf, no limit, for tmax)."""
    if value is None:
        value = default
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a number, an array of numbers or None, "
                        f"got {type(value).__name__}") from None
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1 or len(arr) not in (1, n):
        raise ValueError(f"{name} must be a scalar or have shape ({n},), got {arr.shape}")
    if np.isnan(arr).any():
        raise ValueError(f"{name} contains NaN")
    if (arr < 0).any():
        raise ValueError(f"{name} must be >= 0")
    return np.ascontiguousarray(arr, dtype=np.float32)


def progress(value):
    """None or a bsplab.Progress (the core's own type; anything else would
    meet nanobind's raw signature dump)."""
    from . import _core
    if value is not None and not isinstance(value, _core.Progress):
        raise TypeError(f"progress must be a bsplab.Progress or None, got "
                        f"{type(value).__name__}")
    return value

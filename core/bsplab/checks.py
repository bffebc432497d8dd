"""Input checks with messages that name the problem. They run before any
array reaches the compiled core, which trusts its inputs."""

from __future__ import annotations

import math
import numbers

import numpy as np

from .formats.checks import FLOAT32_MAX

MAX_TRIANGLES = (1 << 30) - 1  # triangle ids share 32 bits with a 2-bit tag in the builder


def float_array(value, name: str, shape_tail: tuple[int, ...]) -> np.ndarray:
    """A C-contiguous float32 array of shape (N, *shape_tail), all finite."""
    arr = float_rows(value, name, shape_tail)
    check_finite(arr, name)
    return arr


def float_rows(value, name: str, shape_tail: tuple[int, ...]) -> np.ndarray:
    """A C-contiguous float32 array of shape (N, *shape_tail), not yet checked
    for NaN/inf; a finite value beyond float32's range is refused here, as
    the cast would make it infinite."""
    try:
        arr = np.asarray(value)
    except ValueError:  # rows of different lengths: numpy cannot make an array
        raise TypeError(f"{name} must be an array of shape {_shape(shape_tail)} of numbers; "
                        f"got a {type(value).__name__} whose items differ in shape"
                        f"{_MESH_TUPLE if isinstance(value, list) else ''}") from None
    if arr.dtype == object or not (np.issubdtype(arr.dtype, np.floating)
                                   or np.issubdtype(arr.dtype, np.integer)):
        raise TypeError(f"{name} must be a float array, got dtype {arr.dtype}")
    if arr.ndim != 1 + len(shape_tail) or tuple(arr.shape[1:]) != shape_tail:
        raise ValueError(f"{name} must have shape {_shape(shape_tail)}, got {arr.shape}")
    with np.errstate(over="ignore"):
        out = np.ascontiguousarray(arr, dtype=np.float32)
    if arr.dtype.itemsize > 4 and np.issubdtype(arr.dtype, np.floating):
        _check_float32_range(arr, out, name)
    return out


_FLOAT32_RANGE = "max 3.4e38"  # FLOAT32_MAX, as messages give it

# What a list that is not one array probably meant.
_MESH_TUPLE = " (a mesh of vertices and indices is a tuple: build((vertices, indices)))"


def _shape(shape_tail: tuple[int, ...]) -> str:
    return "(N, " + ", ".join(map(str, shape_tail)) + ")"


def _check_float32_range(wide: np.ndarray, narrow: np.ndarray, name: str) -> None:
    """Refuses values finite in `wide` (float64) that became infinite in
    `narrow` (their float32 cast): beyond float32's range, not NaN or inf."""
    if np.isfinite(narrow).all():
        return
    over = (np.isfinite(wide) & ~np.isfinite(narrow)).reshape(len(wide), -1).any(axis=1)
    if over.any():
        i = int(np.argmax(over))
        raise ValueError(f"{name} has {int(over.sum())} entries out of float32 range "
                         f"({_FLOAT32_RANGE}) (first at index {i}: "
                         f"{_first_over(wide[i])})")


def _first_over(row: np.ndarray) -> str:
    return f"{float(row.reshape(-1)[np.argmax(np.abs(row.reshape(-1)) > FLOAT32_MAX)]):g}"



def check_finite(arr: np.ndarray, name: str) -> None:
    finite = np.isfinite(arr)
    if not finite.all():
        bad = np.flatnonzero(~finite.reshape(len(arr), -1).all(axis=1))
        raise ValueError(f"{name} has {len(bad)} entries with NaN or infinite coordinates "
                         f"(first at index {bad[0]})")


def triangles(value) -> np.ndarray:
    """(N, 3, 3) float32 triangles from an array or a (vertices, indices) pair."""
    if isinstance(value, list) and len(value) == 2 and _looks_like_mesh(value):
        raise TypeError("a mesh of (vertices, indices) must be a tuple, got a list of two "
                        "arrays: build((vertices, indices))")
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


def _looks_like_mesh(pair: list) -> bool:
    """[V (n, 3) floats, F (m, 3) integers]: a (vertices, indices) pair in a
    list. (Of different shapes numpy cannot stack them, and float_rows says
    so; of the same shape they would pass for two triangles.)"""
    try:
        v, f = (np.asarray(x) for x in pair)
    except ValueError:
        return False
    return (v.ndim == f.ndim == 2 and v.shape[1] == f.shape[1] == 3
            and np.issubdtype(v.dtype, np.floating) and np.issubdtype(f.dtype, np.integer))


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
    """The checked options of `method` (a method_table.Method), defaults
    filled in, each against its schema in the core's registry."""
    from .method_table import BSP_OPTIONS, COMMON_OPTIONS, OPTIONS
    allowed = method.params
    unknown = sorted(set(options) - set(allowed))
    if unknown:
        raise TypeError(f"unknown build option(s) {', '.join(unknown)} for method "
                        f"{method.name!r}; its options are {', '.join(allowed)}")
    given = {**COMMON_OPTIONS, **BSP_OPTIONS, **method.defaults, **options}
    out = {name: option(schema, given[name], method)
           for name, schema in OPTIONS.items() if name in allowed}
    for name in out:
        _check_choice_k(OPTIONS[name], out)
    return out


def option(schema: dict, value, method):
    """One option's value checked against its schema (see method_table.OPTIONS)."""
    name = schema["name"]
    if schema["type"] == "enum":
        return choice(value, name, tuple(c["name"] for c in schema["choices"]))
    integer = schema["type"] == "int"
    if not schema["per_method_limits"]:
        return number(value, name, low=schema["min"], high=schema["max"],
                      low_open=schema["min_open"], integer=integer)
    # K: the method narrows the limits.
    value = number(value, name, integer=integer)
    low, high = method.min_k, schema["max"]
    if value < low or value > high:
        why = " (a '+' method counts the three axes among its K)" if method.plus_axes else ""
        raise ValueError(f"{name} must be in {low}..{high} for {method.name}{why}, got {value}")
    return value


def _check_choice_k(schema: dict, out: dict) -> None:
    """A choice that exists only for some K (the k-DOP sets) against the K chosen."""
    for c in schema["choices"]:
        if c["name"] == out[schema["name"]] and c["k_values"] and out.get("k") not in c["k_values"]:
            sizes = ", ".join(map(str, c["k_values"][:-1])) + f" or {c['k_values'][-1]}"
            raise ValueError(f"the {c['label']} direction sets have K = {sizes}, "
                             f"got {out.get('k')}")


def costs_choice(value):
    """`build`'s costs=: None or "default" (the options' costs) or "measured"
    (this machine's costs file)."""
    if value not in (None, "default", "measured"):
        raise ValueError(f"costs must be None, 'default' or 'measured'; got {value!r}")
    return value


def choice(value, name: str, allowed: tuple[str, ...]) -> str:
    if value not in allowed:
        raise ValueError(f"{name} must be one of {', '.join(allowed)}; got {value!r}")
    return value


def trace_flags(cull, counters, packets) -> tuple[bool, bool, bool]:
    """The trace's switches, as intersect() takes them (Tree's and
    InstancedTree's): each True or False, and packets only on the hits-only
    path without culling (a packet's rays share one walk, so there are no
    per-ray counters or per-leaf segment boxes to give)."""
    for name, value in (("cull", cull), ("counters", counters), ("packets", packets)):
        if not isinstance(value, (bool, np.bool_)):
            raise TypeError(f"{name} must be True or False, got {value!r}")
    if packets and counters:
        raise ValueError("packets=True traces hits only: the counters are per-ray "
                         "single-ray quantities; pass counters=False")
    if packets and cull:
        raise ValueError("packets=True traces without leaf culling; pass cull=False")
    return bool(cull), bool(counters), bool(packets)


# Tree.intersect's (and InstancedTree.intersect's) ray_order: how the
# single-ray hits-only path of kd and BSP trees orders a batch (core:
# RayOrder in trace/traverse.hpp, whose values are these indices). "spatial"
# traces an incoherent batch sorted by the rays' origins and directions,
# "auto" does so when a probe of the rays shows their walks long enough to
# pay for the sort, "given" keeps the caller's order; the hits are the same.
RAY_ORDERS = ("auto", "spatial", "given")


def ray_order(value) -> int:
    """The core's RayOrder for a ray_order string."""
    if value not in RAY_ORDERS:
        raise ValueError(f"ray_order must be one of {', '.join(map(repr, RAY_ORDERS))}, "
                         f"got {value!r}")
    return RAY_ORDERS.index(value)


def threads(value) -> int:
    from .method_table import OPTIONS
    return option(OPTIONS["threads"], value, None)


def rays(origins, directions) -> tuple[np.ndarray, np.ndarray]:
    o = float_rows(origins, "origins", (3,))
    d = float_rows(directions, "directions", (3,))
    if len(o) != len(d):
        raise ValueError(f"origins ({len(o)}) and directions ({len(d)}) differ in length")
    # One pass in the core says whether all is well (numpy's checks below
    # cost a quarter of a packet trace); only then are the bad rays found
    # and named.
    from . import _core
    if _core.rays_are_valid(o, d):
        return o, d
    check_finite(o, "origins")
    check_finite(d, "directions")
    # A zero direction has every component +0 or -0: every bit but the sign
    # clear.
    bits = d.view(np.uint32)
    zero = ((bits[:, 0] | bits[:, 1] | bits[:, 2]) & np.uint32(0x7FFFFFFF)) == 0
    if zero.any():
        raise ValueError(f"{int(zero.sum())} directions have zero length "
                         f"(first at index {int(np.flatnonzero(zero)[0])})")
    return o, d


def ray_range(value, name: str, n: int, default: float = 0.0) -> np.ndarray:
    """tmin/tmax as a length-1 (broadcast) or length-n float32 array of real
    numbers >= 0 (inf allowed: no limit); None means `default` (0 for tmin,
    inf for tmax). A string, a complex number, a None inside an array, NaN
    and a finite value beyond float32's range are refused."""
    if value is None:
        value = default
    try:
        arr = np.asarray(value)
    except ValueError:
        arr = np.asarray(value, dtype=object)
    if arr.dtype.kind not in "iuf":  # bool, complex, str, object (None, mixed)
        if arr.ndim == 0:
            shown = f"{type(value).__name__} {value!r}"
        elif arr.dtype == object and any(x is None for x in arr.ravel()):
            shown = f"a {type(value).__name__} holding None (None stands only for the whole {name})"
        else:
            kinds = {"U": "strings", "S": "bytes", "c": "complex numbers", "b": "booleans"}
            shown = f"a {type(value).__name__} of {kinds.get(arr.dtype.kind, arr.dtype)}"
        raise TypeError(f"{name} must be a real number, an array of real numbers or None, "
                        f"got {shown}"[:200])
    arr = arr.astype(np.float64)
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1 or len(arr) not in (1, n):
        raise ValueError(f"{name} must be a scalar or have shape ({n},), got {arr.shape}")
    if np.isnan(arr).any():
        raise ValueError(f"{name} contains NaN (first at index {int(np.argmax(np.isnan(arr)))})")
    if (arr < 0).any():
        raise ValueError(f"{name} must be >= 0")
    over = np.isfinite(arr) & (arr > FLOAT32_MAX)
    if over.any():
        i = int(np.argmax(over))
        raise ValueError(f"{name} out of float32 range ({_FLOAT32_RANGE}): {arr[i]:g} at "
                         f"index {i} (inf means no limit)")
    return np.ascontiguousarray(arr, dtype=np.float32)


def ray_ranges(tmin, tmax, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Checked tmin and tmax (see ray_range), with tmin <= tmax on every ray:
    a ray whose tmin exceeds its tmax could hit nothing."""
    lo = ray_range(tmin, "tmin", n, default=0.0)
    hi = ray_range(tmax, "tmax", n, default=np.inf)
    above = lo > hi
    if above.any():
        i = int(np.argmax(above))
        at = f"ray {i}: " if max(len(lo), len(hi)) > 1 else ""
        raise ValueError(f"tmin must be <= tmax; {at}tmin {lo[min(i, len(lo) - 1)]:g} > "
                         f"tmax {hi[min(i, len(hi) - 1)]:g}")
    return lo, hi


def progress(value):
    """None or a bsplab.Progress (the core's own type; anything else would
    meet nanobind's raw signature dump)."""
    from . import _core
    if isinstance(value, type) and issubclass(value, _core.Progress):
        raise TypeError("progress must be a bsplab.Progress or None, got the class "
                        "bsplab.Progress itself; pass an instance: progress=bsplab.Progress()")
    if value is not None and not isinstance(value, _core.Progress):
        raise TypeError(f"progress must be a bsplab.Progress or None, got "
                        f"{type(value).__name__}")
    return value

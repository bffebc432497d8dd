"""The one table of tree methods. Every interface (Python API, CLI, add-on
enum, benchmark) reads it; adding a method here makes it appear everywhere."""

from __future__ import annotations

from dataclasses import dataclass, field

MAX_K = 64  # directions per node at most (each costs a sort and a sweep per node)

# Options every method understands, with their defaults.
COMMON_OPTIONS = {
    "traversal_cost": 1.0,
    "intersect_cost": 1.5,
    "empty_bonus": 0.2,
    "max_depth": 0,
    "leaf_size": 1,
    "max_duplication": 8.0,
    "memory_limit_mb": 4096.0,
    "threads": 0,
    # Leaf culling with the ray segment's box: "triangle" keeps each
    # triangle's box (24 bytes per triangle), "clipped" each reference's box
    # clipped to its leaf cell (24 bytes per reference), "none" neither.
    "leaf_boxes": "triangle",
}

# Options of the BSP family, with their defaults. The ^Kd costs: Ize et al.
# (2008) price a general node at alpha * K_i * (n - 1) + K_d with alpha = 0.1,
# and fall back to a constant K_d,BSP; general_cost = 2 K_d reflects that a
# general step (two dot products and a division) costs about twice a kd step
# (one subtraction and one multiplication) in our traversal.
BSP_OPTIONS = {
    "k": 6,
    "seed": 1,
    "alpha": 0.1,
    "general_cost": 2.0,
    "rbsp_set": "auto",
    "cluster_iterations": 16,
    "cluster_sample": 1024,
    "ize_candidates": 64,
}

_SWEEP = ("k", "seed")
_KD_COSTS = ("alpha", "general_cost")


@dataclass(frozen=True)
class Method:
    name: str
    label: str
    description: str
    builder: str                 # "kd" (Wald-Havran) or "bsp" (the one sweep builder)
    strategy: str = "axes"       # _core.Strategy name
    plus_axes: bool = False      # "+": the three axes are among the K directions
    kd_nodes: bool = False       # ^Kd: axis splits stored and traversed as kd nodes
    extra: tuple[str, ...] = ()  # BSP options that apply
    defaults: dict = field(default_factory=dict)

    @property
    def params(self) -> tuple[str, ...]:
        return tuple(COMMON_OPTIONS) + self.extra

    @property
    def min_k(self) -> int:
        return 3 if self.plus_axes else 1

    def as_dict(self) -> dict:
        return {"label": self.label, "description": self.description,
                "params": list(self.params), "builder": self.builder,
                "kd_nodes": self.kd_nodes, "plus_axes": self.plus_axes,
                "min_k": self.min_k if "k" in self.extra else None,
                "max_k": MAX_K if "k" in self.extra else None,
                "defaults": {**{k: BSP_OPTIONS[k] for k in self.extra}, **self.defaults}}


def _family(base: str, label: str, what: str, strategy: str, extra: tuple[str, ...],
            k_default: int, plus_only: bool = False) -> list[Method]:
    """A direction strategy as plain, "+" (axes included) and "+kd" (^Kd) methods."""
    out = []
    if not plus_only:
        out.append(Method(base, label, f"{what} at every node.", "bsp", strategy,
                          extra=extra, defaults={"k": k_default}))
    out.append(Method(f"{base}+", f"{label}+", f"The three axes plus {what.lower()}.",
                      "bsp", strategy, plus_axes=True, extra=extra,
                      defaults={"k": k_default}))
    out.append(Method(f"{base}+kd", f"{label}+ ^Kd",
                      f"The three axes plus {what.lower()}; axis splits are fast kd nodes.",
                      "bsp", strategy, plus_axes=True, kd_nodes=True, extra=extra + _KD_COSTS,
                      defaults={"k": k_default}))
    return out


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method("kd", "kd (SAH)",
               "Axis-aligned kd-tree, SAH with perfect splits, O(N log N) build "
               "(Wald & Havran 2006).", "kd"),
        Method("rbsp", "RBSP",
               "Restricted BSP: one fixed set of K directions (k-DOP for K = 3, 7, 9, 13, "
               "else the three axes plus K - 3 golden-spiral points) at every node.", "bsp", "fixed",
               extra=_SWEEP + ("rbsp_set",), defaults={"k": 13}),
        Method("rbsp+kd", "RBSP ^Kd",
               "RBSP whose axis splits are fast kd nodes.", "bsp", "fixed", kd_nodes=True,
               extra=_SWEEP + ("rbsp_set",) + _KD_COSTS, defaults={"k": 13}),
        *_family("bsp_random", "BSP random", "K random directions, fresh", "random",
                 _SWEEP, 10),
        *_family("bsp_wn", "BSP wn", "The normals of K random triangles of the node",
                 "normals", _SWEEP, 6),
        *_family("bsp_cn", "BSP cn",
                 "K cluster centres (antipodal spherical k-means) of the node's normals",
                 "clustered", _SWEEP + ("cluster_iterations", "cluster_sample"), 6),
        Method("bsp_ize", "BSP IZE",
               "kd planes plus every triangle's own plane and its three edge planes "
               "(Ize, Wald & Parker 2008).", "bsp", "ize", plus_axes=True,
               extra=("seed", "ize_candidates")),
        Method("bsp_ize+kd", "BSP IZE ^Kd", "BSP_IZE whose axis splits are fast kd nodes.",
               "bsp", "ize", plus_axes=True, kd_nodes=True,
               extra=("seed", "ize_candidates") + _KD_COSTS),
    )
}


def methods() -> dict[str, dict]:
    """Name -> {label, description, params, ...} for every tree method."""
    return {name: m.as_dict() for name, m in METHODS.items()}


def get(name: str) -> Method:
    if not isinstance(name, str):
        raise TypeError(f"method must be a string, not {type(name).__name__}")
    try:
        return METHODS[name]
    except KeyError:
        raise ValueError(f"unknown method {name!r}; known methods: {', '.join(METHODS)}") from None

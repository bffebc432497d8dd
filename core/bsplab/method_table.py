"""The one table of tree methods and their options, generated from the core's
registry (core/src/registry.cpp, exported as `_core.registry()`). Every
interface (Python API, CLI, add-on enum and panel, benchmarks) reads it;
adding a method to the registry makes it appear everywhere."""

from __future__ import annotations

from dataclasses import dataclass, field

from . import _core

_REGISTRY = _core.registry()

MAX_K = _REGISTRY["max_k"]  # directions per node at most (each costs a sort and a sweep per node)

# Name -> schema of every build option: type ("float", "int", "enum"),
# default, min/max (None: unbounded; min_open: min itself is excluded),
# per_method_limits (K: min/max are the widest, a method's min_k narrows
# them), soft_max (a slider's
# end), choices ({name, label, help, k_values}), label, short_label, help,
# and the BuildOptions field it sets. In the core's order.
OPTIONS: dict[str, dict] = {o["name"]: o for o in _REGISTRY["options"]}

# Options every method understands, with their defaults.
COMMON_OPTIONS = {name: o["default"] for name, o in OPTIONS.items() if o["group"] == "common"}

# Common options that bound how a tree is built (its threads, its memory)
# and change nothing in the tree built: two trees built under other values
# of them are the same tree (build_instanced does not compare them).
NOT_TREE_OPTIONS = ("threads", "memory_limit_mb")

# Options of the BSP family, with their defaults (a method lists the ones
# that apply to it in `extra`).
BSP_OPTIONS = {name: o["default"] for name, o in OPTIONS.items() if o["group"] == "bsp"}

# The options of an instanced scene's top level (bsplab.build_instanced), with
# their defaults: no method's (a tree's build refuses them).
TOP_OPTIONS = {name: o["default"] for name, o in OPTIONS.items() if o["group"] == "top"}

# The direction strategies of the core (core/src/builders/strategies/).
STRATEGIES: tuple[str, ...] = tuple(_REGISTRY["strategies"])


@dataclass(frozen=True)
class Method:
    name: str
    label: str
    description: str
    builder: str                 # "kd" (Wald-Havran), "bsp" (the one sweep builder), "bvh"
    # Every interior node of its trees is a general node (the sweep builder
    # without ^Kd), so its traversal step is the general step.
    all_general_nodes: bool = False
    strategy: str = "axes"       # a name in STRATEGIES
    plus_axes: bool = False      # "+": the three axes are among the K directions
    kd_nodes: bool = False       # ^Kd: axis splits stored and traversed as kd nodes
    extra: tuple[str, ...] = ()  # BSP options that apply
    defaults: dict = field(default_factory=dict)
    # What its trees are made of: "bvh" (boxes) or "bsp" (split planes: kd, BSP).
    structure: str = "bsp"

    @property
    def params(self) -> tuple[str, ...]:
        return tuple(COMMON_OPTIONS) + self.extra

    @property
    def min_k(self) -> int:
        # A "+" method counts the three axes among its K (the registry's rule).
        return _MIN_K[self.name]

    def as_dict(self) -> dict:
        takes_k = "k" in self.extra
        # K's limits only for methods that take K.
        return {"label": self.label, "description": self.description,
                "params": list(self.params), "builder": self.builder,
                "structure": self.structure,
                "kd_nodes": self.kd_nodes, "plus_axes": self.plus_axes,
                "min_k": self.min_k if takes_k else None,
                "max_k": MAX_K if takes_k else None,
                "defaults": {**{k: COMMON_OPTIONS[k] for k in _overridden_common()},
                             **{k: BSP_OPTIONS[k] for k in self.extra}, **self.defaults}}


def _overridden_common() -> list[str]:
    """The common options some method gives a default of its own (the BVH's
    intersect_cost): every method's table says its value of them, so that a
    panel switching from that method to another loads the other's back."""
    return sorted({k for m in _REGISTRY["methods"] for k in m["defaults"] if k in COMMON_OPTIONS})


def _method(entry: dict) -> Method:
    return Method(entry["name"], entry["label"], entry["description"], entry["builder"],
                  entry["all_general_nodes"], entry["strategy"], entry["plus_axes"],
                  entry["kd_nodes"], tuple(entry["options"]), dict(entry["defaults"]),
                  entry["structure"])


_MIN_K = {m["name"]: m["min_k"] for m in _REGISTRY["methods"]}

METHODS: dict[str, Method] = {m["name"]: _method(m) for m in _REGISTRY["methods"]}


def methods() -> dict[str, dict]:
    """Name -> {label, description, params, ...} for every tree method."""
    return {name: m.as_dict() for name, m in METHODS.items()}


def option_schema() -> dict[str, dict]:
    """Name -> schema of every build option (see OPTIONS), for interfaces
    that show or edit options (the add-on's panel)."""
    return {name: dict(o) for name, o in OPTIONS.items()}


def get(name: str) -> Method:
    if not isinstance(name, str):
        raise TypeError(f"method must be a string, not {type(name).__name__}")
    try:
        return METHODS[name]
    except KeyError:
        raise ValueError(f"unknown method {name!r}; known methods: {', '.join(METHODS)}") from None

"""The one table of tree methods. Every interface (Python API, CLI, add-on
enum, benchmark) reads it; adding a method here makes it appear everywhere."""

from __future__ import annotations

from dataclasses import dataclass

# Options every method understands, with their defaults. The Python API checks
# names and ranges against this table before anything reaches the core.
COMMON_OPTIONS = {
    "traversal_cost": 1.0,
    "intersect_cost": 1.5,
    "empty_bonus": 0.2,
    "max_depth": 0,
    "leaf_size": 1,
    "max_duplication": 8.0,
    "memory_limit_mb": 4096.0,
    "threads": 0,
}


@dataclass(frozen=True)
class Method:
    name: str
    label: str
    description: str
    builder: str  # the _core function that builds it
    params: tuple[str, ...] = tuple(COMMON_OPTIONS)

    def as_dict(self) -> dict:
        return {"label": self.label, "description": self.description, "params": list(self.params)}


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method(
            name="kd",
            label="kd (SAH)",
            description="Axis-aligned kd-tree, SAH with perfect splits, O(N log N) build "
            "(Wald & Havran 2006).",
            builder="build_kd",
        ),
    )
}


def methods() -> dict[str, dict]:
    """Name -> {label, description, params} for every tree method."""
    return {name: m.as_dict() for name, m in METHODS.items()}


def get(name: str) -> Method:
    if not isinstance(name, str):
        raise TypeError(f"method must be a string, not {type(name).__name__}")
    try:
        return METHODS[name]
    except KeyError:
        raise ValueError(f"unknown method {name!r}; known methods: {', '.join(METHODS)}") from None

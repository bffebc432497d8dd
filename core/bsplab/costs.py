"""The measured SAH costs of this machine: the small file that
`python -m bsplab calibrate --write` stores and `build(..., costs="measured")`
reads.

The costs belong to the machine (its caches, its vector units, the kernel the
core was built with), not to a scene or a checkout, so the file lives in the
user's configuration folder: `$BSPLAB_COSTS` when set (a CI job or a second
machine profile points it elsewhere), else `$XDG_CONFIG_HOME/bsplab/costs.toml`
(`~/.config/bsplab/costs.toml` when XDG_CONFIG_HOME is unset), where the XDG
convention puts per-user settings that are not data and not cache.

The builders' SAH only compares costs with one another, so the file holds
them in the builders' unit, the kd step: traversal_cost = 1, intersect_cost =
K_i / K_kd and general_cost = K_gen / K_kd as `calibrate` fitted them.
"""

from __future__ import annotations

import math
import os
import tomllib
from datetime import datetime, timezone
from pathlib import Path

# The build options a measured file sets, each a ratio to the kd step.
COST_OPTIONS = ("traversal_cost", "intersect_cost", "general_cost")

def costs_path() -> Path:
    """Where the measured costs are read and written (see the module's note)."""
    override = os.environ.get("BSPLAB_COSTS")
    if override:
        return Path(override).expanduser()
    config = os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config"
    return Path(config) / "bsplab" / "costs.toml"


def costs_from_fit(fit: dict) -> dict[str, float]:
    """The build options a `calibrate` fit stands for, in kd steps; a fit that
    priced a test or a general step at zero or below cannot drive a build."""
    out = {"traversal_cost": 1.0, "intersect_cost": fit["intersect_per_kd"],
           "general_cost": fit["general_per_kd"]}
    _check_costs(out, "the fit")
    return out


def write_costs(fit: dict, path: Path | None = None) -> Path:
    """Stores the fit's costs (and, for the reader, what they came from)."""
    costs = costs_from_fit(fit)
    path = path or costs_path()
    path.parent.mkdir(parents=True, exist_ok=True)
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    lines = [f"# Written by `python -m bsplab calibrate --write` on {stamp}.",
             "# The SAH costs of this machine in kd steps (traversal_cost = 1).",
             "[costs]"]
    lines += [f"{name} = {value!r}" for name, value in costs.items()]
    lines += ["", "[fit]"]
    lines += [f"{name} = {value!r}" for name, value in fit.items()
              if isinstance(value, (int, float)) and not isinstance(value, bool)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def read_costs(path: Path | None = None) -> dict[str, float]:
    """The measured costs as build options; ValueError naming the file and
    the remedy when there are none or they cannot be read."""
    path = path or costs_path()
    remedy = "run `python -m bsplab calibrate --write` to measure them"
    if not path.is_file():
        raise ValueError(f"no measured costs: {path} does not exist ({remedy}, or set "
                         "BSPLAB_COSTS to a costs file)")
    try:
        table = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise ValueError(f"the measured costs file {path} is not valid TOML ({e}); {remedy}") \
            from None
    costs = table.get("costs")
    if not isinstance(costs, dict) or set(costs) != set(COST_OPTIONS):
        raise ValueError(f"the measured costs file {path} must have a [costs] table with "
                         f"exactly {', '.join(COST_OPTIONS)}; {remedy}")
    _check_costs(costs, str(path))
    return {name: float(costs[name]) for name in COST_OPTIONS}


def _check_costs(costs: dict, source: str) -> None:
    for name, value in costs.items():
        if (isinstance(value, bool) or not isinstance(value, (int, float))
                or not math.isfinite(value) or value <= 0):
            raise ValueError(f"{source} gives {name} = {value!r}; a cost must be a positive "
                             "finite number")


def measured_options(method, given: dict) -> dict:
    """The measured costs as `method`'s build options (a method_table.Method).
    A ^Kd method prices its axis nodes with traversal_cost and its general
    nodes with general_cost; a BSP method without ^Kd traverses every node
    as a general one, so its traversal_cost is the general step; kd takes
    no general_cost. Options given explicitly would silently win or lose
    against the file, so asking for both is an error."""
    both = sorted(set(given) & set(COST_OPTIONS))
    if both:
        raise ValueError(f"costs='measured' sets {', '.join(both)} from the measured costs "
                         "file; give either costs='measured' or the costs themselves")
    measured = read_costs()
    if method.all_general_nodes:
        measured["traversal_cost"] = measured["general_cost"]
    return {name: value for name, value in measured.items() if name in method.params}

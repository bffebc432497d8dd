"""The add-on's layout as docs/addon.md#layout states it, read from the
source (every import, the lazy ones inside functions too): no import circle,
the shared machinery (addon/jobs/) below the features, no feature reaching
into another's modules, and the kinds of tree told apart only through the
features' tables on `tree.structure`, each of which knows every kind the
core builds."""

import ast
from pathlib import Path

import numpy as np
import pytest

import bsplab

ADDON = Path(__file__).resolve().parents[2] / "addon"
FEATURES = ("build_render", "compare", "k_sweep", "inspector", "overlay")
# Below the features: what every feature may import.
SHARED = ("jobs", "drawing")
# The one module of a feature that others use: compare's bpy-free image
# helpers (Build & Render makes the A/B preview, the inspector tells which
# half of a split preview a pixel is on).
SHARED_FEATURE_MODULES = {"compare.images"}


def _modules():
    """{dotted name below the add-on: path} of the shipped modules."""
    out = {}
    for path in sorted(ADDON.rglob("*.py")):
        parts = path.relative_to(ADDON).with_suffix("").parts
        if parts[0] in ("tests", "tools"):
            continue
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _imports(name, path):
    """The add-on modules `name` imports (relative imports, anywhere in it)."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if not isinstance(node, ast.ImportFrom) or not node.level:
            continue
        base = package[:len(package) - (node.level - 1)]
        target = ".".join(base + ([node.module] if node.module else []))
        for alias in node.names:
            full = ".".join(filter(None, (target, alias.name)))
            found.add(full if full in MODULES else target)
    return {m for m in found if m in MODULES and m != name}


GRAPH = {name: _imports(name, path) for name, path in MODULES.items()}


def _is_registration(name, target):
    """A package's __init__ importing its own modules to register them."""
    return MODULES[name].name == "__init__.py" and target.startswith(name + ".") if name else True


def _cycles():
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []

    def visit(node):
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for nxt in GRAPH[node]:
            if _is_registration(node, nxt):
                continue
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in on_stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for node in GRAPH:
        if node not in index:
            visit(node)
    return out


def _top(name):
    return name.split(".")[0]


def test_the_graph_sees_the_imports():
    # The reader itself: a lazy import inside a function counts.
    assert "jobs.tree_cache" in GRAPH["state"]
    assert {"jobs.worker", "jobs.job_operator", "jobs.scene_reader"} <= GRAPH["k_sweep.operator"]


def test_no_import_circle():
    assert _cycles() == []


def test_the_shared_machinery_imports_no_feature():
    for name, targets in GRAPH.items():
        if _top(name) in SHARED:
            assert not {t for t in targets if _top(t) in FEATURES}, name


def test_no_feature_imports_another_features_modules():
    for name, targets in GRAPH.items():
        if _top(name) not in FEATURES:
            continue
        foreign = {t for t in targets if _top(t) in FEATURES and _top(t) != _top(name)}
        assert foreign <= SHARED_FEATURE_MODULES, (name, foreign)


def test_nothing_imports_build_render():
    """Build & Render is one feature among the others."""
    for name, targets in GRAPH.items():
        if name and _top(name) != "build_render":
            assert not {t for t in targets if _top(t) == "build_render"}, name


# What telling a tree's kind by its attributes looked like.
KIND_ATTRIBUTES = {"structure", "mesh_index", "flatten", "meshes", "instance_at"}


def test_no_tree_kind_is_told_by_its_attributes():
    for name, path in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
                    and node.func.id in ("hasattr", "getattr") and len(node.args) >= 2
                    and isinstance(node.args[1], ast.Constant)):
                assert node.args[1].value not in KIND_ATTRIBUTES, (name, ast.unparse(node))


@pytest.fixture(scope="module")
def structures():
    """The kinds of tree the core builds: every method's flat tree, and a
    two-level build's."""
    triangles = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]],
                          [[0, 0, 1], [1, 0, 1], [0, 1, 1]]], np.float32)
    flat = {bsplab.build(triangles, method=method).structure for method in bsplab.methods()}
    two_level = bsplab.build_instanced([bsplab.build(triangles, method="kd")], [0],
                                       np.eye(4)[None, :3], "kd").structure
    return flat, two_level


def _table_keys(module, table):
    """The constant keys of the dict assigned to `table` in addon/`module`."""
    tree = ast.parse(MODULES[module].read_text())
    for node in tree.body:
        targets = [t.id for t in getattr(node, "targets", []) if isinstance(t, ast.Name)]
        if table in targets and isinstance(node.value, ast.Dict):
            return {key.value for key in node.value.keys}
    raise AssertionError("no dict {} in {}".format(table, module))


# The per-kind tables: of every kind of tree, or of the flat kinds only
# (a flat tree's, or a two-level build's mesh trees').
EVERY_KIND = (("jobs.embree_check", "SIDES"), ("build_render.job", "BUILD_STATS"),
              ("build_render.statistics", "BUILD_ROWS"),
              ("build_render.statistics", "COMPARED_ROWS"),
              ("build_render.operator", "BUILD_REPORTS"), ("build_render.operator", "NODE_COUNTS"),
              ("inspector.operators", "INSPECTIONS"),
              ("inspector.panel", "WALK_PANELS"), ("overlay.cache", "DRAWN"),
              ("overlay.panel", "PANEL_KINDS"))
FLAT_KINDS = (("inspector.walk_arrays", "CROSSED"), ("inspector.walk_arrays", "INSTANCE_CROSSED"),
              ("overlay.geometry", "FLAT_DRAWN"), ("overlay.panel", "SETTINGS_ROWS"))


@pytest.mark.parametrize("module, table", EVERY_KIND)
def test_a_table_of_every_kind_knows_every_structure(structures, module, table):
    flat, two_level = structures
    assert _table_keys(module, table) == flat | {two_level}


@pytest.mark.parametrize("module, table", FLAT_KINDS)
def test_a_table_of_the_flat_kinds_knows_every_flat_structure(structures, module, table):
    assert _table_keys(module, table) == structures[0]

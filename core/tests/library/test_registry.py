"""The core's registry of methods and options (core/src/registry.cpp) and
what the Python package generates from it."""

from __future__ import annotations

import math

import pytest

import bsplab
from bsplab import _core, checks, scenes
from bsplab.method_table import (BSP_OPTIONS, COMMON_OPTIONS, MAX_K, METHODS, OPTIONS,
                                 STRATEGIES, TOP_OPTIONS)

def test_methods_name_known_strategies_builders_and_options():
    assert set(STRATEGIES) >= {"axes", "fixed", "random", "normals", "clustered", "ize"}
    for m in METHODS.values():
        assert m.strategy in STRATEGIES, m.name
        for name in m.params:
            assert name in OPTIONS, (m.name, name)
        # A method's own defaults are of options it takes: its family's, or
        # a common one it prices its own way (the BVH's intersect_cost).
        for name in m.defaults:
            assert name in m.params, (m.name, name)
    # Every strategy is used by some method: none is registered but unreachable.
    assert {m.strategy for m in METHODS.values()} == set(STRATEGIES)


@pytest.mark.parametrize("method", list(METHODS))
def test_all_general_nodes_says_what_the_trees_hold(method):
    # The registry's statement the measured costs rely on (bsplab.costs):
    # a method whose trees hold general nodes only, or one whose trees may
    # hold kd nodes. (The room: axis-aligned walls, where every method
    # splits along the axes too.)
    m = METHODS[method]
    s = bsplab.build(scenes.generate("room"), method).stats
    assert s["interior_nodes"] > 0
    if m.structure == "bvh":  # box nodes only: neither kd nor general nodes
        assert s["kd_nodes"] == 0 and s["general_nodes"] == 0 and s["structure"] == "bvh"
    elif m.all_general_nodes:
        assert s["kd_nodes"] == 0 and s["general_nodes"] == s["interior_nodes"]
    else:
        assert s["kd_nodes"] > 0


def test_groups_split_the_options():
    assert list(OPTIONS) == list(COMMON_OPTIONS) + list(BSP_OPTIONS) + list(TOP_OPTIONS)
    used = {name for m in METHODS.values() for name in m.extra}
    assert used == set(BSP_OPTIONS)
    # The top level's are no method's.
    assert set(TOP_OPTIONS) == {"top_bins", "top_traversal_cost", "top_intersect_cost"}
    assert not any(set(TOP_OPTIONS) & set(m.params) for m in METHODS.values())


def test_top_settings_come_from_the_registry():
    s = _core.top_settings_for({})
    assert (s.bins, s.traversal_cost, s.intersect_cost, s.threads) == (
        TOP_OPTIONS["top_bins"], TOP_OPTIONS["top_traversal_cost"],
        TOP_OPTIONS["top_intersect_cost"], COMMON_OPTIONS["threads"])
    s = _core.top_settings_for({"top_bins": 40, "top_intersect_cost": 2.5, "threads": 3})
    assert (s.bins, s.intersect_cost, s.threads) == (40, 2.5, 3)
    # The same bins limits as a BVH's: the same builder.
    assert (OPTIONS["top_bins"]["min"], OPTIONS["top_bins"]["max"]) == \
        (OPTIONS["bins"]["min"], OPTIONS["bins"]["max"])


@pytest.mark.parametrize("values, words", [
    ({"k": 6}, "option k is not read by the top level; its options are threads, top_bins"),
    ({"colour": 1}, "unknown option colour"),
    ({"top_bins": 2.5}, "option top_bins takes a whole number"),
])
def test_top_settings_refuse_other_options(values, words):
    with pytest.raises(ValueError, match=words):
        _core.top_settings_for(values)


def test_a_tree_refuses_the_top_levels_options():
    with pytest.raises(ValueError, match="option top_bins is the top level's of an instanced"):
        _core.options_for("kd", {"top_bins": 16})
    with pytest.raises(TypeError, match="unknown build option.s. top_bins for method 'kd'"):
        bsplab.build(scenes.generate("cube"), "kd", top_bins=16)


def within(spec, value, low=None):
    low = spec["min"] if low is None else low
    if low is not None and (value < low or (spec["min_open"] and value == low)):
        return False
    return spec["max"] is None or value <= spec["max"]


@pytest.mark.parametrize("name", list(OPTIONS))
def test_schema_is_complete_and_its_default_is_valid(name):
    spec = OPTIONS[name]
    assert spec["label"] and spec["short_label"] and spec["help"]
    # The field it sets: a tree's BuildOptions', a top option's the top level's.
    fields = _core.TopLevelSettings() if spec["group"] == "top" else _core.BuildOptions()
    assert hasattr(fields, spec["field"])
    if spec["type"] == "enum":
        assert spec["default"] in [c["name"] for c in spec["choices"]]
        assert spec["min"] is None and spec["max"] is None
        return
    assert not spec["choices"]
    assert isinstance(spec["default"], int if spec["type"] == "int" else float)
    assert within(spec, spec["default"])
    if spec["min"] is not None and spec["max"] is not None:
        assert spec["min"] < spec["max"]
    if spec["soft_max"] is not None:
        assert within(spec, spec["soft_max"])


@pytest.mark.parametrize("method", list(METHODS))
def test_method_defaults_are_valid(method):
    m = METHODS[method]
    opts = checks.build_options(m, {})
    assert set(opts) == set(m.params)
    info = bsplab.methods()[method]
    for name, value in info["defaults"].items():
        assert opts[name] == value
    if "k" in m.extra:
        assert m.min_k <= opts["k"] <= MAX_K == OPTIONS["k"]["max"]
        assert m.min_k == (3 if m.plus_axes else 1)


def beyond(spec):
    """Values just outside each limit of a numeric option."""
    out = []
    if spec["min"] is not None:
        out.append(spec["min"] if spec["min_open"] else spec["min"] - 1)
    if spec["max"] is not None:
        out.append(spec["max"] + 1 if spec["type"] == "int" else spec["max"] * 1.5 + 1)
    return out


@pytest.mark.parametrize("method", ["kd", "rbsp+kd", "bsp_cn+kd", "bsp_ize"])
def test_a_limit_violation_names_the_option(method):
    m = METHODS[method]
    for name in m.params:
        spec = OPTIONS[name]
        if spec["per_method_limits"]:
            bad = [m.min_k - 1, MAX_K + 1]
        elif spec["type"] == "enum":
            bad = ["no such choice"]
        else:
            bad = beyond(spec)
        for value in bad:
            with pytest.raises(ValueError, match=f"^{name} must be "):
                bsplab.build(scenes.generate("cube"), method, **{name: value})


def test_k_limits_are_the_methods():
    with pytest.raises(ValueError, match=r"k must be in 3\.\.64 for bsp_wn\+ \(a '\+' method"):
        bsplab.build(scenes.generate("cube"), "bsp_wn+", k=2)
    with pytest.raises(ValueError, match="the k-DOP direction sets have K = 3, 7, 9 or 13, got 5"):
        bsplab.build(scenes.generate("cube"), "rbsp", k=5, rbsp_set="dop")


@pytest.mark.parametrize("k, kind, fixed_set", [
    (7, "auto", 1), (13, "auto", 1), (8, "auto", 2), (3, "auto", 1), (8, "spiral", 0),
    (9, "dop", 1),
])
def test_rbsp_set_rule_lives_in_the_core(k, kind, fixed_set):
    o = _core.options_for("rbsp", {"k": k, "rbsp_set": kind})
    assert (o.k, o.fixed_set, o.strategy) == (k, fixed_set, "fixed")


def test_options_for_sets_fields_by_name():
    opts = checks.build_options(METHODS["bsp_cn+kd"], {"k": 9, "seed": 2**63 - 1, "alpha": 0.5})
    o = _core.options_for("bsp_cn+kd", opts)
    assert (o.strategy, o.plus_axes, o.kd_nodes) == ("clustered", True, True)
    assert (o.k, o.seed, o.leaf_boxes) == (9, 2**63 - 1, _core.LeafBoxes.triangle)
    assert math.isclose(o.alpha, 0.5) and math.isclose(o.traversal_cost, 1.0)
    assert o.cluster_sample == 1024


@pytest.mark.parametrize("values, words", [
    ({"colour": 1}, "unknown option colour"),
    ({"k": "six"}, "option k takes a number"),
    ({"k": 6.5}, "option k takes a whole number"),
    ({"leaf_boxes": 1}, "option leaf_boxes takes a string"),
    ({"leaf_boxes": "all"}, "option leaf_boxes must be none, triangle or clipped"),
    ({"build_quality": 1}, "option build_quality takes a string"),
    ({"build_quality": "turbo"}, "option build_quality must be exact or fast, got turbo"),
    ({"fast_bins": 8.5}, "option fast_bins takes a whole number"),
])
def test_options_for_refuses_bad_names_and_types(values, words):
    with pytest.raises(ValueError, match=words):
        _core.options_for("bsp_wn", values)


def test_build_quality_is_kds_and_the_sweeps_not_the_bvhs():
    # The BVH is binned whatever it is asked; every other method takes the option.
    assert "build_quality" not in METHODS["bvh"].params
    for name, m in METHODS.items():
        if name != "bvh":
            assert {"build_quality", "fast_bins", "fast_min_refs"} <= set(m.params), name
    o = _core.options_for("kd", {"build_quality": "fast", "fast_bins": 16, "fast_min_refs": 100})
    assert (o.build_quality, o.fast_bins, o.fast_min_refs) == (_core.BuildQuality.fast, 16, 100)
    assert _core.options_for("kd", {}).build_quality == _core.BuildQuality.exact
    with pytest.raises(TypeError, match="unknown build option.s. build_quality for method 'bvh'"):
        bsplab.build(scenes.generate("cube"), "bvh", build_quality="fast")


def test_unknown_method_is_named():
    # (An unknown strategy cannot come from Python: the registry sets it from
    # the method; cpp_tests/test_registry.cpp checks make_strategy's message.)
    with pytest.raises(ValueError, match="unknown method octree; known: kd, rbsp"):
        _core.options_for("octree", {})
    with pytest.raises(ValueError, match="unknown method octree; known: kd, rbsp"):
        _core.build(scenes.generate("cube"), "octree", {}, None)


def test_build_sets_options_by_name_in_one_call():
    # The fan (9k triangles): a ^Kd tree of general and kd nodes either way,
    # built in a tenth of the spheres' time (22 s under ASan + UBSan).
    tris = scenes.generate("fan")
    tree = _core.build(tris, "bsp_wn+kd", {"k": 4, "seed": 3, "leaf_size": 2}, None)
    same = bsplab.build(tris, "bsp_wn+kd", k=4, seed=3, leaf_size=2)
    assert tree.node_bytes() == same._tree.node_bytes()
    with pytest.raises(ValueError, match="option k takes a whole number"):
        _core.build(tris, "bsp_wn", {"k": 6.5}, None)

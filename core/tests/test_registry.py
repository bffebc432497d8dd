"""The core's registry of methods and options (core/src/registry.cpp) and
what the Python package generates from it."""

from __future__ import annotations

import hashlib
import math

import pytest

import bsplab
from bsplab import _core, checks, scenes
from bsplab.method_table import BSP_OPTIONS, COMMON_OPTIONS, MAX_K, METHODS, OPTIONS, STRATEGIES

# sha256 and size of node_bytes() of every method with its defaults, built by
# main before the strategies moved into core/src/strategies/: moving them
# must not change a single tree.
DEFAULT_TREES = {
    ("room", "kd"): (37240, "753c2ac9d09187ba4c534f20836a36ba9eeea91662187bb56d6018820ba74dfe"),
    ("room", "rbsp"): (83528, "7422e664096618878cc4d01ea5adbd4475a111d398b16f3be4b5e7a4448e6fc5"),
    ("room", "rbsp+kd"): (41496, "ff74b211abc43e61d5c12ea68317ddd243bb416cafd86d8930c8c854ba4d5e32"),
    ("room", "bsp_random"): (291272, "bbd1f45287ea648734488482b1b7dbdb00d3a9a6c2f63f96f4bc6896f16c41bd"),
    ("room", "bsp_random+"): (81480, "585341c8f51f9aceb74a464cde2bf5325e84e9fe4441ce4358452eefa3b74864"),
    ("room", "bsp_random+kd"): (39368, "33195daf1eb1495c0319cc707886863d243d31f492439f29232a990973a4b1a5"),
    ("room", "bsp_wn"): (36104, "dc98929dc24989199b1629a7f64ac6f2e93751337153888ea548115b1ffc9bf7"),
    ("room", "bsp_wn+"): (70888, "afd8565ac62d158b5bdef53d1287b2fd15b2e34a49f43d33d5359ff22a5bf05d"),
    ("room", "bsp_wn+kd"): (38104, "cc5eb474f0d1f83746ce3da4485d2258678676d5f9bdf5676c0688bc83851d6c"),
    ("room", "bsp_cn"): (35880, "d5508f1a312675394f1f428b4337444864fbf5c8b2afe11567e470cf029a5469"),
    ("room", "bsp_cn+"): (70600, "facf33bfa570b9ef508165edcdf6be098a818a90506d572b046bcd3e27e41fb2"),
    ("room", "bsp_cn+kd"): (38088, "abd100f3bba13917935f0fb589c61c197df56cecc81119eb2f93b8c15feaa665"),
    ("room", "bsp_ize"): (85864, "dfba5b17e2d81a202c4ba3a38b9be4a87d3d218dadaf732de33d623d72161f18"),
    ("room", "bsp_ize+kd"): (46296, "de4d799c73fc443af16d08115e7bd11b8e24ed06f63a9a3b65f2ff82cf9c281c"),
    ("fan", "kd"): (46664, "86a8a9a9b06a2440aae2d686379c312f6432d5e1d701857f7f5d0696e2488f69"),
    ("fan", "rbsp"): (60264, "b835e61b2d0eb85585e29a96fc99453ea23a72350a37067411e2e3fedbeff980"),
    ("fan", "rbsp+kd"): (47016, "a445be359be92ce59d048954d9d2694011b9999a36a8768f93a6868774aa8e12"),
    ("fan", "bsp_random"): (808, "ee20056795fb762dd1c883bc7327bd14a1dfaf1e2bc82f175e4337d4bc900fca"),
    ("fan", "bsp_random+"): (146728, "795f6d4b0a01a1a989d616bdc157b0a7670e14cb2ac5ee011e107ed0a79c1173"),
    ("fan", "bsp_random+kd"): (72920, "fc79803230867c03eec0a6d39bfaba4b9f83b619e392bcf12d7f609e9e7b190c"),
    ("fan", "bsp_wn"): (41224, "b18022811a9ffbb79445ebc1ca612375b5f6f842179cc8a9ea0b67b76bbc593e"),
    ("fan", "bsp_wn+"): (41768, "23139da337c2f4430c9b2b2c7f8d54b6a40f13752b6a232715e20d6ec703af96"),
    ("fan", "bsp_wn+kd"): (26424, "da480902e955a434b5d2487cd226aaf4db7c6122082fa075808d257cb5bb546b"),
    ("fan", "bsp_cn"): (69640, "02e3591542223787759f1b429326f8013a4a8382e75d18fd777e496e7575b7b6"),
    ("fan", "bsp_cn+"): (75176, "02013255dd0c5732cb3dc799f4a26a44d33524b715d863be38ad2d9abdbd8e98"),
    ("fan", "bsp_cn+kd"): (26216, "1e76ba95e73a6196e1b01c2664a6ef18d03b91d542e094dfbd27127daf837fcc"),
    ("fan", "bsp_ize"): (199144, "44924cab730d8bb514153733c313b0824e0ba65c121feb306351a2c870ffbf01"),
    ("fan", "bsp_ize+kd"): (137976, "f74842277588d303e6bdf17828e0efe3a4970e1a16bd073bad40fa40815177d9"),
}

# The same with options away from the defaults (rbsp_set's auto rule, the
# strategies' own options, the ^Kd costs, the kd builder's SAH options).
OPTION_TREES = [
    ("room", "rbsp", {'k': 7}, 80648, "1f76fe10f2d69ac9d1311f47fefeffd9e85633b98f4e55ef6d97e310de1b702f"),
    ("room", "rbsp", {'k': 5, 'rbsp_set': 'spiral'}, 315112, "1ddbb54012df65de2f46dd82cf084e596fa6054f3fc07e73165d1c06119563d4"),
    ("fan", "rbsp+kd", {'k': 9, 'rbsp_set': 'dop'}, 49160, "11d2fcb7a4ed5ae58a9b1279a056a6879233c55dc603f1d30b91ca530fa35b6c"),
    ("fan", "rbsp", {'k': 11}, 80200, "60ef4d8695c1f5667a81d95edf9714d1ead8535f2cdb71bc3f99704fb9a55c01"),
    ("fan", "bsp_cn+", {'k': 8, 'cluster_sample': 64, 'cluster_iterations': 3, 'seed': 7}, 68168, "3c0fd3c61bf342b00e4dd9492bba625dc7795aa7521aeb666598356af0da2d3c"),
    ("fan", "bsp_ize", {'ize_candidates': 8, 'seed': 3}, 310376, "73eda683daaadb9dd2d87966bfcf1afd58dae9d9cf2fb0acc9af5b84ede3d750"),
    ("room", "bsp_random+kd", {'k': 5, 'alpha': 0.3, 'general_cost': 3.0, 'max_depth': 12}, 19992, "9e680fed6a8296544170cedde0a088e12d1474afa9f23edaad3b54dd5ebe2e51"),
    ("room", "kd", {'traversal_cost': 2.0, 'empty_bonus': 0.5, 'leaf_size': 4}, 16808, "ff14c61cfc1f219631ef969debe1727323aae8c4ab936b82ad1e773b109f1fba"),
]


@pytest.fixture(scope="module")
def generated():
    return {name: scenes.generate(name) for name in ("room", "fan")}


def digest(tree):
    data = tree.node_bytes()
    return len(data), hashlib.sha256(data).hexdigest()


def test_every_method_has_a_reference_tree():
    assert {m for _, m in DEFAULT_TREES} == set(METHODS)


@pytest.mark.parametrize("scene, method", sorted(DEFAULT_TREES))
def test_default_trees_are_unchanged(generated, scene, method):
    assert digest(bsplab.build(generated[scene], method)) == DEFAULT_TREES[scene, method]


@pytest.mark.parametrize("scene, method, options, size, sha", OPTION_TREES)
def test_trees_with_options_are_unchanged(generated, scene, method, options, size, sha):
    assert digest(bsplab.build(generated[scene], method, **options)) == (size, sha)


def test_methods_name_known_strategies_builders_and_options():
    assert set(STRATEGIES) >= {"axes", "fixed", "random", "normals", "clustered", "ize"}
    for m in METHODS.values():
        assert m.strategy in STRATEGIES, m.name
        assert m.builder in ("kd", "bsp"), m.name
        for name in m.params:
            assert name in OPTIONS, (m.name, name)
        for name in m.defaults:
            assert name in m.extra, (m.name, name)
    # Every strategy is used by some method: none is registered but unreachable.
    assert {m.strategy for m in METHODS.values()} == set(STRATEGIES)


def test_groups_split_the_options():
    assert list(OPTIONS) == list(COMMON_OPTIONS) + list(BSP_OPTIONS)
    used = {name for m in METHODS.values() for name in m.extra}
    assert used == set(BSP_OPTIONS)


def within(spec, value, low=None):
    low = spec["min"] if low is None else low
    if low is not None and (value < low or (spec["min_open"] and value == low)):
        return False
    return spec["max"] is None or value <= spec["max"]


@pytest.mark.parametrize("name", list(OPTIONS))
def test_schema_is_complete_and_its_default_is_valid(name):
    spec = OPTIONS[name]
    assert spec["label"] and spec["short_label"] and spec["help"]
    assert hasattr(_core.BuildOptions(), spec["field"])
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
])
def test_options_for_refuses_bad_names_and_types(values, words):
    with pytest.raises(ValueError, match=words):
        _core.options_for("bsp_wn", values)


def test_unknown_method_and_strategy_are_named():
    with pytest.raises(ValueError, match="unknown method octree; known: kd, rbsp"):
        _core.options_for("octree", {})
    o = _core.options_for("bsp_wn", {})
    o.strategy = "x_only"
    with pytest.raises(ValueError, match="unknown direction strategy x_only; known: axes, fixed"):
        _core.build(scenes.generate("cube"), "bsp", o, None)

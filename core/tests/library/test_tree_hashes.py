"""The trees of every method stay bit-identical across refactorings of the
builders: the sha256 of each tree's node and plane arrays and its SAH cost on
two generated scenes (and on `room` with clipped leaf boxes, whose leaves are
laid out differently), recorded on main before the cost model and the named
node kinds (core/src/builders/cost_model.hpp, Node in tree.hpp) replaced the inline
formulas and bare kind bits. A change that moves one plane or rounds one cost
differently changes a hash here.

A deliberate change of the trees (a new cost term, another tie rule) updates
tree_hashes.json: `python core/tests/library/test_tree_hashes.py` prints the new
"defaults" entries; say in the commit why the trees changed."""

import hashlib
import json
from pathlib import Path

import pytest

import bsplab
from bsplab import scenes

# Recorded trees (tree_hashes.json): "defaults" maps "scene/method[/option=value]"
# to the sha256 of node_bytes() and stats["sah_cost"]; "with_options" lists trees
# with options away from the defaults (rbsp_set's auto rule, the strategies' own
# options, the ^Kd costs, the kd builder's SAH options) by size and sha256,
# recorded on main before the direction strategies moved into core/src/strategies/.
# The fast build quality's trees (issue 25) come last: kd and the sweep with
# fast_min_gain 0 (binned big nodes, exact below), then three at the
# defaults (the minimum gain, kd's 1024 bins).
HASHES_FILE = Path(__file__).with_name("tree_hashes.json")
_RECORDED = json.loads(HASHES_FILE.read_text())
RECORDED = {k: (v["sha256"], v["sah_cost"]) for k, v in _RECORDED["defaults"].items()}
OPTION_TREES = [(t["scene"], t["method"], t["options"], t["bytes"], t["sha256"])
                for t in _RECORDED["with_options"]]

# The scenes and options each method is recorded on.
CASES = (("room", ""), ("fan", ""), ("room", "/leaf_boxes=clipped"))


def _case(key: str):
    scene, method, *extra = key.split("/")
    return scene, method, dict(e.split("=", 1) for e in extra)


def _measure(key: str):
    scene, method, options = _case(key)
    tree = bsplab.build(scenes.generate(scene), method, **options)
    return hashlib.sha256(tree.node_bytes()).hexdigest(), tree.stats["sah_cost"]


def test_every_method_is_recorded():
    # A new method gets a recorded tree too (run this file as a script).
    want = {f"{scene}/{m}{extra}" for scene, extra in CASES for m in bsplab.methods()}
    assert set(RECORDED) == want


@pytest.mark.parametrize("key", sorted(RECORDED))
def test_tree_is_bit_identical(key):
    digest, sah_cost = _measure(key)
    want_digest, want_cost = RECORDED[key]
    assert sah_cost == want_cost, f"{key}: SAH cost {sah_cost!r}, recorded {want_cost!r}"
    assert digest == want_digest, f"{key}: the tree's bytes changed (same SAH cost)"


@pytest.mark.parametrize("scene, method, options, size, sha", OPTION_TREES)
def test_tree_with_options_is_bit_identical(scene, method, options, size, sha):
    data = bsplab.build(scenes.generate(scene), method, **options).node_bytes()
    assert (len(data), hashlib.sha256(data).hexdigest()) == (size, sha)


if __name__ == "__main__":
    keys = [f"{scene}/{method}{extra}" for scene, extra in CASES for method in bsplab.methods()]
    measured = {key: dict(zip(("sha256", "sah_cost"), _measure(key))) for key in keys}
    print(json.dumps({"defaults": measured}, indent=1))

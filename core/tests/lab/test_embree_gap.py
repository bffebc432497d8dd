"""docs/verdict.md's section 8 (lab/embree_gap.py): the gap to Embree split
into structure (kd ÷ our BVH) and kernel (our BVH ÷ Embree). The figures are
computed from the times the record holds (a record made up here, with known
times), the traced record's counters are the trees' own, and the command
writes the section."""

import json
import math

import numpy as np
import pytest

from bsplab import build, scenes
from bsplab.lab import embree_gap, verdict, verdict_report


def _tree(seconds, steps=10.0, box_tests=0.0, tests=1.0, differs=0):
    return {"method": "?", "seconds": list(seconds), "steps": steps, "box_tests": box_tests,
            "tests": tests, "differs_from_kd": differs}


def _workload(embree, kd, wn, cn, bvh):
    return {"rays": 100, "embree_seconds": list(embree),
            "trees": {"kd": _tree(kd, steps=30.0, tests=2.0),
                      "bsp_wn+kd 8": _tree(wn), "bsp_cn+kd 8": _tree(cn),
                      "bvh": _tree(bvh, steps=20.0, box_tests=35.0, tests=2.5)}}


def _record(workloads):
    return {"started": "now", "rounds": 3, "width": 10, "height": 10, "minutes": 0.5,
            "command": "python -m bsplab verdict", "scenes": [
                {"scene": "made_up", "triangles": 12, "workloads": workloads}]}


# Three rounds; Embree 1 s, kd 3 s (a 3x gap), our BVH 2 s: per round the
# same ratios but for one slow round, which the median ignores.
MADE_UP = _workload(embree=[1.0, 1.0, 2.0], kd=[3.0, 3.0, 3.0], wn=[2.4, 2.4, 2.4],
                    cn=[2.6, 2.6, 2.6], bvh=[2.0, 2.0, 4.0])


def test_ratios_are_medians_of_the_rounds_given():
    assert embree_gap.ratio(MADE_UP, "kd", "embree") == 3.0   # rounds 3, 3, 1.5
    assert embree_gap.ratio(MADE_UP, "bvh", "embree") == 2.0  # 2, 2, 2
    assert embree_gap.ratio(MADE_UP, "kd", "bvh") == 1.5      # 1.5, 1.5, 0.75
    assert embree_gap.best_kd(MADE_UP) == "bsp_wn+kd 8"       # 2.4 s beats 2.6 s
    f = embree_gap.split(MADE_UP)
    assert f["best_bvh"] == pytest.approx(1.2)
    # log(kd ÷ BVH) / log(kd ÷ Embree): the structure's part of the gap.
    assert f["kd_structure"] == pytest.approx(math.log(1.5) / math.log(3.0))


def test_section_shows_the_figures_and_a_headline_computed_from_them():
    page = "\n".join(embree_gap.section(_record({"primary": MADE_UP}), 8))
    assert "## 8. The gap to Embree: structure or kernel" in page
    share = 100 * math.log(1.5) / math.log(3.0)  # 37 %: the kernel has the rest
    assert (f"| made_up | primary | 3.00 | 2.00 | 1.50 | bsp_wn+kd 8: 1.20 | {share:.0f} | "
            f"{100 - share:.0f} | 30.0 / 10.0 / 20.0 | 35.0 | 2.00 / 1.00 / 2.50 | 0 |") in page
    assert ("kd takes 3.00× Embree's time over 1 scene × 1 ray sets (medians); our BVH, on the "
            "same kernel, 2.00×, and kd 1.50× our BVH's (the best ^Kd tree 1.20×).") in page
    assert f"{share:.0f} % is the structure" in page and "mostly the kernel" in page


def test_headline_follows_the_figures():
    # The BVH as fast as Embree: the whole gap is the structure.
    same = _workload(embree=[1.0], kd=[2.0], wn=[1.5], cn=[1.6], bvh=[1.0])
    assert "100 % is the structure" in embree_gap.headline(_record({"primary": same})["scenes"])
    assert "mostly the structure" in embree_gap.headline(_record({"primary": same})["scenes"])
    # kd's planes faster than our BVH: none of the gap is the structure.
    planes = _workload(embree=[1.0], kd=[2.0], wn=[1.5], cn=[1.6], bvh=[3.0])
    text = embree_gap.headline(_record({"primary": planes})["scenes"])
    share = 100 * math.log(2.0 / 3.0) / math.log(2.0)
    assert f"{share:.0f} % is the structure" in text and "none of it is the structure" in text
    # kd faster than Embree: nothing to split, and the sentence says so.
    fast = _workload(embree=[2.0], kd=[1.0], wn=[1.5], cn=[1.6], bvh=[1.0])
    text = embree_gap.headline(_record({"primary": fast})["scenes"])
    assert "no gap to split" in text and "0.50× Embree" in text
    # A gap within the noise (kd 1.05× Embree) is not split either.
    small = _workload(embree=[1.0], kd=[1.05], wn=[1.5], cn=[1.6], bvh=[2.0])
    assert embree_gap.structure_share(small) is None


def test_section_says_when_it_was_not_traced():
    assert "Not traced" in "\n".join(embree_gap.section(None, 8))


@pytest.fixture(scope="module")
def room_gap():
    spec = embree_gap.gap_spec(["room"], verdict.SPECS / "results.toml", width=24, height=24)
    return embree_gap.trace_scene(spec, "room", rounds=2)


def test_traced_record_holds_the_trees_own_counters(room_gap):
    assert set(room_gap["workloads"]) == {"primary", "random"}
    tris = scenes.generate("room")
    for name, w in room_gap["workloads"].items():
        assert len(w["embree_seconds"]) == 2
        assert set(w["trees"]) == set(embree_gap.TREES)
        kd, bvh = w["trees"]["kd"], w["trees"]["bvh"]
        assert len(kd["seconds"]) == len(bvh["seconds"]) == 2
        # Box tests are the BVH's counter; a kd-tree makes none.
        assert kd["box_tests"] == 0 and bvh["box_tests"] > 0, name
        # Both answer every ray alike on room (no ties between distinct hits).
        assert bvh["differs_from_kd"] == 0, name
    tree = build(tris, method="bvh")
    spec = embree_gap.gap_spec(["room"], verdict.SPECS / "results.toml", width=24, height=24)
    from bsplab.lab.trials import load_scene, scene_references
    _, rays = scene_references(spec, "room", load_scene("room"))
    hits = tree.intersect(rays["random"].origins, rays["random"].directions)
    assert room_gap["workloads"]["random"]["trees"]["bvh"]["box_tests"] == pytest.approx(
        float(hits["box_tests"].mean()))
    assert room_gap["workloads"]["random"]["rays"] == 24 * 24


def test_command_writes_section_and_only_gap_retraces_it_alone(tmp_path):
    out = tmp_path / "verdict.md"
    assert verdict_report.main(out, ["room"], results=None, rounds=1, side=12) == 0
    data = tmp_path / "data" / "verdict.json"
    first = json.loads(data.read_text())
    assert [s["scene"] for s in first["gap"]["scenes"]] == ["room"]
    page = out.read_text()
    assert "## 8. The gap to Embree" in page and "% is the structure" in page
    assert embree_gap.headline(first["gap"]["scenes"]) in page
    # --only-gap: sections 1-4's record kept as it was, the gap traced anew.
    assert verdict_report.main(out, ["room"], rounds=2, side=8, only_gap=True) == 0
    second = json.loads(data.read_text())
    assert second["scenes"] == first["scenes"] and second["started"] == first["started"]
    assert second["gap"]["rounds"] == 2 and second["gap"]["width"] == 8
    assert np.isfinite(embree_gap.ratio(second["gap"]["scenes"][0]["workloads"]["primary"],
                                        "kd", "embree"))

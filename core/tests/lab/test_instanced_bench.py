"""The instanced benchmark (python -m bsplab bench-instanced) on a small world:
its rows, its page, and that the two-level and the flat tree hit the same rays."""

from __future__ import annotations

import numpy as np
import pytest

import bsplab
from bsplab import instanced_scenes
from bsplab.lab import instanced_bench

pytest.importorskip("embreex", reason="embreex is the reference")


def test_rows_and_page_of_a_small_world(monkeypatch):
    monkeypatch.setitem(instanced_scenes.WORLDS, "spheres50",
                        lambda: instanced_scenes.scatter([instanced_scenes.uv_sphere(8, 10)],
                                                         50, 20.0, 3))
    rows = instanced_bench.bench_instanced(["spheres50"], ["kd", "bvh"], side=32, rays=2000,
                                           rounds=2, log=lambda *_: None)
    assert [r["method"] for r in rows] == ["kd", "bvh"]
    for r in rows:
        assert r["instances"] == 50 and r["meshes"] == 1
        assert r["instanced_triangles"] == 50 * 160
        assert r["top_bytes_per_instance"] <= 200
        for work in ("primary", "random"):
            assert r[f"{work}_same_hit_mask"], work
            assert r[f"{work}_two_per_flat"] > 0 and r[f"{work}_two_per_embree"] > 0
            assert r[f"{work}_top_steps"] >= 1
        assert r["primary_instance_visits"] > 0
    page = instanced_bench.markdown(rows, "python -m bsplab bench-instanced --worlds spheres50")
    assert page.count("| spheres50 | kd |") == 3 and "## Random rays" in page


def test_limits_leave_out_the_flat_tree_and_embree(monkeypatch):
    monkeypatch.setitem(instanced_scenes.WORLDS, "cubes",
                        lambda: instanced_scenes.scatter([instanced_scenes.cube()], 30, 10.0))
    (row,) = instanced_bench.bench_instanced(["cubes"], ["bvh"], side=16, rays=500, rounds=1,
                                             flat_limit=10, embree_limit=10, log=lambda *_: None)
    assert row["flat_build_s"] is None and row["primary_two_per_flat"] is None
    assert row["primary_two_per_embree"] is None and row["primary_two_s"] > 0
    assert "—" in instanced_bench.markdown([row], "x")


def test_unknown_worlds_and_methods_are_named():
    with pytest.raises(ValueError, match="unknown world 'moon'"):
        instanced_bench.bench_instanced(["moon"])
    with pytest.raises(ValueError):
        instanced_bench.bench_instanced(["city"], ["kdd"])


def test_a_spec_traces_two_levels_and_checks_them_against_embree(monkeypatch):
    import sys

    from bsplab.lab import spec as specs
    trials = sys.modules["bsplab.lab.trials"]
    monkeypatch.setitem(instanced_scenes.WORLDS, "spheres50",
                        lambda: instanced_scenes.scatter([instanced_scenes.uv_sphere(8, 10)],
                                                         50, 20.0, 3))
    base = {"scenes": ["instanced:spheres50", "room"], "methods": ["kd", "bvh"],
            "workloads": ["primary", "random"], "width": 24, "height": 24,
            "random_rays": 1500, "repetitions": 1, "hits_only": True}
    two = specs.make_spec({**base, "instances": "two-level"})
    flat = specs.make_spec(base)
    assert two.fingerprint() != flat.fingerprint()
    assert flat.fingerprint() == specs.make_spec({**base, "instances": "flat"}).fingerprint()
    for spec in (two, flat):
        for trial in trials.trials(spec):
            for row in trials.run_trial(spec, trial):
                assert row["unexplained"] == 0, (spec.instances, trial.label(), row["workload"])
                assert row["hits_only_unexplained"] == 0
                assert row["hits"] > 0 and row["nodes"] > 0
    # Two levels over the flat room: one mesh, one identity instance, the
    # mesh's tree plus one top node.
    data = trials.load_scene("room")
    row = trials.run_trial(two, trials.Trial("room", "kd", None, 1))[0]
    assert row["nodes"] == bsplab.build(data.triangles, "kd").stats["nodes"] + 1


@pytest.mark.parametrize("data, message", [
    ({"instances": "both"}, "instances must be one of"),
    ({"instances": "two-level", "cull": True}, "culling is not offered"),
    ({"scenes": ["instanced:moon"]}, "unknown instanced world"),
])
def test_bad_instanced_specs_are_refused(data, message):
    from bsplab.lab import spec as specs
    with pytest.raises(specs.SpecError, match=message):
        specs.make_spec({"scenes": ["room"], **data})

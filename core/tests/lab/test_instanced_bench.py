"""The instanced benchmark (python -m bsplab bench-instanced) on a small world:
its rows, its page, and that the two-level and the flat tree hit the same rays."""

from __future__ import annotations

import numpy as np
import pytest

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

"""`python -m bsplab bench-build`: the kd build, exact and fast, against
Embree's, paired; and what the fast build costs in the tree."""

from __future__ import annotations

import pytest

import bsplab
from bsplab import scenes
from bsplab.__main__ import main
from bsplab.lab import build_bench

pytest.importorskip("embreex")


def test_rows_hold_paired_medians_and_the_trees_cost(monkeypatch):
    from bsplab import workloads
    monkeypatch.setattr(workloads, "shared_scenes_dir", lambda: None)  # no shared meshes here
    logged = []
    rows = build_bench.bench_build(["room", "bunny"], rounds=3, threads=2,
                                   log=logged.append)
    assert [r["scene"] for r in rows] == ["room"]
    assert any("skipped scene bunny" in line for line in logged), logged
    r = rows[0]
    assert r["triangles"] == len(scenes.load("room"))
    assert r["threads"] == 2 and r["rounds"] == 3
    for key in ("kd_1_s", "kd_n_s", "kd_fast_s", "embree_s", "kd_1_per_embree",
                "kd_n_per_embree", "kd_fast_per_embree", "bvh_s", "bvh_per_embree"):
        assert r[key] > 0, key
    # The SAH cost is the tree's, which the build decides alone.
    room = scenes.load("room")
    assert r["sah_cost"] == bsplab.build(room, "kd").stats["sah_cost"]
    assert r["kd_fast_sah_cost"] == bsplab.build(room, "kd", build_quality="fast").stats["sah_cost"]
    assert r["bvh_sah_cost"] == bsplab.build(room, "bvh").stats["sah_cost"]


def test_quality_rows_compare_each_quality_with_the_exact_tree():
    rows = build_bench.bench_build(["room"], rounds=2, threads=2, log=lambda _: None, side=24)
    quality = rows[0]["quality"]
    assert [(q["method"], q["quality"]) for q in quality] == [("kd", "exact"), ("kd", "fast")]
    exact, fast = quality
    room = scenes.load("room")
    tree = bsplab.build(room, "kd")
    assert exact["sah_cost"] == tree.stats["sah_cost"] and exact["sah_per_exact"] == 1.0
    assert fast["sah_per_exact"] == pytest.approx(fast["sah_cost"] / exact["sah_cost"])
    assert exact["bytes"] == tree.stats["bytes"]
    # The counting path's means on the same primary rays (24 x 24, tile order).
    from bsplab import workloads
    o, d = workloads.primary_rays(room, 24, 24, tiles=True)
    counted = tree.intersect(o, d)
    assert exact["primary_steps"] == pytest.approx(counted["steps"].mean())
    assert exact["primary_tests"] == pytest.approx(counted["tests"].mean())
    # A tree over itself is 1 in every round; the fast tree's ratio is measured.
    assert exact["primary_per_exact"] == 1.0 and exact["ao_per_exact"] == 1.0
    assert fast["primary_per_exact"] > 0 and fast["ao_per_exact"] > 0
    assert exact["ao_steps"] > 0 and exact["ao_tests"] > 0
    text = build_bench.build_markdown(rows, "cmd")
    assert "| room | kd | fast |" in text and "primary time / exact" in text
    # side 0: no quality table.
    rows = build_bench.bench_build(["room"], rounds=1, threads=1, log=lambda _: None, side=0)
    assert rows[0]["quality"] == []
    assert "primary time / exact" not in build_bench.build_markdown(rows, "cmd")


def test_markdown_has_a_row_per_scene():
    rows = [{"scene": s, "triangles": 1000, "threads": 2, "kd_1_s": 0.2, "kd_n_s": 0.1,
             "kd_fast_s": 0.03, "embree_s": 0.05, "kd_1_per_embree": 4.0, "kd_n_per_embree": 2.0,
             "kd_fast_per_embree": 0.6, "sah_cost": 12.5, "kd_fast_sah_cost": 12.75,
             "bvh_s": 0.04, "bvh_per_embree": 0.8, "bvh_sah_cost": 30.0,
             "rounds": 3} for s in ("a", "b")]
    text = build_bench.build_markdown(rows, "cmd")
    lines = [line for line in text.splitlines() if line.startswith("| ")]
    assert len(lines) == 3  # the header and one row per scene; no quality rows given
    assert ("| a | 1,000 | 0.050 s | 0.200 s | 0.100 s | 0.030 s | 4.00× | 2.00× | 0.60× | "
            "12.50 | 12.75 | 0.040 s | 0.80× |") in lines
    assert "Machine:" not in text
    # The host goes on the page when given: the ratios to Embree depend on it.
    machine = {"cpu": "Some CPU", "cores": 2, "isa": "avx512", "started": "2026-12-05 21:00:00",
               "load_start": [0.1, 0.2, 0.3], "load_end": [1.5, 1.0, 0.5]}
    text = build_bench.build_markdown(rows, "cmd", machine)
    line = next(x for x in text.splitlines() if x.startswith("Machine:"))
    assert "Some CPU, 2 cores, widest instruction set avx512" in line
    assert "started 2026-12-05 21:00:00" in line and "0.1 / 0.2 / 0.3 at the start" in line
    assert [x for x in text.splitlines() if x.startswith("| ")] == lines
    assert "kd fast / Embree" in lines[0]


def test_command_writes_the_table(tmp_path, capsys):
    out = tmp_path / "build.md"
    assert main(["bench-build", "--scenes", "room", "--repeats", "1", "--threads", "1",
                 "--out", str(out)]) == 0
    text = out.read_text()
    assert f"| room | {len(scenes.load('room')):,} |" in text
    assert "kd 1 / Embree" in text and "| room | kd | fast |" in text
    assert "| room |" in capsys.readouterr().out


def test_command_fails_when_no_scene_is_here(capsys, monkeypatch):
    from bsplab import workloads
    monkeypatch.setattr(workloads, "shared_scenes_dir", lambda: None)
    assert main(["bench-build", "--scenes", "bunny", "--repeats", "1"]) == 2
    assert capsys.readouterr().err == ("error: none of the scenes (bunny) is here (the shared "
                                       "scenes folder: not found); name generated scenes or "
                                       "mesh files with --scenes\n")


def test_sweeps_add_the_bsp_builds_over_kd(tmp_path):
    rows = build_bench.bench_build(["room"], rounds=1, threads=2, log=lambda _: None,
                                   sweeps=True)
    r = rows[0]
    for key in ("wn8", "ize", "wn8_fast", "ize_fast"):
        assert r[f"{key}_s"] > 0, key
        # The ratio is over the exact kd build on the same threads, in the same
        # round (one round: the median is that round's).
        assert r[f"{key}_per_kd"] == pytest.approx(r[f"{key}_s"] / r["kd_n_s"], rel=1e-9)
    assert [(q["method"], q["quality"]) for q in r["quality"]] == [
        (m, q) for m in ("kd", "bsp_wn+kd K=8", "bsp_ize+kd") for q in ("exact", "fast")]
    text = build_bench.build_markdown(rows, "cmd")
    assert "bsp_wn+kd K=8 exact | fast | exact / kd | fast / kd |" in text
    room_row = next(line for line in text.splitlines() if line.startswith("| room | 2"))
    assert f"{r['wn8_per_kd']:.2f}× | {r['wn8_fast_per_kd']:.2f}× |" in room_row
    out = tmp_path / "b.md"
    assert main(["bench-build", "--scenes", "room", "--repeats", "1", "--sweeps",
                 "--out", str(out)]) == 0
    assert "bsp_ize+kd" in out.read_text()

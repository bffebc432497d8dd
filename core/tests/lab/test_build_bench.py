"""`python -m bsplab bench-build`: the kd build against Embree's, paired."""

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
    for key in ("kd_1_s", "kd_n_s", "embree_s", "kd_1_per_embree", "kd_n_per_embree",
                "bvh_s", "bvh_per_embree"):
        assert r[key] > 0, key
    # The SAH cost is the tree's, which the build decides alone.
    assert r["sah_cost"] == bsplab.build(scenes.load("room"), "kd").stats["sah_cost"]
    assert r["bvh_sah_cost"] == bsplab.build(scenes.load("room"), "bvh").stats["sah_cost"]


def test_markdown_has_a_row_per_scene():
    rows = [{"scene": s, "triangles": 1000, "threads": 2, "kd_1_s": 0.2, "kd_n_s": 0.1,
             "embree_s": 0.05, "kd_1_per_embree": 4.0, "kd_n_per_embree": 2.0,
             "sah_cost": 12.5, "bvh_s": 0.04, "bvh_per_embree": 0.8, "bvh_sah_cost": 30.0,
             "rounds": 3} for s in ("a", "b")]
    text = build_bench.build_markdown(rows, "cmd")
    lines = [line for line in text.splitlines() if line.startswith("| ")]
    assert len(lines) == 3  # the header and one row per scene
    assert ("| a | 1,000 | 0.200 s | 0.100 s | 0.050 s | 4.00× | 2.00× | 12.50 | 0.040 s | "
            "0.80× | 30.00 |") in lines
    assert "kd 2 / Embree" in lines[0]


def test_command_writes_the_table(tmp_path, capsys):
    out = tmp_path / "build.md"
    assert main(["bench-build", "--scenes", "room", "--repeats", "1", "--threads", "1",
                 "--out", str(out)]) == 0
    text = out.read_text()
    assert f"| room | {len(scenes.load('room')):,} |" in text
    assert "kd 1 / Embree" in text
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
    for key in ("wn8", "ize"):
        assert r[f"{key}_s"] > 0, key
        # The ratio is over the kd build on the same threads, in the same round.
        assert r[f"{key}_per_kd"] == pytest.approx(r[f"{key}_s"] / r["kd_n_s"], rel=1e-9)
    text = build_bench.build_markdown(rows, "cmd")
    assert "bsp_wn+kd K=8, 2 | / kd 2 |" in text
    assert f"{r['wn8_per_kd']:.2f}× |" in text.splitlines()[-1]
    out = tmp_path / "b.md"
    assert main(["bench-build", "--scenes", "room", "--repeats", "1", "--sweeps",
                 "--out", str(out)]) == 0
    assert "bsp_ize+kd" in out.read_text()

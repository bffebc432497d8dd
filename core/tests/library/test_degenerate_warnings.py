"""A tree that degenerates says so in stats["warnings"] (issue 10, item 7),
in the demo's table and in the benchmark's report."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import bsplab
from bsplab import __main__ as cli
from bsplab import io, scenes

from test_memory_limit import soup

REPO_SCENES = Path(__file__).resolve().parents[3] / "scenes"


@pytest.mark.parametrize("name", ["room", "spheres"])
def test_normal_scenes_have_no_warning(name):
    tree = bsplab.build(io.load_mesh(REPO_SCENES / f"{name}.ply"), method="kd")
    assert tree.stats["warnings"] == []


def test_normal_bsp_tree_has_no_warning():
    assert bsplab.build(scenes.generate("room"), method="bsp_wn+kd").stats["warnings"] == []


def test_one_leaf_holding_everything():
    """Long needles across the whole scene with no duplication allowed: every
    split that would help duplicates, so everything ends in one leaf."""
    tris = soup(2_000)
    s = bsplab.build(tris, method="kd", max_duplication=1).stats
    assert s["max_leaf_size"] > 0.05 * len(tris)
    big = [w for w in s["warnings"] if "one leaf holds" in w]
    assert big, s["warnings"]
    assert big[0].startswith(f"degenerate tree: one leaf holds {s['max_leaf_size']} of the 2000 ")


def test_tiny_depth_with_many_triangles():
    tris = scenes.generate("spheres")
    s = bsplab.build(tris, max_depth=3).stats
    small = [w for w in s["warnings"] if "on average" in w]
    assert small, s["warnings"]
    assert f"depth 3 (limit 3) for {len(tris)} triangles" in small[0]


def test_sweep_builder_that_only_cuts_empty_space():
    """The case the issue found: on a needle soup bsp_wn+kd only trims empty
    space off the cell and keeps every triangle in one leaf."""
    tris = soup(12_000)
    s = bsplab.build(tris, method="bsp_wn+kd", max_depth=12).stats
    assert s["max_leaf_size"] == len(tris)
    assert len(s["warnings"]) == 2, s["warnings"]


def test_small_scenes_and_small_leaves_do_not_warn():
    # A leaf of 64 triangles is never flagged, however small the scene.
    tris = scenes.generate("room")[:64]
    s = bsplab.build(tris, leaf_size=64).stats
    assert s["max_leaf_size"] == 64 and s["warnings"] == []


def test_demo_table_shows_the_warning(tmp_path, capsys):
    tris = soup(2_000)
    # The demo builds with the defaults; a soup of needles through the whole
    # cube is degenerate with them too (one leaf far over 5% of the scene).
    s = bsplab.build(tris).stats
    assert s["warnings"], s
    path = tmp_path / "needles.ply"
    io.write_ply(path, tris.reshape(-1, 3), np.arange(3 * len(tris)).reshape(-1, 3))
    assert cli.main(["demo", "--scene", str(path), "--width", "32", "--height", "24",
                     "--out", str(tmp_path / "demo.png")]) == 0
    out = capsys.readouterr().out
    assert "WARNING" in out and "degenerate tree" in out


def test_bench_report_shows_the_warning():
    from bsplab.lab import ROW_FIELDS, report
    warning = "degenerate tree: one leaf holds 1000 of the 1000 triangles (100%)"
    rows = [{**{c: "1" for c in ROW_FIELDS}, "scene": "needles", "method": "kd", "k": "",
             "workload": w, "trace_s": "0.2 0.2", "kd_s": "0.2 0.2", "embree_s": "0.1 0.1",
             "level_planes": "1", "level_directions": "1", "unexplained": "0",
             "variant": "", "warnings": warning} for w in ("primary", "random")]
    md = report.benchmark_markdown(rows, "cmd")
    assert f"**Warning** (needles, kd): {warning}." in md

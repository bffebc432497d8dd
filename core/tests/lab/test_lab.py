"""The lab around the library: the one timing protocol, the benchmarks run as
specs through the runner (tiny, on the generated scenes), scene loading by
name, and the rule that the library never imports the lab."""

from __future__ import annotations

import ast
import hashlib
import json
import math
import re
import subprocess
import sys
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest

from bsplab import io, scenes
from bsplab.lab import SpecError, make_spec, paired_rounds, Tracer
from bsplab.lab.spec import LATER_KEYS

PACKAGE = Path(__file__).resolve().parents[2] / "bsplab"


# -----------------------------------------------------------------------------
# The timing protocol


def test_paired_rounds_rotate_the_order_and_pair_the_times():
    calls = []
    fake = {"ours": 3.0, "kd": 2.0, "embree": 1.0}

    def tracer(name):
        def run():
            calls.append(name)
            return name.upper()
        return Tracer(run, lambda: fake[name] * (1 + len(calls) / 100))

    times = paired_rounds({n: tracer(n) for n in fake}, 3)
    # Every tracer runs once per round, and each leads one round.
    assert calls == ["ours", "kd", "embree", "kd", "embree", "ours", "embree", "ours", "kd"]
    assert times.results == {"ours": "OURS", "kd": "KD", "embree": "EMBREE"}
    assert [len(s) for s in times.seconds.values()] == [3, 3, 3]
    # The ratios are per round, then the median: close to 3 / 1 with the drift.
    ratios = times.ratios("ours", "embree")
    assert len(ratios) == 3 and np.all((2.9 < ratios) & (ratios < 3.1))
    assert times.ratio("ours", "embree") == pytest.approx(float(np.median(ratios)))
    assert times.ratio("kd", "ours") < 1 < times.ratio("ours", "kd")
    assert times.median("embree") == pytest.approx(1.05)  # calls 3, 5, 7: 1.03, 1.05, 1.07


def test_paired_rounds_measure_wall_time_and_can_be_stopped(monkeypatch):
    # The protocol's clock, made to advance only while a tracer runs and by
    # a known amount: each round's time is exactly what its run took, not
    # whatever a loaded machine happened to take.
    from types import SimpleNamespace
    from bsplab.lab import timing
    clock = [100.0]
    monkeypatch.setattr(timing, "time", SimpleNamespace(perf_counter=lambda: clock[0]))
    took = iter([0.25, 0.5])

    def timed():
        clock[0] += next(took)

    times = paired_rounds({"a": Tracer(timed)}, 2)
    assert times.seconds["a"] == [0.25, 0.5]
    monkeypatch.undo()

    def busy():
        return sum(range(20000))

    stops = []

    def stop():
        stops.append(1)
        if len(stops) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        paired_rounds({"a": Tracer(busy)}, 5, between_rounds=stop)
    assert len(stops) == 2
    with pytest.raises(ValueError, match="rounds must be at least 1, got 0"):
        paired_rounds({"a": Tracer(busy)}, 0)
    with pytest.raises(ValueError, match="no tracers"):
        paired_rounds({}, 1)


def test_the_library_times_nothing_itself():
    """The old benchmarks' own timing loops are gone: perf_counter appears in
    the lab only in timing.py (the library's build/render report their own)."""
    lab_files = sorted((PACKAGE / "lab").glob("*.py"))
    timers = [p.name for p in lab_files if "perf_counter" in p.read_text()]
    assert timers == ["runner.py", "timing.py"]  # the runner times the whole run only
    for gone in ("bench.py", "bench_family.py", "bench_cull.py", "calibrate.py",
                 "experiment.py", "executors.py", "report.py", "results.py"):
        assert not (PACKAGE / gone).exists(), gone


# -----------------------------------------------------------------------------
# The library never imports the lab


def _imports_of(path: Path) -> list[str]:
    """Absolute names of the modules a source file imports (relative resolved)."""
    package = "bsplab" if path.parent.name == "bsplab" else f"bsplab.{path.parent.name}"
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package.rsplit(".", node.level - 1)[0] if node.level else ""
            module = ".".join(x for x in (base, node.module or "") if x)
            out.append(module)
            out += [f"{module}.{a.name}" for a in node.names]
    return out


def test_no_library_module_imports_the_lab():
    # The command line (__main__) fronts both the library and the lab.
    library = [p for p in sorted(PACKAGE.glob("*.py")) if p.name != "__main__.py"]
    assert len(library) > 10
    offenders = {p.name: [m for m in _imports_of(p) if m == "bsplab.lab"
                          or m.startswith("bsplab.lab.")] for p in library}
    assert {k: v for k, v in offenders.items() if v} == {}
    # And at run time: importing every library module loads no lab module.
    names = [f"bsplab.{p.stem}" for p in library if p.stem != "__init__"]
    code = (f"import importlib, sys\nfor n in {names!r}: importlib.import_module(n)\n"
            "print(sorted(m for m in sys.modules if m.startswith('bsplab.lab')))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"


def test_the_import_scan_sees_relative_imports(tmp_path):
    """The scan above would catch the ways a module can reach the lab."""
    fake = tmp_path / "bsplab" / "thing.py"
    fake.parent.mkdir()
    fake.write_text("from . import lab\nfrom .lab import report\nimport bsplab.lab.trials\n")
    assert {"bsplab.lab", "bsplab.lab.report", "bsplab.lab.trials"} <= set(_imports_of(fake))


# -----------------------------------------------------------------------------
# Scene loading by name (the library's, used by the runner and the commands)


def test_scenes_load_generated_files_and_refuse_unknown_names(tmp_path):
    tris, camera = scenes.load_with_camera("room")
    assert np.array_equal(tris, scenes.generate("room")) and camera is not None
    assert scenes.load_with_camera("cube")[1] is None  # probe scenes have no camera
    path = tmp_path / "fan.ply"
    io.write_ply(path, *scenes.generate_mesh("fan"))
    from_file, cam = scenes.load_with_camera(str(path))
    assert from_file.shape == scenes.generate("fan").shape and cam is None
    with pytest.raises(FileNotFoundError, match="no scene 'nowhere'"):
        scenes.load("nowhere")
    with pytest.raises(FileNotFoundError, match="no scene '.*missing.obj'"):
        scenes.load(str(tmp_path / "missing.obj"))
    with pytest.raises(ValueError, match="is a directory"):
        scenes.load(str(tmp_path))


# -----------------------------------------------------------------------------
# Spec keys the benchmarks brought


def test_older_specs_keep_their_fingerprint():
    """Results files written before variants/cull/random_rays still resume."""
    spec = make_spec({"scenes": ["room"], "methods": ["kd"]})
    d = asdict(spec)
    for k in ("executor", "workers", "scheduler", "name", "build_threads") + LATER_KEYS:
        d.pop(k)
    old = hashlib.sha1(json.dumps(d, sort_keys=True).encode()).hexdigest()[:12]
    assert spec.fingerprint() == old
    assert make_spec({"scenes": ["room"], "methods": ["kd"], "cull": True}).fingerprint() != old


@pytest.mark.parametrize("changes, message", [
    ({"variants": {}}, "variants: expected a non-empty list of option tables"),
    ({"variants": []}, "variants: expected a non-empty list"),
    ({"variants": [{"leaf_boxes": "round"}]}, "leaf_boxes"),
    ({"variants": [{"sparkle": 1}]}, "unknown build option"),
    ({"variants": [{}, {}]}, "variants: '' is listed twice"),
    ({"method_variants": {"kdd": [{}]}}, "method_variants: unknown method 'kdd'"),
    ({"cull": "yes"}, "cull must be true or false, got a string"),
    ({"hits_only": 1}, "hits_only must be true or false, got a number"),
    ({"random_rays": 0}, "random_rays must be an integer in 1..100000000"),
])
def test_bad_benchmark_keys_say_what_is_wrong(changes, message):
    with pytest.raises(SpecError, match=message):
        make_spec({"scenes": ["room"], "methods": ["kd", "bsp_wn+kd"], **changes})


def test_variants_make_trials_of_their_own():
    from bsplab.lab import trials
    spec = make_spec({"scenes": ["room"], "methods": ["kd", "bsp_wn+kd"], "ks": [4],
                      "variants": [{"leaf_boxes": "triangle"}, {"leaf_boxes": "clipped"}],
                      "method_variants": {"kd": [{}]}})
    got = [(c.method, c.variant) for c in trials(spec)]
    assert got == [("kd", ""), ("bsp_wn+kd", '{"leaf_boxes": "triangle"}'),
                   ("bsp_wn+kd", '{"leaf_boxes": "clipped"}')]
    assert len({c.key for c in trials(spec)}) == 3


# -----------------------------------------------------------------------------
# The benchmarks, tiny, through the runner

pytest.importorskip("embreex", reason="the benchmarks time Embree beside every trace")


def _table(md: str, heading: str) -> list[list[str]]:
    """The rows (cells stripped) of the first table after `heading`."""
    lines = md.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(heading))
    rows, seen = [], False
    for line in lines[start + 1:]:
        if line.startswith("|"):
            seen = True
            rows.append([c.strip() for c in line.strip("|").split("|")])
        elif seen:
            break
    return rows[2:]  # without the header and the rule


def _ratio(cell: str) -> float:
    value = float(cell.strip("*"))
    assert math.isfinite(value) and value > 0, cell
    return value


def _records(md: str, heading: str) -> list[dict[str, str]]:
    """The rows of the first table after `heading`, by column name."""
    lines = md.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(heading))
    header = next(line for line in lines[start + 1:] if line.startswith("|"))
    names = [c.strip() for c in header.strip("|").split("|")]
    return [dict(zip(names, r, strict=True)) for r in _table(md, heading)]


def _speed(cell: str) -> float:
    """A `× Embree speed` cell, `median (min–max)`: the median, checked to lie
    in its spread."""
    med, spread = cell.split(" (")
    lo, hi = spread.rstrip(")").split("–")
    assert _ratio(lo) <= _ratio(med) <= _ratio(hi), cell
    return _ratio(med)


def _csv_rows(path: Path) -> list[dict]:
    import csv
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_bench_writes_a_row_per_scene_and_method(tmp_path):
    from bsplab.lab import benchmarks
    out = tmp_path / "benchmark.md"
    assert benchmarks.bench(out, ["fan", "room"], ["kd", "bsp_wn+kd"], side=12, rays=300,
                            repeats=2) == 0
    md = out.read_text()
    assert "paired" in md and "median" in md  # the header says how times were taken
    data = _csv_rows(tmp_path / "data" / "benchmark.csv")
    assert len(data) == 2 * 2 * 2
    build = _records(md, "## Build")
    assert [(r["scene"], r["method"]) for r in build] == [
        ("fan", "kd"), ("fan", "bsp_wn+kd"), ("room", "kd"), ("room", "bsp_wn+kd")]
    for r in build:  # the tree's size per triangle, from its bytes
        row = next(d for d in data if (d["scene"], d["method"]) == (r["scene"], r["method"]))
        assert int(r["B/tri"]) == round(int(row["bytes"]) / int(row["triangles"]))
    for heading, workload, rays in (("## Primary rays", "primary", "144"),
                                    ("## Random rays", "random", "300")):
        rows = _records(md, heading)
        assert [(r["scene"], r["method"]) for r in rows] == [
            (r["scene"], r["method"]) for r in build]
        for r in rows:
            assert r["rays"] == rays and r["wrong hits"] == "0"
            for rate in ("Embree Mray/s", "hits-only Mray/s", "counters Mray/s"):
                _ratio(r[rate])
            assert r["hits-only × Embree speed"].startswith("**")  # the headline
            hits_only = _speed(r["hits-only × Embree speed"].replace("**", ""))
            _speed(r["counters × Embree speed"])
            # Embree's time over ours, round by round, then the median.
            row = next(d for d in data if (d["scene"], d["method"], d["workload"])
                       == (r["scene"], r["method"], workload))
            per_round = np.divide([float(x) for x in row["embree_s"].split()],
                                  [float(x) for x in row["hits_only_s"].split()])
            assert len(per_round) == 2 and hits_only == pytest.approx(
                float(np.median(per_round)), abs=0.006)
            assert row["hits_only_unexplained"] == "0"
            # Packets trace the primary rays only, with no wrong hit either.
            assert (row["packets_s"] != "") == (workload == "primary")
            if workload == "primary":
                assert row["packets_unexplained"] == "0"
                _ratio(r["packets Mray/s"])
                _speed(r["packets × Embree speed"])
        assert any("packets" in name for name in rows[0]) == (workload == "primary")


def _fake_packets(wrong: bool):
    """A packet path for the tests: the tree's hits-only path, its answers
    moved to other triangles when `wrong`."""
    from bsplab.lab import Tracer

    def factory(tree, rays, spec):
        def run():
            hits = tree.intersect(rays.origins, rays.directions, tmax=rays.tmax, threads=1,
                                  counters=False)
            if wrong:
                hits["prim"] = np.where(hits["prim"] >= 0, hits["prim"] ^ 1, -1)
                hits["t"] = hits["t"] * 2
            return hits
        return Tracer(run)
    return factory


@pytest.mark.parametrize("wrong", [False, True])
def test_a_packet_path_is_one_table_entry_and_its_hits_are_checked(tmp_path, monkeypatch,
                                                                   wrong):
    from bsplab.lab import benchmarks, tracers
    primary = {**tracers.HITS_ONLY_TRACERS["primary"], "packets": _fake_packets(wrong)}
    monkeypatch.setitem(tracers.HITS_ONLY_TRACERS, "primary", primary)
    out = tmp_path / "benchmark.md"
    code = benchmarks.bench(out, ["room"], ["kd", "bsp_cn+kd"], side=12, rays=100, repeats=2)
    assert code == (1 if wrong else 0)  # a path that disagrees with Embree fails the bench
    md = out.read_text()
    for r in _records(md, "## Primary rays"):
        _ratio(r["packets Mray/s"])
        _speed(r["packets × Embree speed"])
        assert (int(r["wrong hits"]) > 0) == wrong
    random = _records(md, "## Random rays")  # packets trace primary rays only
    assert not any("packets" in name for name in random[0])
    assert all(r["wrong hits"] == "0" for r in random)
    data = _csv_rows(tmp_path / "data" / "benchmark.csv")
    for row in data:
        traced = row["workload"] == "primary"
        assert (row["packets_s"] != "") == traced
        assert row["unexplained"] == row["hits_only_unexplained"] == "0"
        if traced:
            assert (int(row["packets_unexplained"]) > 0) == wrong


def test_every_hits_only_tracer_has_its_columns():
    from bsplab.lab import ROW_FIELDS, tracers
    from bsplab.lab.spec import WORKLOADS
    assert set(tracers.HITS_ONLY_TRACERS) == set(WORKLOADS)
    for per_workload in tracers.HITS_ONLY_TRACERS.values():
        for name in per_workload:
            assert name in tracers.HITS_ONLY_PATHS
            assert {f"{name}_s", f"{name}_unexplained"} <= set(ROW_FIELDS)


def test_the_shipped_bench_spec_times_kd_the_kd_node_trees_and_the_bvh_on_every_path():
    from bsplab.lab import benchmarks
    from bsplab.method_table import METHODS
    spec = benchmarks.benchmark_spec("bench", ["room"])
    assert spec.hits_only and spec.repetitions >= 5
    assert spec.methods[0] == "kd" and spec.methods[-1] == "bvh"
    # Between them, the ^Kd trees the side-by-side table picks the best of.
    assert spec.methods[1:-1] and all(METHODS[m].kd_nodes for m in spec.methods[1:-1])
    from bsplab.lab import report
    assert set(spec.methods[1:-1]) <= set(report.BEST_KD_METHODS)


def test_bench_page_sets_kd_the_best_kd_tree_and_the_bvh_side_by_side(tmp_path):
    from bsplab.lab import benchmarks, report
    from bsplab.lab.store import read_rows
    out = tmp_path / "benchmark.md"
    benchmarks.bench(out, ["room"], methods=["kd", "bsp_wn+kd", "bsp_cn+kd", "bvh"], side=12,
                     rays=300, repeats=2)
    rows = read_rows(tmp_path / "data" / "benchmark.csv")
    res = report.Results(rows)
    page = out.read_text()
    for w in ("primary", "random"):
        kd, bvh = res.kd("room", w), res.get("room", w, "bvh", None)
        heading = f"## {w.capitalize()} rays: kd, the best ^Kd and the BVH against Embree"
        assert heading in page
        # The row of this workload's table (other tables have room rows too,
        # and a ratio's digits may turn up in any of them).
        section = page.split(heading, 1)[1].split("\n## ", 1)[0]
        line = next(x for x in section.splitlines() if x.startswith("| room | 2,076 |"))
        # The row's kd ÷ BVH is the ratio of the rows' own paired times:
        # on random rays both trees' in the given order (one walk, no sort).
        path = "given_order_s" if w == "random" else "hits_only_s"
        assert bool(kd.rows[0]["given_order_s"]) == (w == "random")
        assert bool(bvh.rows[0]["given_order_s"]) == (w == "random")
        kd_bvh = (np.median(kd.per_round(path, "embree_s"))
                  / np.median(bvh.per_round(path, "embree_s")))
        assert f"| {kd_bvh:.2f} |" in line, (line, kd_bvh)
        if w == "random":  # kd in both orders, side by side
            given = np.median(kd.per_round("embree_s", "given_order_s"))
            spatial = np.median(kd.per_round("embree_s", "hits_only_s"))
            assert f"| {spatial:.2f} | {given:.2f} |" in line, (line, spatial, given)
        assert f"| {bvh.mean('box_tests'):.1f} |" in line
        assert kd.mean("box_tests") == 0 and bvh.mean("box_tests") > 0


def test_bench_family_has_every_method_and_k_against_kd(tmp_path):
    from bsplab.lab import benchmarks
    out = tmp_path / "bsp.md"
    assert benchmarks.bench_family(out, ["room"], ["bsp_wn+kd", "bsp_ize+kd"], ks=[4, 5],
                                   side=12, repeats=2) == 0
    md = out.read_text()
    for w in ("primary", "ao"):
        rows = _table(md, f"### room — {w} rays")
        assert [(r[0], r[1]) for r in rows] == [("kd", ""), ("bsp_wn+kd", "4"),
                                                ("bsp_wn+kd", "5"), ("bsp_ize+kd", "")]
        assert rows[0][2] == "100.0"  # kd against itself
        for r in rows:
            _ratio(r[2])   # time % kd
            _ratio(r[4])   # × Embree
            assert r[-1] == "0"
    with pytest.raises(ValueError, match="no K of \\[1, 2\\] fits bsp_wn\\+kd"):
        benchmarks.bench_family(None, ["room"], ["bsp_wn+kd"], ks=[1, 2])


def test_bench_cull_pairs_culling_on_with_off(tmp_path):
    from bsplab.lab import benchmarks
    spec = benchmarks.benchmark_spec("bench_cull", ["room"])
    assert spec.cull and len(spec.variants) == 2 and len(spec.method_variants["kd"]) == 4
    out = tmp_path / "cull.md"
    # The shipped spec's trials, on fewer rays: every method, both box kinds.
    # Three rounds: the median survives one preempted trace (these take 0.1 ms).
    assert benchmarks.bench_cull(out, ["room"], side=16, repeats=3) == 0
    rows = _table(out.read_text(), "# Benchmark")
    methods = {r[1] for r in rows}
    assert methods == set(spec.methods)
    assert len(rows) == 4 + 2 * (len(spec.methods) - 1)
    for r in rows:
        _ratio(r[7])                  # primary time on/off
        _ratio(r[10])                 # AO time on/off
        off, on = (float(x) for x in r[5].split("→"))
        assert on <= off              # culling only removes tests
        assert r[-1] == "0"           # and never changes an answer
    assert any(r[3] == "intersect_cost 0.3, leaf_boxes clipped" for r in rows)


def test_bench_command_line(tmp_path):
    out = tmp_path / "docs" / "benchmark.md"
    out.parent.mkdir()  # an --out's folder must exist; its data/ beside it is made
    r = subprocess.run([sys.executable, "-m", "bsplab", "bench", "--scenes", "room",
                        "--side", "8", "--rays", "64", "--repeats", "1", "--out", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    from bsplab.lab import benchmarks
    trees = len(benchmarks.benchmark_spec("bench", ["room"]).methods)
    assert f"{trees}/{trees} trials" in r.stderr  # the runner's progress bar
    assert "Command: `python -m bsplab bench --scenes room" in out.read_text()
    assert (tmp_path / "docs" / "data" / "benchmark.json").exists()

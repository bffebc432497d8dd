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

PACKAGE = Path(__file__).resolve().parents[1] / "bsplab"


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


def test_paired_rounds_measure_wall_time_and_can_be_stopped():
    def busy():
        return sum(range(20000))

    times = paired_rounds({"a": Tracer(busy)}, 2)
    assert all(0 < s < 5 for s in times.seconds["a"])
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
    fake.write_text("from . import lab\nfrom .lab import report\nimport bsplab.lab.cells\n")
    assert {"bsplab.lab", "bsplab.lab.report", "bsplab.lab.cells"} <= set(_imports_of(fake))


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
    ({"random_rays": 0}, "random_rays must be an integer in 1..100000000"),
])
def test_bad_benchmark_keys_say_what_is_wrong(changes, message):
    with pytest.raises(SpecError, match=message):
        make_spec({"scenes": ["room"], "methods": ["kd", "bsp_wn+kd"], **changes})


def test_variants_make_cells_of_their_own():
    from bsplab.lab import cells
    spec = make_spec({"scenes": ["room"], "methods": ["kd", "bsp_wn+kd"], "ks": [4],
                      "variants": [{"leaf_boxes": "triangle"}, {"leaf_boxes": "clipped"}],
                      "method_variants": {"kd": [{}]}})
    got = [(c.method, c.variant) for c in cells(spec)]
    assert got == [("kd", ""), ("bsp_wn+kd", '{"leaf_boxes": "triangle"}'),
                   ("bsp_wn+kd", '{"leaf_boxes": "clipped"}')]
    assert len({c.key for c in cells(spec)}) == 3


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


def test_bench_writes_a_row_per_scene_and_method(tmp_path):
    from bsplab.lab import benchmarks
    out = tmp_path / "benchmark.md"
    assert benchmarks.bench(out, ["fan", "room"], ["kd", "bsp_wn+kd"], side=12, rays=300,
                            repeats=2) == 0
    md = out.read_text()
    assert "paired" in md and "median" in md  # the header says how times were taken
    build = _table(md, "## Build")
    assert [(r[0], r[2]) for r in build] == [("fan", "kd"), ("fan", "bsp_wn+kd"),
                                             ("room", "kd"), ("room", "bsp_wn+kd")]
    for heading, rays in (("## Primary rays", "144"), ("## Random rays", "300")):
        rows = _table(md, heading)
        assert [(r[0], r[1]) for r in rows] == [(r[0], r[2]) for r in build]
        for r in rows:
            assert r[3] == rays
            _ratio(r[4])                   # × Embree
            lo, hi = r[5].split("–")       # its spread over the rounds
            assert _ratio(lo) <= _ratio(r[4].strip("*")) <= _ratio(hi)
            assert r[10] == "0"            # wrong hits
    data = tmp_path / "data" / "benchmark.csv"
    assert data.exists() and len(data.read_text().splitlines()) == 1 + 2 * 2 * 2


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
    # The shipped spec's cells, on fewer rays: every method, both box kinds.
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


def test_calibration_recovers_known_costs_through_the_kd_pairing():
    from bsplab.lab.benchmarks import fit_costs
    rng = np.random.default_rng(3)
    rows = []
    for i in range(12):
        kd, gen, tests = rng.uniform(5, 40), rng.uniform(0, 10), rng.uniform(1, 20)
        per_ray = (100 + 2 * kd + 5 * gen + 20 * tests) * 1e-9
        drift = rng.uniform(0.5, 2.0, 3)  # the machine's speed in each round
        rows.append({"scene": "s", "workload": "w", "rays": "1000",
                     "steps": str(kd + gen), "general_steps": str(gen), "tests": str(tests),
                     "trace_s": " ".join(str(per_ray * 1000 * d) for d in drift),
                     "kd_s": " ".join(str(0.01 * d) for d in drift)})
    fit = fit_costs(rows)
    # The drift cancels in the pairing; what is left is exact up to one scale
    # (the kd-tree's median time), which the ratios do not see.
    assert fit["intersect_per_kd"] == pytest.approx(10.0)
    assert fit["general_per_kd"] == pytest.approx(2.5)
    assert fit["r2"] == pytest.approx(1.0)
    with pytest.raises(ValueError, match="at least 4 rows"):
        fit_costs(rows[:3])


def test_calibrate_fits_costs_from_the_runner(tmp_path):
    r = subprocess.run([sys.executable, "-m", "bsplab", "calibrate", "--scenes", "room",
                        "--repeats", "1"], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    fit = dict(re.findall(r"^\s+(\w+)\s+(\S+)$", r.stdout, re.M))
    assert set(fit) >= {"ns_per_ray", "intersect_per_kd", "general_per_kd", "r2", "samples"}
    assert int(fit["samples"]) == 2 * 7  # 7 trees x 2 workloads
    assert math.isfinite(float(fit["intersect_per_kd"]))
    assert (tmp_path / "out" / "bench" / "calibrate.csv").exists()


def test_bench_command_line(tmp_path):
    out = tmp_path / "docs" / "benchmark.md"
    r = subprocess.run([sys.executable, "-m", "bsplab", "bench", "--scenes", "room",
                        "--side", "8", "--rays", "64", "--repeats", "1", "--out", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "1/1 cells" in r.stderr  # the runner's progress bar
    assert "Command: `python -m bsplab bench --scenes room" in out.read_text()
    assert (tmp_path / "docs" / "data" / "benchmark.json").exists()

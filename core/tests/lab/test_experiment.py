"""The experiment runner on the tiny generated room: rows, resume, executors,
reports, bad specs. Timings are not checked (they are noise at this size);
counters and row bookkeeping are."""

from __future__ import annotations

import csv
import json
import subprocess
import sys

import pytest

from bsplab import lab
from bsplab.lab import SpecError, executors, plots, report

pytest.importorskip("embreex", reason="the runner times Embree beside every trace")

TINY = {
    "name": "tiny",
    "scenes": ["room"],
    "methods": ["kd", "bsp_wn+kd", "bsp_ize+kd"],
    "ks": [3, 5],
    "seeds": [1, 2],
    "repetitions": 2,
    "workloads": ["primary", "ao"],
    "width": 24,
    "height": 16,
    "executor": "inline",
}
# kd: 1 trial; bsp_wn+kd: 2 K x 2 seeds; bsp_ize+kd: no K, 2 seeds.
TINY_TRIALS = 1 + 4 + 2


class SpyExecutor(executors.InlineExecutor):
    """Inline, recording the trials it runs; can stop after `stop_after` trials."""

    def __init__(self, stop_after=None):
        super().__init__(lab.run_trial)
        self.ran, self.stop_after = [], stop_after

    def map(self, spec, todo, scene_data=None, progress=None):
        for trial, rows in super().map(spec, todo, scene_data, progress):
            if self.stop_after is not None and len(self.ran) == self.stop_after:
                raise KeyboardInterrupt
            self.ran.append(trial)
            yield trial, rows


def spec(**changes):
    return lab.make_spec({**TINY, **changes})


def read_csv(path):
    with open(path.with_suffix(".csv"), newline="") as f:
        return list(csv.DictReader(f))


def test_rows_cover_every_trial_and_workload(tmp_path):
    rows = lab.run(spec(), tmp_path / "r", quiet=True)
    assert len(rows) == TINY_TRIALS * 2
    on_disk = read_csv(tmp_path / "r")
    assert len(on_disk) == len(rows)
    keys = {(r["method"], r["k"], r["seed"], r["workload"]) for r in on_disk}
    assert ("kd", "", "1", "primary") in keys and ("kd", "", "2", "ao") not in keys
    assert ("bsp_wn+kd", "5", "2", "ao") in keys and ("bsp_ize+kd", "", "2", "primary") in keys
    for r in on_disk:
        assert r["unexplained"] == "0", r  # every tree agrees with Embree
        assert len(r["trace_s"].split()) == 2 and len(r["embree_s"].split()) == 2
        assert int(r["rays"]) == (24 * 16 if r["workload"] == "primary" else int(r["rays"]))
        assert float(r["steps"]) > 0 and int(r["hits"]) > 0
    kd = next(r for r in on_disk if r["method"] == "kd")
    assert kd["general_nodes"] == "0" and int(kd["kd_nodes"]) > 0
    # K = 3 with the axes is a kd-tree: no general nodes.
    wn3 = next(r for r in on_disk if r["method"] == "bsp_wn+kd" and r["k"] == "3")
    assert wn3["general_nodes"] == "0"
    meta = json.loads((tmp_path / "r.json").read_text())
    assert meta["spec"]["methods"] == TINY["methods"]
    assert meta["runs"][-1]["machine"]["cores"] >= 1
    assert meta["runs"][-1]["machine"]["versions"]["embreex"]
    assert meta["runs"][-1]["cells_after"] == TINY_TRIALS


def test_resume_runs_only_the_missing_trials(tmp_path):
    first = SpyExecutor(stop_after=3)
    with pytest.raises(KeyboardInterrupt):
        lab.run(spec(), tmp_path / "r", executor=first, quiet=True)
    assert len(read_csv(tmp_path / "r")) == 3 * 2
    second = SpyExecutor()
    rows = lab.run(spec(), tmp_path / "r", executor=second, quiet=True)
    assert len(second.ran) == TINY_TRIALS - 3
    assert not {c.key for c in first.ran} & {c.key for c in second.ran}
    assert len(rows) == len(read_csv(tmp_path / "r")) == TINY_TRIALS * 2
    third = SpyExecutor()
    lab.run(spec(), tmp_path / "r", executor=third, quiet=True)
    assert third.ran == []  # nothing left to do
    meta = json.loads((tmp_path / "r.json").read_text())
    assert [r["cells_before"] for r in meta["runs"]] == [0, 3, TINY_TRIALS]


def test_a_cut_last_line_is_run_again(tmp_path):
    lab.run(spec(), tmp_path / "r", quiet=True)
    path = (tmp_path / "r").with_suffix(".csv")
    lines = path.read_text().splitlines()
    path.write_text("\n".join(lines[:-1] + [lines[-1][:20]]) + "\n")  # killed mid-write
    spy = SpyExecutor()
    lab.run(spec(), tmp_path / "r", executor=spy, quiet=True)
    assert len(spy.ran) == 1
    assert len(read_csv(tmp_path / "r")) == TINY_TRIALS * 2


def test_another_spec_does_not_resume_into_old_results(tmp_path):
    lab.run(spec(methods=["kd"]), tmp_path / "r", quiet=True)
    with pytest.raises(SpecError, match="different spec"):
        lab.run(spec(methods=["kd"], width=30), tmp_path / "r", quiet=True)
    rows = lab.run(spec(methods=["kd"], width=30), tmp_path / "r", fresh=True, quiet=True)
    assert {r["rays"] for r in rows if r["workload"] == "primary"} == {str(30 * 16)}


def test_process_pool_and_dask_give_the_same_counters(tmp_path):
    small = dict(methods=["kd", "bsp_cn+kd"], ks=[4], seeds=[1], workloads=["ao"])
    inline = lab.run(spec(**small), tmp_path / "inline", quiet=True)
    pool = lab.run(spec(executor="process", workers=2, **small), tmp_path / "pool",
                          quiet=True)
    pytest.importorskip("distributed", reason="dask distributed is in the test dependencies")
    dask = lab.run(spec(executor="dask", workers=2, **small), tmp_path / "dask",
                          quiet=True)

    def counters(rows):
        return sorted((r["method"], str(r["k"]), str(r["steps"]), str(r["tests"]),
                       str(r["nodes"])) for r in rows)

    assert len(inline) == 2
    assert counters(inline) == counters(pool) == counters(dask)


def test_report_renders_tables_and_plots(tmp_path):
    rows = lab.run(spec(), tmp_path / "r", quiet=True)
    rows = read_csv(tmp_path / "r")
    pngs = plots.plots(rows, tmp_path / "plots")
    names = {p.name for p in pngs}
    assert {"time_primary.png", "tests_ao.png", "steps_primary.png", "build.png",
            "levels_directions.png", "levels_planes.png"} <= names
    for p in pngs:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 5000
    md = report.markdown(rows, "Tiny", json.loads((tmp_path / "r.json").read_text()), pngs,
                         relative_to=tmp_path)
    assert "#### BSP wn+ ^Kd (`bsp_wn+kd`): render time as % of kd, primary rays" in md
    assert "| K | room min | room med | room max |" in md
    assert "| 3 | " in md and "| 5 | " in md  # the K rows
    assert "room Kd | room BSP | room total" in md  # table 5.10 shape
    assert "![time_primary](plots/time_primary.png)" in md
    kd_row = next(line for line in md.splitlines() if line.startswith("| kd |  | 100.0"))
    assert kd_row.endswith("| 0 |")  # no wrong hits


@pytest.mark.parametrize("changes, message", [
    ({"methods": ["kd", "bsp_magic"]}, "unknown method 'bsp_magic'"),
    ({"methods": ["bsp_wn+"], "ks": [2]}, r"K = 2 is out of range for bsp_wn\+"),
    ({"methods": ["rbsp"], "ks": [65]}, "K = 65 is out of range for rbsp"),
    ({"methods": ["bsp_cn"], "method_ks": {"bsp_cn": [0]}}, "K = 0 is out of range"),
    ({"scenes": ["no/such/file.ply"]}, "scene file no/such/file.ply does not exist"),
    ({"scenes": ["not_a_scene"]}, "no scene 'not_a_scene'"),
    ({"scenes": []}, "at least one scene"),
    ({"workloads": ["shadow"]}, "workloads"),
    ({"repetitions": 0}, "repetitions must be an integer in 1..1000"),
    ({"width": 1.5}, "width must be an integer"),
    ({"ks": "3..x"}, "ks: expected"),
    ({"colour": "red"}, "unknown spec key"),
    ({"executor": "cloud"}, "executor must be one of"),
    ({"options": {"alpha": -1}}, "alpha"),
    ({"options": {"sparkle": 1}}, "unknown build option"),
    ({"ks": "10..3"}, r"ks: empty range '10..3' \(the first number must not exceed the last\)"),
    ({"seeds": "5..1"}, "seeds: empty range '5..1'"),
    ({"method_ks": {"bsp_wn+kd": "9..4"}}, r"method_ks.bsp_wn\+kd: empty range '9..4'"),
    ({"seeds": "1..100000000000"}, "seeds: range '1..100000000000' has 100000000000 values, "
                                   "more than the 10000 allowed"),
    ({"seeds": [2**63]}, "seeds must be in 0..9223372036854775807"),
    ({"ks": [3, 5, 3]}, "ks: 3 is listed twice"),
    ({"methods": ["kd", "kd"]}, "methods: 'kd' is listed twice"),
    ({"scenes": ["room", "room"]}, "scenes: 'room' is listed twice"),
    ({"workloads": ["ao", "ao"]}, "workloads: 'ao' is listed twice"),
    ({"methods": {"kd": 1}}, "methods: give a list of method names"),
    ({"name": 3}, "name must be a string, got a number 3"),
    ({"name": "../up"}, "name must be a plain file name"),
    ({"scheduler": ["tcp://x"]}, "scheduler must be a string, got a list"),
    ({"executor": ["inline"]}, "executor must be one of"),
])
def test_bad_specs_say_what_is_wrong(changes, message):
    with pytest.raises(SpecError, match=message):
        lab.make_spec({**TINY, **changes})


@pytest.mark.parametrize("data, kind", [([TINY], "a list"), ("tiny", "a string"),
                                        (3, "a number"), (None, "null")])
def test_a_spec_must_be_a_table(tmp_path, data, kind):
    with pytest.raises(SpecError, match=f"a spec must be a table .* got {kind}$"):
        lab.make_spec(data)
    path = tmp_path / "list.json"
    path.write_text(json.dumps(data))
    with pytest.raises(SpecError, match=f"^{path}: a spec must be a JSON object of settings "
                                        rf".*, got {kind}$"):
        lab.load_spec(path)


def test_spec_file_errors_name_the_file(tmp_path):
    with pytest.raises(SpecError, match=f"spec file {tmp_path} is a directory"):
        lab.load_spec(tmp_path)
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe\x00bad")
    with pytest.raises(SpecError, match=rf"^{binary}: not a text \(UTF-8\) file: byte 0 is "):
        lab.load_spec(binary)
    empty = tmp_path / "empty.toml"
    empty.write_text('scenes = ["room"]\nmethods = ["rbsp"]\nks = "10..3"\n')
    with pytest.raises(SpecError, match=f"^{empty}: ks: empty range '10..3'"):
        lab.load_spec(empty)
    with pytest.raises(SpecError, match=f"^{empty} with --workers: ks: empty range"):
        lab.load_spec(empty, workers=2)  # the command line's keys are named too
    (tmp_path / "scene.ply").mkdir()
    with pytest.raises(SpecError, match="scene file .*scene.ply is a directory"):
        lab.make_spec({**TINY, "scenes": [str(tmp_path / "scene.ply")]})


def _report_cli(*argv):
    r = subprocess.run([sys.executable, "-m", "bsplab", "report", *map(str, argv)],
                       capture_output=True, text=True)
    assert "Traceback" not in r.stderr and r.stderr.count("\n") == 1, r.stderr
    return r.returncode, r.stderr


def test_report_refuses_files_that_are_not_experiment_results(tmp_path):
    foreign = tmp_path / "foreign.csv"
    foreign.write_text("name,value\na,1\n")
    with pytest.raises(ValueError, match=f"^{foreign}: not the results of `python -m bsplab "
                                         "experiment`: missing column\\(s\\) scene, "
                                         "workload, method, k,"):
        lab.read_rows(foreign)
    code, err = _report_cli(foreign, "--out", tmp_path / "r.md")
    assert code == 2 and err.startswith(f"error: {foreign}: not the results of")
    assert "missing column(s) scene" in err
    # The right columns with a value that is not a number: the line is named.
    good = lab.ROW_FIELDS
    row = {c: "1" for c in good} | {"scene": "room", "workload": "primary", "method": "kd",
                                    "k": "", "trace_s": "0.1 0.2", "embree_s": "x"}
    bad = tmp_path / "bad.csv"
    with open(bad, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=good)
        w.writeheader()
        w.writerow(row)
    with pytest.raises(ValueError, match=f"^{bad}: line 2: column embree_s has 'x', expected "
                                         "numbers separated by spaces, or nothing$"):
        lab.read_rows(bad)
    header_only = tmp_path / "header.csv"
    header_only.write_text(",".join(good) + "\n")
    with pytest.raises(ValueError, match="no result rows"):
        lab.read_rows(header_only)
    with pytest.raises(FileNotFoundError, match="no results file .*missing.csv"):
        lab.read_rows(tmp_path / "missing.csv")
    code, err = _report_cli(tmp_path / "missing.csv", "--out", tmp_path / "r.md")
    assert code == 2 and err == f"error: no results file {tmp_path / 'missing.csv'}\n"


def test_spec_files_and_the_command_line(tmp_path):
    good = tmp_path / "good.toml"
    good.write_text('name = "cli"\nscenes = ["room"]\nmethods = ["kd"]\nrepetitions = 1\n'
                    'width = 8\nheight = 8\nworkloads = ["primary"]\nexecutor = "inline"\n')
    out = tmp_path / "res"
    r = subprocess.run([sys.executable, "-m", "bsplab", "experiment", str(good), "--out",
                        str(out), "--report", str(tmp_path / "rep.md")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert len(read_csv(out)) == 1 and (tmp_path / "rep.md").exists()
    assert "1/1 trials" in r.stderr  # the progress bar
    bad = tmp_path / "bad.toml"
    bad.write_text('scenes = ["room"]\nmethods = ["bsp_wn+kd"]\nks = "1..4"\n')
    r = subprocess.run([sys.executable, "-m", "bsplab", "experiment", str(bad)],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "K = 1 is out of range for bsp_wn+kd" in r.stderr
    assert "Traceback" not in r.stderr
    broken = tmp_path / "broken.toml"
    broken.write_text("scenes = [room\n")
    r = subprocess.run([sys.executable, "-m", "bsplab", "experiment", str(broken)],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "not valid TOML" in r.stderr
    r = subprocess.run([sys.executable, "-m", "bsplab", "experiment", str(tmp_path / "no.toml")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "does not exist" in r.stderr
    # Scene files are relative to the spec file.
    rel = tmp_path / "rel.json"
    rel.write_text(json.dumps({"scenes": ["meshes/missing.ply"], "methods": ["kd"]}))
    with pytest.raises(SpecError, match="meshes/missing.ply does not exist"):
        lab.load_spec(rel)


def test_results_quick_regenerates_its_page(tmp_path):
    from bsplab.lab import results
    assert results.main(quick=True, out=tmp_path / "results.md") == 0
    md = (tmp_path / "results.md").read_text()
    assert "# Results: the BSP family against kd and Embree (quick)" in md
    assert "#### room — primary rays" in md and "#### spheres — ao rays" in md
    assert (tmp_path / "results_quick_plots" / "time_ao.png").exists()
    assert len(read_csv(tmp_path / "data" / "results_quick")) == 2 * 2 * (1 + 2 + 3 + 3 + 1)


def test_thesis_comparison_lines_up_methods_and_scenes():
    from bsplab.lab import results
    rows = []
    for method, k, t in (("kd", "", "2"), ("bsp_wn+kd", "6", "1.5")):
        for w in ("primary", "ao"):
            rows.append({"scene": "sponza_dabrovic", "triangles": "10", "method": method,
                         "k": k, "seed": "1", "workload": w, "rays": "4", "trace_s": t,
                         "embree_s": "1", "build_s": "1", "steps": "1", "tests": "1",
                         "kd_nodes": "1", "general_nodes": "0", "bytes": "1",
                         "unexplained": "0", "level_directions": "1", "level_planes": "1"})
    lines = results.thesis_comparison(rows)
    row = next(line for line in lines if line.startswith("| bsp_wn+kd | 6 |"))
    # thesis Sponza K=6: 80.364; ours 1.5 / 2 = 75 %.
    assert row == "| bsp_wn+kd | 6 | 80 | 75 | 75 |"


def test_a_spec_sweeps_the_build_quality(tmp_path):
    # build_quality is a build option like any: variants make a trial of each,
    # and each trial's tree is the one bsplab.build makes with that option
    # (fast_min_refs low, so that the room's top nodes are binned).
    import bsplab
    from bsplab import scenes
    qualities = [{"build_quality": "exact"}, {"build_quality": "fast"}]
    rows = lab.run(spec(methods=["kd", "bsp_wn+kd"], ks=[4], seeds=[1], workloads=["primary"],
                        options={"fast_min_refs": 64},
                        method_variants={"kd": qualities, "bsp_wn+kd": qualities}),
                   tmp_path / "q", quiet=True)
    got = {(r["method"], r["variant"]): r for r in rows}
    assert len(got) == 4
    room = scenes.generate("room")
    for (method, variant), r in got.items():
        quality = json.loads(variant)["build_quality"]
        options = {"k": 4} if method != "kd" else {}
        tree = bsplab.build(room, method, fast_min_refs=64, build_quality=quality, **options)
        # The rows as the results file keeps them: text.
        assert float(r["sah"]) == tree.stats["sah_cost"], (method, quality)
        assert int(r["nodes"]) == tree.stats["nodes"]
        assert str(r["unexplained"]) == "0"  # fast trees agree with Embree too

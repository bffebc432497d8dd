"""The run's record says how loaded the machine was (store.load_average at a
run's start and finish) and the reports say it; bsp_benchmark's scope line is
generated from its rows."""

import json

from bsplab.lab import report
from bsplab.lab.runner import run
from bsplab.lab.spec import load_spec
from bsplab.lab.results import SPECS


def test_a_run_records_its_load_and_the_report_names_it(tmp_path):
    spec = load_spec(SPECS / "results_quick.toml", scenes=["cube"], methods=["kd", "bsp_wn+kd"],
                     ks=[4], width=8, height=8, repetitions=1, workloads=["primary"])
    rows = run(spec, tmp_path / "r", fresh=True, quiet=True)
    meta = json.loads((tmp_path / "r.json").read_text())
    last = meta["runs"][-1]
    assert len(last["load_start"]) == 3 and len(last["load_end"]) == 3
    line = report.machine_lines(meta)[0]
    assert "load average (1/5/15 min)" in line and f"on {last['machine']['cores']} cores" in line
    scope = report.scope_lines(report.Results(rows))[0]
    assert scope.startswith("Scope: cube; K = 4; 2 methods.")


def test_load_sentence_flags_a_shared_machine_and_skips_a_rerender():
    measuring = {"started": "t0", "seconds": 600, "cells_before": 0, "cells_after": 5,
                 "load_start": [3.5, 2.0, 1.0], "load_end": [1.0, 1.0, 1.0], "machine": {}}
    rerender = {"started": "t1", "seconds": 0.1, "cells_before": 5, "cells_after": 5,
                "load_start": [0.1, 0.1, 0.1], "load_end": [0.1, 0.1, 0.1], "machine": {}}
    s = report.load_sentence(measuring, 2)
    assert "took 10 minutes" in s and "3.5 / 2.0 / 1.0 at the start" in s
    assert "other jobs shared the machine" in s
    assert "shared" not in report.load_sentence({**measuring, "load_start": [1.5, 1, 1]}, 2)
    assert report.load_sentence({"started": "t"}, 2) == ""  # older records: no load
    line = report.machine_lines({"runs": [measuring, rerender]})[0]
    assert "3.5 / 2.0 / 1.0" in line  # the run that measured, not the re-render

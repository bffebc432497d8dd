"""The lab around the library: experiment specs, the runner and its results
store, the one timing protocol, the reports, and the benchmarks as specs.

The library (`bsplab` outside this package) never imports the lab: the lab
is one user of the library among others (the add-on, scripts)."""

from .trials import Trial, SceneData, trials, load_scene, run_trial
from .runner import run
from .spec import Spec, SpecError, load_spec, make_spec
from .store import ROW_FIELDS, ResultsFile, read_rows
from .k_sweep import sweep_k, sweep_table
from .timing import PairedTimes, Tracer, paired_rounds

__all__ = ["Trial", "PairedTimes", "ROW_FIELDS", "ResultsFile", "SceneData", "Spec", "SpecError",
           "Tracer", "trials", "load_scene", "load_spec", "make_spec", "paired_rounds",
           "read_rows", "run", "run_trial", "sweep_k", "sweep_table"]

"""The results store: rows in `<out>.csv` as trials finish, and beside them
`<out>.json` recording the spec, its fingerprint and every (re)start of the
run with the machine and the versions. A rerun with the same spec resumes:
the trials already there are skipped."""

from __future__ import annotations

import csv
import json
import os
import platform
import sys
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from .trials import Trial
from .spec import Spec, SpecError
from .tracers import HITS_ONLY_PATHS

ROW_FIELDS = [
    "scene", "triangles", "method", "k", "seed", "workload", "rays",
    "build_s", "nodes", "kd_nodes", "general_nodes", "leaves", "refs_per_tri", "bytes",
    "sah", "level_planes", "level_directions",
    "trace_s", "kd_s", "embree_s", "steps", "general_steps", "tests", "hits", "unexplained",
    "grazing", "embree_build_s",
    # Added with the benchmarks (empty where a spec does not measure them).
    "variant", "max_depth", "mean_leaf_size", "box_bytes", "warnings",
    "cull_s", "cull_tests", "culled", "cull_differs",
    # The hits-only paths, where the spec times them: their rounds' times and
    # wrong hits (hits_only_s, hits_only_unexplained, packets_s, ...).
    *(f"{path}_{column}" for path in HITS_ONLY_PATHS for column in ("s", "unexplained")),
    # Ray-box tests per ray (a BVH's; 0 on kd and BSP trees, empty in older files).
    "box_tests",
]


def machine_info() -> dict:
    cpu = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    versions = {"python": platform.python_version(), "numpy": np.__version__}
    from .. import __version__
    versions["bsplab"] = __version__
    try:
        from importlib.metadata import version
        versions["embreex"] = version("embreex")
    except Exception:
        versions["embreex"] = None
    return {"host": platform.node(), "machine": platform.machine(), "cpu": cpu,
            "cores": os.cpu_count(), "system": platform.platform(), "versions": versions}


def load_average() -> list[float] | None:
    """The system's 1, 5 and 15 minute load averages (None where there are
    none): kept with a run, because a load above the cores means other jobs
    shared the machine while it was timed."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return None


class ResultsFile:
    """Rows in `<out>.csv`, the run's record in `<out>.json`; resumable."""

    def __init__(self, out, spec: Spec, fresh: bool = False):
        out = Path(out)
        self.csv = out.with_suffix(".csv")
        self.meta = out.with_suffix(".json")
        self.spec = spec
        self.rows: list[dict] = []
        self.csv.parent.mkdir(parents=True, exist_ok=True)
        if fresh:
            self.csv.unlink(missing_ok=True)
            self.meta.unlink(missing_ok=True)
        if self.csv.exists() and self.meta.exists():
            meta = json.loads(self.meta.read_text())
            if meta.get("fingerprint") != spec.fingerprint():
                raise SpecError(f"{self.csv} holds results of a different spec; pass --fresh "
                                "to start over or choose another --out")
            with open(self.csv, newline="") as f:
                reader = csv.DictReader(f)
                rows = list(reader)
                header = reader.fieldnames or []
            # A run killed mid-write leaves a cut last line or a trial with some
            # of its workloads: drop those rows, the trial runs again.
            self.rows = [r for r in rows if all(r.get(k) is not None for k in header)]
            complete = self.done()
            self.rows = [{k: r.get(k, "") for k in ROW_FIELDS} for r in self.rows
                         if self._key(r) in complete]
            # Rewritten too when an older file lacks the newer columns.
            if len(self.rows) != len(rows) or header != ROW_FIELDS:
                self._rewrite()
        else:
            self.csv.unlink(missing_ok=True)
        self._start_run()
        if not self.csv.exists():
            with open(self.csv, "w", newline="") as f:
                csv.DictWriter(f, fieldnames=ROW_FIELDS).writeheader()

    def _meta(self) -> dict:
        return json.loads(self.meta.read_text()) if self.meta.exists() else {}

    def _start_run(self) -> None:
        meta = self._meta()
        meta.update({"fingerprint": self.spec.fingerprint(), "spec": asdict(self.spec)})
        # Every (re)start of the run is recorded: a resumed run may have
        # continued on another machine.
        meta.setdefault("runs", []).append({
            "started": time.strftime("%Y-%m-%d %H:%M:%S"), "command": " ".join(sys.argv),
            "cells_before": len(self.done()), "machine": machine_info(),
            "load_start": load_average()})
        self.meta.write_text(json.dumps(meta, indent=2))

    def finish(self, seconds: float) -> None:
        meta = self._meta()
        meta["runs"][-1].update(finished=time.strftime("%Y-%m-%d %H:%M:%S"),
                                seconds=round(seconds, 3), cells_after=len(self.done()),
                                load_end=load_average())
        self.meta.write_text(json.dumps(meta, indent=2))

    @staticmethod
    def _key(r: dict) -> str:
        return Trial(r["scene"], r["method"], int(r["k"]) if r["k"] else None, int(r["seed"]),
                    r.get("variant") or "").key

    def _rewrite(self) -> None:
        with open(self.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=ROW_FIELDS)
            w.writeheader()
            w.writerows(self.rows)

    def done(self) -> set[str]:
        have: dict[str, set] = {}
        for r in self.rows:
            have.setdefault(self._key(r), set()).add(r["workload"])
        return {k for k, ws in have.items() if ws >= set(self.spec.workloads)}

    def add(self, rows: list[dict]) -> None:
        with open(self.csv, "a", newline="") as f:
            csv.DictWriter(f, fieldnames=ROW_FIELDS).writerows(rows)
        self.rows += [{k: str(v) for k, v in r.items()} for r in rows]


# The columns `report` reads, and how each must parse. Others (and the
# kd_s column that older runs lack) are optional.
REPORT_COLUMNS = {
    "scene": "text", "workload": "text", "method": "text", "k": "int?", "triangles": "int",
    "rays": "int", "build_s": "number", "kd_nodes": "number", "general_nodes": "number",
    "bytes": "number", "steps": "number", "tests": "number", "unexplained": "int?",
    "level_planes": "ints", "level_directions": "ints", "trace_s": "numbers",
    "embree_s": "numbers?",
}


def _parses(value: str, kind: str) -> bool:
    if kind == "text":
        return True
    if value.strip() == "":  # '?' kinds may be empty, and so may a tree's level lists
        return kind.endswith("?") or kind == "ints"
    convert = int if kind.startswith("int") else float
    try:
        for x in value.split():
            convert(x)
    except ValueError:
        return False
    return kind.rstrip("?") in ("ints", "numbers") or len(value.split()) == 1


def read_rows(path) -> list[dict]:
    """The rows of an `experiment` results file (`path`, or `path` with a
    .csv suffix); ValueError naming the file when it is not one."""
    if Path(path).is_dir():
        raise ValueError(f"{path} is a directory, not a results file (give the .csv "
                         "`experiment` wrote)")
    csv_path = Path(path).with_suffix(".csv")
    if csv_path.is_dir():
        raise ValueError(f"{csv_path} is a directory, not a results file")
    if csv_path.exists() and not csv_path.is_file():  # a FIFO or a device: never opened
        raise ValueError(f"{csv_path}: not a regular file, not a results file")
    if not csv_path.is_file():
        raise FileNotFoundError(f"no results file {csv_path}")
    try:
        with open(csv_path, newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            rows = list(reader)
            columns = reader.fieldnames or []
    except (UnicodeDecodeError, csv.Error) as e:
        raise ValueError(f"{csv_path}: not a CSV results file ({e})") from None
    missing = [c for c in REPORT_COLUMNS if c not in columns]
    if missing:
        raise ValueError(f"{csv_path}: not the results of `python -m bsplab experiment`: "
                         f"missing column(s) {', '.join(missing)}")
    for i, r in enumerate(rows, start=2):
        if None in r.values():
            raise ValueError(f"{csv_path}: line {i} has too few columns (a run cut short? "
                             "rerun the experiment with the same spec to complete it)")
        for c, kind in REPORT_COLUMNS.items():
            if not _parses(r[c], kind):
                raise ValueError(f"{csv_path}: line {i}: column {c} has {r[c]!r}, expected "
                                 f"{_EXPECTED[kind]}")
    if not rows:
        raise ValueError(f"{csv_path}: no result rows (only the header)")
    return rows


_EXPECTED = {"text": "text", "int": "a whole number", "int?": "a whole number or nothing",
             "number": "a number", "ints": "whole numbers separated by spaces",
             "numbers": "numbers separated by spaces",
             "numbers?": "numbers separated by spaces, or nothing"}

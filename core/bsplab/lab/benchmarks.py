"""The benchmarks as specs: `python -m bsplab bench`, `bench-family`,
`bench-cull` and `calibrate` each read a spec from `specs/` (the command
line replacing some keys), run it through the experiment runner (and so with
the one timing protocol, `timing.paired_rounds`), and render their document
with `report`. Their rows stay beside the document as a results file."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from .. import workloads
from ..method_table import METHODS
from . import report
from .runner import run
from .timing import parse_times
from .spec import Spec, SpecError, check_scene, load_spec

SPECS = Path(__file__).resolve().parent.parent / "specs"


def spec_path(name: str) -> Path:
    return SPECS / f"{name}.toml"


def available_scenes(names: list[str], log=print) -> list[str]:
    """The spec's scenes that can be loaded here; the shared meshes may be absent."""
    out = []
    for name in names:
        try:
            check_scene(name)
            out.append(name)
        except SpecError:
            log(f"skipped scene {name}: not here (shared scenes folder: "
                f"{workloads.shared_scenes_dir() or 'not found'})")
    return out


def _spec_scenes(name: str) -> list[str]:
    import tomllib
    return list(tomllib.loads(spec_path(name).read_text(encoding="utf-8"))["scenes"])


def benchmark_spec(name: str, scene_names: list[str] | None = None, **overrides) -> Spec:
    """The benchmark's spec with the command line's keys; without `scene_names`
    the spec's own scenes that are here."""
    chosen = scene_names or available_scenes(_spec_scenes(name))
    return load_spec(spec_path(name), scenes=chosen, **overrides)


def rows_path(out: Path | None, name: str) -> Path:
    """Where the rows go: docs/data/<doc name> beside a document, else out/bench/<name>."""
    return out.parent / "data" / out.stem if out else Path("out") / "bench" / name


def _run(spec: Spec, out: Path | None, name: str) -> tuple[list[dict], dict]:
    data = rows_path(out, name)
    rows = run(spec, data, fresh=True)
    meta = json.loads(data.with_suffix(".json").read_text())
    return rows, meta


def _write(out: Path | None, text: str) -> None:
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)
        print(f"written {out} (rows in {rows_path(out, '').with_suffix('.csv')})")


def _wrong(rows: list[dict]) -> int:
    return sum(report.row_wrong_hits(r) for r in rows)


def command_line() -> str:
    return "python -m bsplab " + " ".join(sys.argv[1:])


def bench(out: Path | None, scene_names=None, methods=None, side=None, rays=None,
          repeats=None) -> int:
    """docs/benchmark.md: each method (kd by default) against Embree."""
    spec = benchmark_spec("bench", scene_names, methods=methods, width=side, height=side,
                          random_rays=rays, repetitions=repeats)
    rows, meta = _run(spec, out, "bench")
    _write(out, report.benchmark_markdown(rows, command_line(), meta))
    return 1 if _wrong(rows) else 0


def family_ks(methods: list[str], ks: list[int]) -> dict[str, list[int]]:
    """Per method taking K, the K of `ks` it accepts (the "+" methods start at 3)."""
    return {m: [k for k in ks if k >= METHODS[m].min_k] for m in methods
            if "k" in METHODS[m].params}


def bench_family(out: Path | None, scene_names=None, methods=None, ks=None,
                 side=None, repeats=None) -> int:
    """docs/bsp_benchmark.md: every method at every K against kd and Embree."""
    methods = methods or [m for m in METHODS if m != "kd"]
    # kd is always a row: the tables' `% kd` and `build × kd` columns need it.
    methods = ["kd"] + [m for m in methods if m != "kd"]
    overrides = {"methods": methods, "width": side, "height": side, "repetitions": repeats}
    if ks is not None:
        per_method = family_ks(methods, ks)
        empty = [m for m, k in per_method.items() if not k]
        if empty:
            raise ValueError(f"no K of {ks} fits {', '.join(empty)} (the '+' methods take "
                             "K from 3)")
        overrides.update(ks=[min(ks)], method_ks=per_method)
    spec = benchmark_spec("bench_family", scene_names, **overrides)
    rows, meta = _run(spec, out, "bench_family")
    _write(out, report.family_markdown(rows, command_line(), meta))
    return 1 if _wrong(rows) else 0


def bench_cull(out: Path | None, scene_names=None, side=None, repeats=None) -> int:
    """docs/cull_benchmark.md: leaf culling on against off, per tree."""
    spec = benchmark_spec("bench_cull", scene_names, width=side, height=side,
                          repetitions=repeats)
    rows, meta = _run(spec, out, "bench_cull")
    _write(out, report.cull_markdown(rows, command_line(), meta))
    differs = sum(int(r["cull_differs"]) for r in rows)
    return 1 if differs or _wrong(rows) else 0


def calibrate(scene_names=None, repeats=None, out: Path | None = None) -> dict:
    """Fits the SAH costs to this machine: the same rays through trees of
    different shapes, the time per ray (paired with the kd-tree's, see
    `_paired_seconds_per_ray`) fitted as

        seconds = a + K_kd * kd_steps + K_gen * general_steps + K_i * tests

    by least squares (kd_steps counts leaves too: both are cheap fetches).
    The ratios K_i / K_kd and K_gen / K_kd are what the builders' costs mean."""
    spec = benchmark_spec("calibrate", scene_names, repetitions=repeats)
    rows, _ = _run(spec, out, "calibrate")
    return fit_costs(rows)


def _paired_seconds_per_ray(rows: list[dict]) -> list[float]:
    """Each row's time per ray, drift removed: the median of its per-round
    ratios to the scene's kd-tree (traced in the same rounds) times that
    kd-tree's median time over the whole run on the same workload."""
    kd_times: dict[tuple, list[float]] = {}
    for r in rows:
        kd_times.setdefault((r["scene"], r["workload"]), []).extend(parse_times(r["kd_s"]))
    out = []
    for r in rows:
        ratio = np.median(np.divide(parse_times(r["trace_s"]), parse_times(r["kd_s"])))
        out.append(float(ratio * np.median(kd_times[(r["scene"], r["workload"])]))
                   / int(r["rays"]))
    return out


def fit_costs(rows: list[dict]) -> dict:
    """The least-squares fit of `calibrate` over result rows."""
    features = []
    for r in rows:
        gen = float(r["general_steps"])
        features.append([1.0, float(r["steps"]) - gen, gen, float(r["tests"])])
    times = _paired_seconds_per_ray(rows)
    A, y = np.array(features), np.array(times)
    if len(y) < 4:
        raise ValueError(f"calibrate needs at least 4 rows to fit 4 costs, got {len(y)}")
    # Relative least squares: cheap and expensive workloads count alike.
    coef, *_ = np.linalg.lstsq(A / y[:, None], np.ones_like(y), rcond=None)
    fit = A @ coef
    r2 = 1 - ((y - fit) ** 2).sum() / max(((y - y.mean()) ** 2).sum(), 1e-300)
    base, k_kd, k_gen, k_i = coef
    return {"ns_per_ray": base * 1e9, "ns_kd_step": k_kd * 1e9, "ns_general_step": k_gen * 1e9,
            "ns_test": k_i * 1e9, "intersect_per_kd": k_i / k_kd,
            "general_per_kd": k_gen / k_kd, "r2": float(r2), "samples": len(y)}

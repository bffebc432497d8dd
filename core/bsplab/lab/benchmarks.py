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
    """Fits the SAH costs to this machine from trees of different shapes
    traced on the same rays as the scene's kd-tree (`fit_costs`)."""
    spec = benchmark_spec("calibrate", scene_names, repetitions=repeats)
    rows, _ = _run(spec, out, "calibrate")
    return fit_costs(rows)


# The fitted quantities, in the order `calibrate` prints them.
FIT_KEYS = ("ns_kd_step", "ns_general_step", "ns_test", "intersect_per_kd", "general_per_kd",
            "ns_per_ray")

# Resamples of the rounds behind the spread and the percentiles it reports
# (the interquartile range), and how far from the fit the ratios' IQR may
# reach for the fit to count as stable (the issue asks for runs that agree
# within 10 %). The bootstrap of a median of few rounds is pessimistic: on a
# loaded machine three runs agreed within 6 % while their IQRs reached 12-20 %
# (docs/algorithms.md, "Measured costs").
BOOTSTRAP_RESAMPLES = 200
SPREAD_PERCENTILES = (25, 75)
STABLE_WITHIN = 0.10


def _is_reference(row: dict) -> bool:
    """The scene's kd-tree with the spec's options: every row's pair."""
    return row["method"] == "kd" and row.get("variant") in (None, "", "{}", {})


def _round_ratios(rows: list[dict]) -> list[np.ndarray]:
    """Per row, its per-round time ratios to the kd-tree traced in the same rounds."""
    return [np.divide(parse_times(r["trace_s"]), parse_times(r["kd_s"])) for r in rows]


def _kd_seconds_per_ray(rows: list[dict]) -> np.ndarray:
    """Per row, the median time per ray of its scene's kd-tree on its workload
    over the whole run: the scale that turns ratios back into seconds."""
    kd_times: dict[tuple, list[float]] = {}
    for r in rows:
        kd_times.setdefault((r["scene"], r["workload"]), []).extend(parse_times(r["kd_s"]))
    return np.array([np.median(kd_times[(r["scene"], r["workload"])]) / int(r["rays"])
                     for r in rows])


def _paired_seconds_per_ray(rows: list[dict]) -> list[float]:
    """Each row's time per ray, drift removed: the median of its per-round
    ratios to the scene's kd-tree (traced in the same rounds) times that
    kd-tree's median time over the whole run on the same workload."""
    ratios = np.array([np.median(x) for x in _round_ratios(rows)])
    return list(map(float, ratios * _kd_seconds_per_ray(rows)))


def _counters(row: dict) -> np.ndarray:
    """kd steps (leaves included: both are cheap fetches), general steps and
    tests, per ray."""
    gen = float(row["general_steps"])
    return np.array([float(row["steps"]) - gen, gen, float(row["tests"])])


def _reference_counters(rows: list[dict]) -> list[np.ndarray]:
    """Per row, the counters of its kd-tree (same scene, same rays)."""
    refs = {(r["scene"], r["workload"]): _counters(r) for r in rows if _is_reference(r)}
    missing = sorted({(r["scene"], r["workload"]) for r in rows} - set(refs))
    if missing:
        raise ValueError("calibrate pairs every tree with the scene's kd-tree, but there is "
                         f"no kd row without a variant for {missing}")
    return [refs[(r["scene"], r["workload"])] for r in rows]


def _least_squares(A: np.ndarray, y: np.ndarray) -> np.ndarray:
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    return coef


def _fit_values(coef: np.ndarray, base: float) -> dict[str, float]:
    k_kd, k_gen, k_i = (float(c) for c in coef)
    return dict(zip(FIT_KEYS, (k_kd * 1e9, k_gen * 1e9, k_i * 1e9, k_i / k_kd, k_gen / k_kd,
                               base * 1e9)))


def _base_per_ray(coef: np.ndarray, refs: list[np.ndarray], scale: np.ndarray) -> float:
    """What the kd-trees' time per ray leaves beyond their steps and tests
    (ray set-up, the hit record, the Python around the trace): the median
    over scenes and workloads."""
    return float(np.median([t - ref @ coef for ref, t in zip(refs, scale)]))


def _bootstrap(A, ratios, scale, refs, resamples: int, seed: int) -> dict:
    """The SPREAD_PERCENTILES of each fitted value when every row's rounds are
    drawn again with replacement: how much the fit owes to which rounds the
    machine happened to run fast or slow."""
    rng = np.random.default_rng(seed)
    fits = []
    for _ in range(resamples):
        y = np.array([np.median(rng.choice(x, len(x))) for x in ratios]) - 1
        coef = _least_squares(A, y)
        fits.append(_fit_values(coef, _base_per_ray(coef, refs, scale)))
    return {k: tuple(float(p) for p in np.percentile([f[k] for f in fits], SPREAD_PERCENTILES))
            for k in FIT_KEYS}


def _is_stable(fit: dict, spread: dict) -> bool:
    """The builders' ratios (all the SAH sees) keep their spread within
    STABLE_WITHIN of the fit."""
    for key in ("intersect_per_kd", "general_per_kd"):
        lo, hi = spread[key]
        if not (fit[key] > 0 and lo >= fit[key] * (1 - STABLE_WITHIN)
                and hi <= fit[key] * (1 + STABLE_WITHIN)):
            return False
    return True


def fit_costs(rows: list[dict], resamples: int = BOOTSTRAP_RESAMPLES, seed: int = 0) -> dict:
    """The costs of a kd step, a general step and a triangle test fitted to
    the rows' times: every tree against the scene's kd-tree on the same rays,

        (time / kd_time - 1) * kd_time = K_kd * d_kd_steps + K_gen * d_general_steps
                                         + K_i * d_tests

    (d: the tree's counter per ray minus the kd-tree's). The pairing takes
    the machine's drift out (the median of per-round ratios) and the
    difference takes out the per-ray base cost, which would otherwise be a
    fourth unknown larger than all the steps together. Each row's equation is
    divided by its kd time, so fast and slow workloads weigh alike. With the
    fit: `spread` (key -> (25 %, 75 %) over resampled rounds), `stable`, `r2`."""
    rows = all_rows = list(rows)
    refs = _reference_counters(rows)
    scale = _kd_seconds_per_ray(rows)
    deltas = np.array([_counters(r) - ref for r, ref in zip(rows, refs)])
    used = np.abs(deltas).sum(axis=1) > 0  # the kd-trees themselves say nothing
    if used.sum() < 3:
        raise ValueError(f"calibrate needs at least 3 trees that differ from the kd-tree "
                         f"to fit 3 costs, got {int(used.sum())}")
    rows = [r for r, u in zip(rows, used) if u]
    refs = [ref for ref, u in zip(refs, used) if u]
    A, scale = deltas[used] / scale[used, None], scale[used]
    ratios = _round_ratios(rows)
    y = np.array([np.median(x) for x in ratios]) - 1
    coef = _least_squares(A, y)
    r2 = 1 - ((y - A @ coef) ** 2).sum() / max(((y - y.mean()) ** 2).sum(), 1e-300)
    out: dict = _fit_values(coef, _base_per_ray(coef, refs, scale))
    out["spread"] = _bootstrap(A, ratios, scale, refs, resamples, seed)
    out["stable"] = _is_stable(out, out["spread"])
    out.update(r2=float(r2), samples=len(y), rounds=min(len(x) for x in ratios))
    workloads = sorted({r["workload"] for r in rows})
    if len(workloads) > 1:
        # Coherent and incoherent rays price a step very differently (cache
        # misses): the pooled fit is a compromise, the per-workload fits show
        # between what.
        out["by_workload"] = {w: fit_costs([r for r in rows if r["workload"] == w]
                                           + [r for r in all_rows if _is_reference(r)
                                              and r["workload"] == w], resamples, seed)
                              for w in workloads}
    return out

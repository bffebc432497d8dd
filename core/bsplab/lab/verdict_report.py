"""docs/verdict.md: the tables of `python -m bsplab verdict`, one per
explanation the results' discussion gives. Two sources: the experiment's own
record (`verdict.run`: trees traced side by side on both paths) and the rows
of the results run (docs/data/results.csv: every method on every scene),
from which the cost fit, ^Kd against plain general nodes, and the SAH
against the rays are read. Counters are exact; times are medians of
per-round ratios to kd traced in the same rounds."""

from __future__ import annotations

import numpy as np

from . import embree_gap
from .benchmarks import fit_costs
from .report import Results, scene_label
from .verdict import KD, paired_ratio, ratio_to_kd

# The targets for the best normal-based ^Kd tree's AO time, as a
# fraction of kd's: the architectural scenes, and the curved ones.
AO_TARGETS = {"sponza_dabrovic": 0.80, "conference": 0.80, "bunny": 0.70,
              "dragon_res2": 0.70, "sportscar": 0.70}
BEST = ("bsp_wn+kd 8", "bsp_cn+kd 8")  # the experiment's normal-based ^Kd trees
# The number of the section on the gap to Embree (embree_gap.py), after the
# seven on BSP planes.
GAP_SECTION = 8


def _pct(x: float | None, digits: int = 0) -> str:
    return "—" if x is None or not np.isfinite(x) else f"{100 * x:.{digits}f}"


def _span(x: np.ndarray) -> str:
    return f"{100 * np.median(x):.1f} ({100 * x.min():.0f}–{100 * x.max():.0f})"


def _table(head: list[str], rows: list[list[str]]) -> list[str]:
    return (["| " + " | ".join(head) + " |", "|---|" + "---:|" * (len(head) - 1)]
            + ["| " + " | ".join(r) + " |" for r in rows] + [""])


def _workloads(record: dict):
    for s in record["scenes"]:
        for name, w in s["workloads"].items():
            yield s, name, w


def general_step_table(record: dict) -> list[str]:
    """The same planes stored as general nodes against kd nodes: the
    counters within a fraction of a percent (a general crossing's wider
    error bound), so the time ratio is the price of the encoding."""
    rows = []
    for s, name, w in _workloads(record):
        g, k = w["trees"]["axes general"], w["trees"]["axes kd"]
        # Steps and tests per ray with general nodes over kd nodes, in %.
        more = "{:+.2f} / {:+.2f}".format(*(100 * (g[c] / k[c] - 1) for c in ("steps", "tests")))
        # Per general step (interior nodes; the leaves visited are alike).
        extra = [(np.asarray(g["seconds"][p]) - np.asarray(k["seconds"][p]))
                 / (w["rays"] * g["general_steps"]) * 1e9 for p in ("counting", "hits_only")]
        rows.append([scene_label(s["scene"]), name,
                     f"{g['steps']:.1f} ({g['general_steps']:.1f})", f"{g['tests']:.2f}",
                     more if g["general_nodes"] > 0 else "**no general nodes**",
                     _span(paired_ratio(w, "axes general", "axes kd", "counting")),
                     _span(paired_ratio(w, "axes general", "axes kd", "hits_only")),
                     f"{np.median(extra[1]):.2f}"])
    return _table(["scene", "rays", "steps/ray (interior)", "tests/ray",
                   "steps / tests, general over kd nodes (%)",
                   "time general ÷ kd nodes, counting % (min–max)", "hits-only %",
                   "extra ns per interior step (hits-only)"], rows)


def parity_table(record: dict) -> list[str]:
    """The sweep builder with the axes alone against the kd builder."""
    rows = []
    for s, name, w in _workloads(record):
        a, kd = w["trees"]["axes kd"], w["trees"][KD]
        rows.append([scene_label(s["scene"]), name, _pct(a["sah"] / kd["sah"], 1),
                     f"{kd['refs_per_tri']:.2f} / {a['refs_per_tri']:.2f}",
                     _pct(a["tests"] / kd["tests"], 1),
                     _pct(ratio_to_kd(w, "axes kd", "hits_only"), 1)])
    return _table(["scene", "rays", "SAH % kd", "refs/tri kd / sweep", "tests % kd",
                   "time % kd (hits-only)"], rows)


def _best(w: dict) -> str:
    """Of the experiment's ^Kd trees, the fastest on the hits-only path."""
    return min(BEST, key=lambda label: ratio_to_kd(w, label, "hits_only"))


def best_tree_table(record: dict) -> list[str]:
    """The best normal-based ^Kd tree against kd, on both paths, with the
    issue's AO targets."""
    rows = []
    for s, name, w in _workloads(record):
        label = _best(w)
        t, kd = w["trees"][label], w["trees"][KD]
        fast = ratio_to_kd(w, label, "hits_only")
        target = AO_TARGETS.get(s["scene"]) if name == "ao" else None
        verdict = "—" if target is None else (f"≤ {target:.2f}: " + ("met" if fast <= target
                                                                      else "**missed**"))
        rows.append([scene_label(s["scene"]), name, label, _pct(t["steps"] / kd["steps"]),
                     f"{t['general_steps']:.1f} of {t['steps']:.1f}",
                     _pct(t["tests"] / kd["tests"]),
                     _pct(ratio_to_kd(w, label, "counting"), 1), _pct(fast, 1), verdict])
    return _table(["scene", "rays", "best tree", "steps % kd", "general steps/ray",
                   "tests % kd", "time % kd, counting", "time % kd, hits-only", "target"],
                  rows)


def alignment_table(record: dict) -> list[str]:
    """How much of each scene is axis-aligned, how many general nodes the
    best tree keeps, and what that buys on AO rays."""
    rows = []
    for s in record["scenes"]:
        w = s["workloads"].get("ao") or next(iter(s["workloads"].values()))
        label = _best(w)
        t, kd = w["trees"][label], w["trees"][KD]
        rows.append([scene_label(s["scene"]), f"{s['triangles']:,}",
                     _pct(s["axis_aligned_share"]),
                     _pct(t["general_nodes"] / max(t["general_nodes"] + t["kd_nodes"], 1)),
                     _pct(t["general_steps"] / t["steps"]), _pct(t["tests"] / kd["tests"]),
                     _pct(ratio_to_kd(w, label, "hits_only"))])
    return _table(["scene", "triangles", "area within 1° of an axis %",
                   "general nodes % of interior", "general steps % (AO)", "AO tests % kd",
                   "AO time % kd (hits-only)"], rows)


# --- from the results run's rows ---------------------------------------------

def cost_fit(rows: list[dict], workload: str) -> dict:
    """`calibrate`'s fit (benchmarks.fit_costs) over the results run's trees
    on one workload: what a kd step, a general step and a test cost there."""
    return fit_costs([r for r in rows if r["workload"] == workload], resamples=50)


def cost_fit_lines(fits: dict[str, dict]) -> list[str]:
    rows = [[w, f"{f['ns_kd_step']:.2f}", f"{f['ns_general_step']:.2f}", f"{f['ns_test']:.2f}",
             f"{f['r2']:.2f}", str(f["samples"])] for w, f in fits.items()]
    return _table(["rays", "ns per kd step", "ns per general step", "ns per test", "r²",
                   "trees"], rows)


def _kd_ns_per_ray(res: Results, scene: str, workload: str) -> float:
    kd = res.kd(scene, workload)
    t = [float(x) for r in kd.rows for x in r["kd_s"].split()]
    return float(np.median(t)) / int(kd.rows[0]["rays"]) * 1e9


def _best_group(res: Results, scene: str, workload: str):
    """The normal-based ^Kd tree with the lowest median time % kd."""
    groups = [g for m in ("bsp_wn+kd", "bsp_cn+kd") for k in res.ks(m)
              if (g := res.get(scene, workload, m, k)) is not None]
    return min(groups, key=lambda g: float(np.median(res.pct_of_kd(g)))) if groups else None


def floor_table(rows: list[dict], fits: dict[str, dict]) -> list[str]:
    """Per scene, the share of kd's time per ray its tests take by the fit;
    the best ^Kd tree measured and predicted from its counters; and its
    floor: its steps with no triangle test at all. The fit explains time
    *differences* between trees of a scene (its per-ray base is not
    meaningful alone), so every column is kd's measured time plus fitted
    differences."""
    res = Results(rows)
    out = []
    for scene in res.scenes:
        for w, f in fits.items():
            best, kd = _best_group(res, scene, w), res.kd(scene, w)
            if best is None or kd is None:
                continue
            t_kd = _kd_ns_per_ray(res, scene, w)
            kd_tests = kd.mean("tests") * f["ns_test"]
            gen = best.mean("general_steps")
            d_steps = ((best.mean("steps") - gen - kd.mean("steps")) * f["ns_kd_step"]
                       + gen * f["ns_general_step"])  # kd's steps are all kd steps
            floor = t_kd + d_steps - kd_tests
            predicted = floor + best.mean("tests") * f["ns_test"]
            out.append([scene_label(scene), w, f"{best.method} {best.k}", f"{t_kd:.0f}",
                        f"{kd.mean('steps'):.1f} / {kd.mean('tests'):.2f}",
                        _pct(kd_tests / t_kd), _pct(best.mean("tests") / kd.mean("tests")),
                        f"{np.median(res.pct_of_kd(best)):.0f}", _pct(predicted / t_kd),
                        _pct(floor / t_kd)])
    return _table(["scene", "rays", "best tree (results)", "kd ns/ray", "kd steps / tests",
                   "kd's tests, % of its time", "best tests % kd", "best measured % kd",
                   "predicted % kd", "floor: its steps, no tests, % kd"], out)


def kd_nodes_table(rows: list[dict], ks=(6, 8)) -> list[str]:
    """The same normal-based directions with and without ^Kd: how many of a
    ray's steps are general, and the time."""
    res = Results(rows)
    out = []
    for scene in res.scenes:
        for w in res.workloads:
            for k in ks:
                plain, kdn = (res.get(scene, w, m, k) for m in ("bsp_wn+", "bsp_wn+kd"))
                if plain is None or kdn is None:
                    continue
                out.append([scene_label(scene), w, str(k)] + [
                    f"{g.mean('general_steps'):.1f} / {g.mean('steps'):.1f}" for g in (plain, kdn)
                ] + [f"{np.median(res.pct_of_kd(g)):.0f}" for g in (plain, kdn)])
    return _table(["scene", "rays", "K", "bsp_wn+ general / all steps",
                   "bsp_wn+kd general / all steps", "bsp_wn+ time % kd",
                   "bsp_wn+kd time % kd"], out)


def sah_table(rows: list[dict]) -> list[str]:
    """Per method: the SAH cost it reaches against the tests and time it
    saves, as medians (and ranges) over the scenes, AO rays."""
    res = Results(rows)
    w = "ao" if "ao" in res.workloads else res.workloads[0]
    out = []
    for m in res.methods:
        if m == "kd":
            continue
        for k in res.ks(m):
            groups = [(g, res.kd(s, w)) for s in res.scenes
                      if (g := res.get(s, w, m, k)) is not None and res.kd(s, w)]
            cols = []
            for value in (lambda g, kd: g.mean("sah") / kd.mean("sah"),
                          lambda g, kd: g.mean("tests") / kd.mean("tests"),
                          lambda g, kd: float(np.median(res.pct_of_kd(g))) / 100):
                v = np.array([value(g, kd) for g, kd in groups])
                cols.append(f"{100 * np.median(v):.0f} ({100 * v.min():.0f}–{100 * v.max():.0f})")
            out.append([m, "" if k is None else str(k)] + cols)
    return _table(["method", "K", "SAH % kd, median (min–max over scenes)",
                   f"{w} tests % kd", f"{w} time % kd"], out)


def markdown(record: dict | None, rows: list[dict] | None, command: str) -> str:
    """The whole page; a section whose source is missing says so."""
    out = ["# Verdict experiments: why BSP planes pay where they do", "",
           f"Generated by `{command}`. Each section checks one explanation of "
           "[results.md](results.md)'s discussion. Counters (steps, tests, nodes) are exact; "
           "a time is the median over paired rounds of the tree's time over kd's traced "
           "in the same round on the same rays, one thread (`bsplab.lab.timing`), min–max "
           "over the rounds in brackets.", ""]
    if record:
        load = ", ".join(f"{a:.1f} → {b:.1f}" for a, b in zip(record["load_start"] or [],
                                                              record["load_end"] or []))
        out += [f"Traced part (`{record.get('command', '?')}`): {record['width']}×{record['height']} primary rays from the "
                f"results spec's camera and one AO ray per hit, {record['rounds']} rounds; "
                f"{record['minutes']:.1f} min, started {record['started']}; load average "
                f"(1/5/15 min) at start → end: {load} on {record['machine']['cores']} cores "
                "(above the cores: other jobs shared the machine).", "",
                "## 1. A general step costs more than a kd step", "",
                "The sweep with the axes alone, once with kd nodes (`bsp_wn+kd`, K = 3) and "
                "once with every node general (`bsp_wn+`, K = 3): the same planes, stored "
                "two ways. A general node's crossing is widened by the error bound of a "
                "general plane's arithmetic, an axis plane's by the smaller one of a kd "
                "split (docs/algorithms.md), so a ray takes both children of a general node "
                "a little more often: its steps and tests per ray differ by the fraction of a "
                "percent the table gives, and the time ratio is the price of the encoding.", "",
                *general_step_table(record),
                "## 2. The sweep at K = 3 is the kd-tree (parity)", "",
                *parity_table(record),
                "## 3. The best normal-based ^Kd tree, on the counting and the hits-only path",
                "", "The results run times the counting path (it writes eight arrays per ray: "
                "the counters); a renderer takes the hits-only path. Both are traced here in "
                "the same rounds; the target column (the issue's, AO rays) judges the "
                "hits-only time.", "",
                *best_tree_table(record),
                "## 4. Where the general planes go", "",
                "Normal-based directions on an axis-aligned surface *are* axes, and ^Kd "
                "stores them as kd nodes.", "",
                *alignment_table(record)]
    else:
        out += ["(The traced part was not run: `--skip-trace`.)", ""]
    if rows:
        fits = {w: cost_fit(rows, w) for w in ("primary", "ao")
                if any(r["workload"] == w for r in rows)}
        out += ["## 5. What kd's tests cost, and the floor of saving them", "",
                "The costs fitted to the results run's own trees (`calibrate`'s "
                "least squares on the differences to kd, `benchmarks.fit_costs`):", "",
                *cost_fit_lines(fits),
                "The fit explains time differences between the trees of a scene (r² above), "
                "not absolute times. With it: how much of kd's time its triangle tests "
                "take, the best ^Kd tree of the results run as measured and as predicted "
                "from its counters, and its floor: the time it would take with its steps "
                "and no triangle test at all. A floor above a target means no plane choice "
                "that only saves tests can reach it; the steps must go.", "",
                *floor_table(rows, fits),
                "## 6. ^Kd against the same directions as general nodes", "",
                *kd_nodes_table(rows),
                "## 7. The SAH cost against the rays", "",
                *sah_table(rows)]
    else:
        out += ["(No results rows: run `python -m bsplab results` first.)", ""]
    out += embree_gap.section((record or {}).get("gap"), GAP_SECTION)
    return "\n".join(out) + "\n"


def main(out, scenes=None, results=None, rounds: int = 7, side: int | None = None,
         trace: bool = True, command: str = "python -m bsplab verdict",
         only_gap: bool = False) -> int:
    """Runs the traced part (unless `trace` is False: then the last record
    beside `out` is reused; with `only_gap`, the record's sections 1-4 are
    reused and only the gap to Embree is traced again), reads the results
    rows, writes the page."""
    import json
    from pathlib import Path

    from . import verdict
    from .store import read_rows
    out = Path(out)
    data = out.parent / "data" / (out.stem + ".json")
    if results and not Path(results).is_file():  # before any long work
        what = "not a regular file" if Path(results).exists() else "no such results file"
        raise ValueError(f"--results {results}: {what} (run `python -m bsplab results` "
                         "first, or name one with --results)")
    if (only_gap or not trace) and not data.is_file():
        flag = "--only-gap" if only_gap else "--skip-trace"
        raise ValueError(f"{flag}: no traced record {data} to reuse; run without {flag}")
    if trace or only_gap:
        from .benchmarks import available_scenes
        chosen = scenes or available_scenes(verdict.DEFAULT_SCENES)
        if not chosen:
            raise ValueError("no scene to trace: the shared scenes are not here; "
                             "name generated ones with --scenes (e.g. room spheres)")
    if trace and not only_gap:
        record = verdict.run(chosen, data, rounds=rounds, width=side, height=side,
                             command=command)
    else:
        record = json.loads(data.read_text())
    if trace or only_gap:
        record["gap"] = dict(embree_gap.run(chosen, verdict.SPECS / "results.toml", rounds,
                                            width=side, height=side), command=command)
        data.write_text(json.dumps(record, indent=1))
    rows = read_rows(results) if results else None
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(markdown(record, rows, command))
    print(f"written {out} (traced record in {data})")
    return 0

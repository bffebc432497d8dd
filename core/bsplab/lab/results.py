"""`python -m bsplab results`: regenerates docs/results.md and its plots from
scratch: runs specs/results.toml (every shared mesh) or, with --quick,
specs/results_quick.toml (the generated scenes, for CI), then writes the
report with the source thesis's figures beside ours."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from . import plots, report
from .runner import run
from .spec import load_spec

SPECS = Path(__file__).resolve().parent.parent / "specs"

# Median render time as % of the thesis's kd-tree, per K: (Been, Sponza,
# Conference Hall), from its tables 5.1-5.9 (7 runs each).
THESIS = {
    "bsp_random": {2: (95.144, 437.608, 300.392), 3: (89.091, 345.522, 266.944), 4: (85.581, 294.67, 232.307), 5: (83.651, 272.468, 214.093), 6: (82.325, 248.777, 204.593), 7: (81.057, 231.221, 194.539), 8: (80.121, 223.647, 184.94), 9: (79.174, 208.786, 178.935), 10: (78.481, 198.755, 173.994)},  # noqa: E501
    "bsp_random+": {3: (102.681, 91.383, 97.129), 4: (90.191, 95.368, 96.988), 5: (85.512, 94.368, 94.099), 6: (82.349, 97.991, 93.91), 7: (80.892, 96.864, 93.843), 8: (79.911, 97.068, 92.504), 9: (79.001, 94.022, 92.212), 10: (78.24, 95.61, 92.371)},  # noqa: E501
    "bsp_random+kd": {3: (101.346, 95.087, 97.286), 4: (92.271, 90.867, 92.736), 5: (88.335, 90.537, 91.448), 6: (84.519, 88.422, 90.463), 7: (82.626, 85.315, 89.65), 8: (81.566, 85.485, 90.072), 9: (80.799, 84.301, 88.272), 10: (80.234, 85.503, 87.09)},  # noqa: E501
    "bsp_wn": {2: (80.439, 205.401, 163.78), 3: (76.171, 165.521, 133.497), 4: (74.369, 149.284, 121.746), 5: (74.334, 153.732, 120.877), 6: (73.867, 137.888, 113.731), 7: (74.099, 143.17, 111.324), 8: (73.992, 134.784, 110.33), 9: (72.973, 130.295, 109.587), 10: (72.579, 134.463, 110.402)},  # noqa: E501
    "bsp_wn+": {3: (102.405, 96.063, 97.503), 4: (70.982, 94.165, 82.461), 5: (68.482, 92.765, 83.239), 6: (67.283, 98.831, 83.912), 7: (67.177, 100.152, 84.41), 8: (66.861, 102.555, 84.228), 9: (66.729, 104.674, 84.364), 10: (66.491, 100.657, 85.119)},  # noqa: E501
    "bsp_wn+kd": {3: (101.544, 95.15, 97.169), 4: (72.068, 83.277, 79.16), 5: (69.158, 83.87, 78.864), 6: (67.723, 80.364, 78.562), 7: (67.182, 80.472, 80.896), 8: (67.012, 80.036, 80.682), 9: (67.043, 80.296, 80.007), 10: (67.126, 83.683, 80.188)},  # noqa: E501
    "bsp_cn": {2: (102.797, 370.346, 178.901), 3: (79.765, 212.866, 141.885), 4: (75.708, 187.343, 132.851), 5: (74.268, 163.685, 126.273), 6: (72.469, 152.916, 120.382), 7: (71.852, 145.378, 117.766), 8: (72.52, 146.582, 116.81), 9: (71.992, 142.395, 114.814), 10: (72.229, 144.594, 114.291)},  # noqa: E501
    "bsp_cn+": {3: (102.606, 102.09, 97.246), 4: (77.536, 99.184, 86.035), 5: (70.343, 93.449, 83.323), 6: (67.694, 105.866, 89.229), 7: (66.572, 114.48, 88.392), 8: (66.451, 110.056, 86.746), 9: (66.879, 110.56, 87.156), 10: (66.411, 111.116, 89.005)},  # noqa: E501
    "bsp_cn+kd": {3: (101.571, 95.846, 96.491), 4: (78.065, 87.161, 83.582), 5: (70.429, 83.064, 80.756), 6: (67.828, 80.339, 79.272), 7: (67.208, 79.844, 79.577), 8: (67.291, 80.107, 79.712), 9: (66.847, 80.173, 78.885), 10: (66.899, 83.764, 80.151)},  # noqa: E501
}
# Ranges the thesis (and the issue quoting it) give without a per-K table.
THESIS_RANGES = {("bsp_ize+kd", None): "85–109", ("rbsp+kd", 13): "78–94"}
THESIS_SCENES = {"sponza_dabrovic": 1, "conference": 2}  # index into THESIS tuples


def _median_pct(res: report.Results, scene: str, workload: str, method: str, k):
    g = res.get(scene, workload, method, k)
    p = res.pct_of_kd(g) if g else None
    return None if p is None else float(np.median(p))


def thesis_comparison(rows: list[dict]) -> list[str]:
    """Our median % of kd beside the thesis's, on the scenes both have."""
    res = report.Results(rows)
    scenes = [s for s in res.scenes if s in THESIS_SCENES]
    others = [s for s in res.scenes if s not in THESIS_SCENES]
    if not scenes:
        return ["(The thesis's scenes, Sponza and Conference, are not in this run.)", ""]
    head = ["method", "K"]
    for s in scenes:
        head += [f"{s} thesis", f"{s} ours primary", f"{s} ours AO"]
    if others:
        head += ["other scenes, ours primary (min–max)", "ours AO (min–max)"]
    out = ["| " + " | ".join(head) + " |", "|---|---:|" + "---:|" * (len(head) - 2)]

    def fmt(x):
        return "—" if x is None else f"{x:.0f}"

    for m in res.methods:
        if m == "kd":
            continue
        for k in res.ks(m):
            fields = [m, "" if k is None else str(k)]
            for s in scenes:
                ref = THESIS.get(m, {}).get(k)
                thesis = (f"{ref[THESIS_SCENES[s]]:.0f}" if ref
                          else THESIS_RANGES.get((m, k), "—"))
                fields += [thesis] + [fmt(_median_pct(res, s, w, m, k))
                                     for w in ("primary", "ao")]
            if others:
                for w in ("primary", "ao"):
                    v = [x for x in (_median_pct(res, s, w, m, k) for s in others) if x]
                    fields.append(f"{min(v):.0f}–{max(v):.0f}" if v else "—")
            out.append("| " + " | ".join(fields) + " |")
    return out + [""]


def main(quick: bool = False, out: Path = Path("docs/results.md"), fresh: bool = True) -> int:
    spec = load_spec(SPECS / ("results_quick.toml" if quick else "results.toml"))
    out = Path(out)
    if quick and out == Path("docs/results.md"):
        out = Path("out/results_quick/results.md")  # CI never rewrites the docs
    data = out.parent / "data" / ("results_quick" if quick else "results")
    rows = run(spec, data, fresh=fresh)
    plot_dir = out.parent / ("results_quick_plots" if quick else "results_plots")
    pngs = plots.plots(rows, plot_dir)
    meta = json.loads(data.with_suffix(".json").read_text())
    # All starts of the run (a resumed run took several).
    minutes = sum(r.get("seconds", 0) for r in meta["runs"]) / 60
    discussion = out.parent / "results_discussion.md"
    text = [
        "# Results: the BSP family against kd and Embree" + (" (quick)" if quick else ""),
        "",
        "Generated by `python -m bsplab results" + (" --quick" if quick else "") + "` "
        f"(spec `core/bsplab/specs/{'results_quick' if quick else 'results'}.toml`); the "
        f"trials took {minutes:.1f} minutes on the machine in the JSON file; rows in `{data.with_suffix('.csv').name}`, machine and "
        f"versions in `{data.with_suffix('.json').name}` (folder `{data.parent}`). "
        "Every number below comes from that run, except the thesis's columns, which are "
        "copied from its tables 5.1–5.9.",
        "",
        "## Against the thesis",
        "",
        "Render time as % of the kd-tree's (median; below 100 is faster). The thesis timed "
        "whole renders of its own scenes' views; ours are primary rays from a camera framing "
        "the scene and one ambient-occlusion ray per hit, traced on one thread.",
        "",
        *thesis_comparison(rows),
    ]
    if not quick and discussion.exists():
        text += [discussion.read_text().strip(), ""]
    body = report.markdown(rows, "Measured tables", meta, pngs, relative_to=out.parent)
    # One level down: the report's headings go under this page's title.
    text += ["#" + line if line.startswith("#") else line for line in body.splitlines()]
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(text) + "\n")
    print(f"written {out} ({len(rows)} rows, {len(pngs)} plots in {plot_dir}) "
          f"in {minutes:.1f} min")
    wrong = sum(report.wrong_hits(g) for g in report.Results(rows).groups.values())
    return 1 if wrong else 0

"""Every table of the lab, in Markdown: the experiment report (tables in the
shape of the source thesis's tables 5.1-5.10: per method, rows K, columns
scene x min/med/max of the render time as a percentage of the kd-tree's;
Kd/BSP node counts; a summary per scene with ratios to kd and to Embree),
and the documents of the benchmarks (`python -m bsplab bench`,
`bench-family`, `bench-cull`, `calibrate`). Plots are in `plots.py`.

Every time is first divided by Embree's time on the same rays measured right
beside it in the same trial (a paired ratio, which cancels most of a shared
machine's drift), then by the kd-tree's median of the same ratio."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..method_table import METHODS
from .timing import parse_times
from .tracers import HITS_ONLY_PATHS


@dataclass
class Group:
    """All rows of one (scene, workload, method, K): seeds and repetitions."""
    scene: str
    workload: str
    method: str
    k: int | None
    variant: str = ""
    rows: list = field(default_factory=list)

    def _first(self, key):
        return float(self.rows[0][key])

    @property
    def triangles(self) -> int:
        return int(self.rows[0]["triangles"])

    def normalised(self) -> np.ndarray:
        """Per repetition: our time / Embree's (or our time when there is no Embree)."""
        out = []
        for r in self.rows:
            t, e = parse_times(r["trace_s"]), parse_times(r["embree_s"])
            out += [a / b for a, b in zip(t, e)] if len(e) == len(t) else t
        return np.array(out)

    def per_round(self, numerator: str, denominator: str) -> np.ndarray | None:
        """Per round: the time in column `numerator` over the time in column
        `denominator` traced beside it; None where a row lacks the pair."""
        out = []
        for r in self.rows:
            a, b = parse_times(r.get(numerator) or ""), parse_times(r.get(denominator) or "")
            if not a or len(a) != len(b):
                return None
            out += [x / y for x, y in zip(a, b)]
        return np.array(out)

    def paired_with_kd(self) -> np.ndarray | None:
        """Per repetition: our time / the kd-tree's, traced right beside it."""
        return self.per_round("trace_s", "kd_s")

    def has_embree(self) -> bool:
        return all(r["embree_s"] for r in self.rows)

    def mean(self, key: str) -> float:
        return float(np.mean([float(r[key]) for r in self.rows]))

    def levels(self, key: str) -> list[int]:
        return [int(x) for x in self.rows[0][key].split()]


def _k(value: str) -> int | None:
    return int(value) if value not in ("", None) else None


def group_rows(rows: list[dict]) -> dict[tuple, Group]:
    groups: dict[tuple, Group] = {}
    for r in rows:
        key = (r["scene"], r["workload"], r["method"], _k(r["k"]), r.get("variant") or "")
        groups.setdefault(key, Group(*key)).rows.append(r)
    return groups


def scene_label(scene: str) -> str:
    return Path(scene).stem if "/" in scene or "." in Path(scene).name else scene


class Results:
    """Rows grouped, with the kd references per (scene, workload)."""

    def __init__(self, rows: list[dict]):
        if not rows:
            raise ValueError("no results to report")
        self.groups = group_rows(rows)
        self.scenes = list(dict.fromkeys(r["scene"] for r in rows))
        self.workloads = list(dict.fromkeys(r["workload"] for r in rows))
        self.methods = [m for m in METHODS if any(r["method"] == m for r in rows)]

    def ks(self, method: str) -> list:
        return sorted({g.k for g in self.groups.values() if g.method == method},
                      key=lambda k: -1 if k is None else k)

    def get(self, scene, workload, method, k, variant: str = "") -> Group | None:
        return self.groups.get((scene, workload, method, k, variant))

    def kd(self, scene, workload) -> Group | None:
        return self.get(scene, workload, "kd", None)

    def pct_of_kd(self, g: Group) -> np.ndarray | None:
        """Render time as % of kd's, per repetition (the thesis's measure):
        against the kd traces paired with ours in the same trial, or else
        through Embree's paired times and the kd trial's median."""
        paired = g.paired_with_kd()
        if paired is not None:
            return 100.0 * paired
        kd = self.kd(g.scene, g.workload)
        if kd is None:
            return None
        return 100.0 * g.normalised() / float(np.median(kd.normalised()))

    def x_embree(self, g: Group) -> float | None:
        return float(np.median(g.normalised())) if g.has_embree() else None

    def build_x_kd(self, g: Group) -> float | None:
        kd = self.kd(g.scene, g.workload)
        return g.mean("build_s") / kd.mean("build_s") if kd else None

    def counter_pct_of_kd(self, g: Group, key: str) -> float | None:
        kd = self.kd(g.scene, g.workload)
        return 100.0 * g.mean(key) / kd.mean(key) if kd and kd.mean(key) > 0 else None


def machine_lines(meta: dict | None) -> list[str]:
    """Where the rows were measured, from the results file's JSON record."""
    if not meta:
        return []
    runs = meta.get("runs") or [{}]
    # The last start that ran trials (a resumed run that only re-renders the
    # page measured nothing: its load says nothing about the rows).
    run = next((r for r in reversed(runs)
                if r.get("cells_after", 1) > r.get("cells_before", 0)), runs[-1])
    mach = run.get("machine", {})
    return [f"Machine: {mach.get('cpu', '?')}, {mach.get('cores', '?')} cores; "
            f"versions {mach.get('versions', {})}. Spec fingerprint "
            f"`{meta.get('fingerprint', '?')}`." + load_sentence(run, mach.get("cores")), ""]


def load_sentence(run: dict, cores) -> str:
    """The run's duration and the machine's load around it, where recorded."""
    start, end = run.get("load_start"), run.get("load_end")
    if not start or not end:
        return ""
    minutes = f" took {run['seconds'] / 60:.0f} minutes" if "seconds" in run else ""
    shared = (" (above the cores: other jobs shared the machine, which widens the min–max "
              "spans; the paired medians and the counters are what to read)"
              if max(start[0], end[0]) > (cores or 1) else "")
    return (f" The run{minutes}, started {run.get('started', '?')}; load average "
            f"(1/5/15 min) {' / '.join(map(str, start))} at the start and "
            f"{' / '.join(map(str, end))} at the end on {cores} cores{shared}.")


# A row's wrong hits, one column per traced path: the counting path's, then
# each hits-only path's.
WRONG_HITS_COLUMNS = ("unexplained",) + tuple(f"{p}_unexplained" for p in HITS_ONLY_PATHS)


def row_wrong_hits(r: dict) -> int:
    """Rays whose answer differs from Embree's beyond ties and grazing, on any
    path the row traced."""
    return sum(int(r[c]) for c in WRONG_HITS_COLUMNS if r.get(c) not in ("", None))


def wrong_hits(g: Group) -> int:
    return sum(row_wrong_hits(r) for r in g.rows)


def _f(x, fmt="{:.1f}") -> str:
    return "—" if x is None or (isinstance(x, float) and math.isnan(x)) else fmt.format(x)


# -----------------------------------------------------------------------------
# Markdown


def summary_tables(res: Results) -> list[str]:
    out = []
    for scene in res.scenes:
        for w in res.workloads:
            kd = res.kd(scene, w)
            any_g = next(g for g in res.groups.values() if g.scene == scene and g.workload == w)
            out += [f"### {scene_label(scene)} — {w} rays ({any_g.triangles:,} triangles, "
                    f"{int(any_g.rows[0]['rays']):,} rays)", ""]
            if kd is not None and kd.has_embree():
                out += [f"kd: {res.x_embree(kd):.2f}× Embree's time, build "
                        f"{kd.mean('build_s'):.2f} s, {kd.mean('steps'):.1f} steps and "
                        f"{kd.mean('tests'):.2f} tests per ray.", ""]
            out += ["| method | K | time % kd (med) | min–max | × Embree | build s | build × kd "
                    "| steps | tests | tests % kd | kd / general nodes | MiB | wrong hits |",
                    "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
            for m in res.methods:
                for k in res.ks(m):
                    g = res.get(scene, w, m, k)
                    if g is None:
                        continue
                    p = res.pct_of_kd(g)
                    wrong = wrong_hits(g)
                    out.append(
                        f"| {m} | {'' if k is None else k} | "
                        f"{_f(None if p is None else float(np.median(p)))} | "
                        f"{_f(None if p is None else float(p.min()))}–"
                        f"{_f(None if p is None else float(p.max()))} | "
                        f"{_f(res.x_embree(g), '{:.2f}')} | {g.mean('build_s'):.2f} | "
                        f"{_f(res.build_x_kd(g), '{:.1f}')} | {g.mean('steps'):.1f} | "
                        f"{g.mean('tests'):.2f} | {_f(res.counter_pct_of_kd(g, 'tests'), '{:.0f}')} "
                        f"| {int(g.mean('kd_nodes')):,} / {int(g.mean('general_nodes')):,} | "
                        f"{g.mean('bytes') / 2**20:.1f} | "
                        f"{wrong if g.has_embree() else '—'} |")
            out.append("")
    return out


def _method_k_tables(res: Results, title, column_names, fields_of) -> list[str]:
    """Per method but kd: a table with rows K and, per scene, the columns
    `column_names` filled by fields_of(group) (None: no such tree)."""
    out = []
    names = [scene_label(s) for s in res.scenes]
    for m in res.methods:
        if m == "kd":
            continue
        out += [f"#### {METHODS[m].label} (`{m}`): {title}", "",
                "| K | " + " | ".join(f"{n} {c}" for n in names for c in column_names) + " |",
                "|---:|" + "---:|" * (len(column_names) * len(names))]
        for k in res.ks(m):
            fields = []
            for s in res.scenes:
                row = fields_of(s, m, k)
                fields += ["—"] * len(column_names) if row is None else row
            out.append(f"| {'' if k is None else k} | " + " | ".join(fields) + " |")
        out.append("")
    return out


def thesis_tables(res: Results, workload: str) -> list[str]:
    """Tables 5.1-5.9: per method, rows K, columns scene x min/med/max (% of kd)."""
    def fields(scene, method, k):
        g = res.get(scene, workload, method, k)
        p = res.pct_of_kd(g) if g else None
        return None if p is None else [f"{p.min():.1f}", f"{np.median(p):.1f}", f"{p.max():.1f}"]
    return _method_k_tables(res, f"render time as % of kd, {workload} rays",
                            ("min", "med", "max"), fields)


def node_tables(res: Results) -> list[str]:
    """Table 5.10: kd vs general (BSP) node counts per method and K."""
    def fields(scene, method, k):
        g = res.get(scene, res.workloads[0], method, k)
        if g is None:
            return None
        a, b = int(g.mean("kd_nodes")), int(g.mean("general_nodes"))
        return [f"{a:,}", f"{b:,}", f"{a + b:,}"]
    return _method_k_tables(res, "interior nodes, Kd / BSP / total", ("Kd", "BSP", "total"),
                            fields)


def markdown(rows: list[dict], title: str = "Experiment results", meta: dict | None = None,
             plots: list[Path] | None = None, relative_to: Path | None = None) -> str:
    res = Results(rows)
    out = [f"# {title}", ""] + machine_lines(meta)
    out += ["Times (one thread each): every repetition traces the tree, the scene's "
            "kd-tree and Embree on the same rays, one right after the other in a rotating "
            "order; `time % kd` is the tree's time over its kd partner's (below 100 is "
            "faster than kd), `× Embree` the median of its time over its Embree partner's. "
            "min/med/max are over seeds × repetitions. Steps and tests per ray are exact. `wrong hits` "
            "counts rays whose answer differs from Embree's beyond ties and grazing edges.", ""]
    out += ["## Summary per scene", ""] + summary_tables(res)
    for w in res.workloads:
        out += [f"## Render time per method (tables 5.1–5.9 shape), {w} rays", ""]
        out += thesis_tables(res, w)
    out += ["## Kd and BSP nodes (table 5.10 shape)", ""] + node_tables(res)
    if plots:
        out += ["## Plots", ""]
        for p in plots:
            rel = p.relative_to(relative_to) if relative_to else p
            out += [f"![{p.stem}]({rel.as_posix()})", ""]
    return "\n".join(out)


# -----------------------------------------------------------------------------
# The benchmarks' documents

PAIRED = ("Every time is measured with the lab's one protocol, paired rounds "
          "(`bsplab.lab.timing`): in each of the spec's repetitions the tree, the scene's "
          "kd-tree and Embree (and, for culling, the same tree with culling on) trace the "
          "same rays on one thread, one right after the other in a rotating order; a "
          "ratio is the median over the repetitions of the per-repetition ratio, a time or "
          "Mray/s the median time. "
          "Mray/s drift with the machine's load; the ratios are what to compare. Steps "
          "and tests per ray are exact counters.")


# What the columns of each benchmark's tables are.
BENCH_COLUMNS = (
    "Each tree traces each workload's rays on up to four paths, each timed beside "
    "Embree (`rtcIntersect1` per ray through embreex, which times its own loop) in the "
    "same rounds: **hits-only**, one ray at a time without counters "
    "(`tree.intersect(o, d, threads=1, counters=False)`: the closest hits only, as "
    "Embree needs; a kd or BSP tree sorts an incoherent batch - the random rays - into "
    "spatial order first (`ray_order=\"auto\"`, the default, which sorts them: their walks "
    "are long enough to pay for it), the BVH keeps the given order); "
    "**given order**, the random rays on the same path kept in the caller's order "
    "(`ray_order=\"given\"`); **packets**, primary rays in the camera's tile order traced in "
    "SIMD groups of 4, 8 or 16 (`tree.intersect(o, d, threads=1, counters=False, "
    "packets=True)`: the same hits, and the path of the shaded, normal and depth "
    "renders); **counters** (`counters=True`: the path "
    "that also counts the steps and tests per ray shown here and in the heatmaps). "
    "`× Embree speed` is Embree's time over the path's time in the same round, the "
    "median over the rounds (above 1: faster than Embree), min–max in brackets; "
    "Mray/s come from median times. Every hit of every path is checked against "
    "Embree's: `wrong hits` counts the rays on which any path's answer differs from "
    "Embree's beyond ties and grazing edges (it must be 0), `grazing` the counters "
    "path's grazing rays. In the build table, `build × Embree` is our build time over "
    "Embree's (embreex's mesh set-up and BVH build, measured once per scene), `B/tri` "
    "the tree's bytes per triangle.")

FAMILY_COLUMNS = ("`time % kd` is the tree's time over the kd-tree's traced beside it "
                  "(below 100 is faster than kd), min–max over the repetitions; `× Embree` "
                  "over Embree's. `build × kd` is the build time over the kd build's. "
                  "`tests % kd` compares the triangle tests per ray. AO rays: one "
                  "cosine-weighted ray from every primary hit, reaching a tenth of the "
                  "scene box's diagonal. `wrong hits` counts rays whose answer differs "
                  "from Embree's beyond ties and grazing edges.")

CULL_COLUMNS = ("Each tree is traced with culling off and on in the same rounds. `fewer "
                "tests` is the share of ray-triangle tests culling removes; `time on/off` "
                "(median of the paired ratios) below 1 means culling pays. The source "
                "thesis (seed 002) reports 80–90 % fewer tests and up to 2x faster "
                "tracing on kd-trees whose leaves hold many triangles; our default SAH "
                "trees hold 2–5 per leaf and a mailbox already skips repeats, so the "
                "`intersect_cost 0.3` rows (larger leaves) are the comparable ones. "
                "`answers differ` counts rays whose hit distance changed with culling "
                "on (it must be 0).")


def _header(title: str, command: str, meta: dict | None, text: str) -> list[str]:
    return [f"# {title}", "", f"Command: `{command}`", ""] + machine_lines(meta) + [
        PAIRED, "", text, ""]


def _mrays(g: Group, column: str) -> float | None:
    """Rays per microsecond (Mray/s) from the median of the rounds' times in
    `column`; None where the rows have none."""
    times = [t for r in g.rows for t in parse_times(r.get(column) or "")]
    return int(g.rows[0]["rays"]) / float(np.median(times)) / 1e6 if times else None


def _build_table(res: Results) -> list[str]:
    """Per scene and method (its first K), the build and the tree's size."""
    out = ["## Build", "",
           "| scene | triangles | method | build s | build × Embree | nodes | leaves | "
           "depth | refs/tri | tris/leaf | MiB | B/tri | SAH |",
           "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    w0 = res.workloads[0]
    warned = []
    for scene in res.scenes:
        for m in res.methods:
            g = res.get(scene, w0, m, None) or next(
                (res.get(scene, w0, m, k) for k in res.ks(m) if res.get(scene, w0, m, k)), None)
            if g is None:
                continue
            r = g.rows[0]
            e = float(r["embree_build_s"]) if r["embree_build_s"] else None
            out.append(
                f"| {scene_label(scene)} | {g.triangles:,} | {m} | {g.mean('build_s'):.2f} | "
                f"{_f(None if not e else g.mean('build_s') / e, '{:.2f}')} | "
                f"{int(g.mean('nodes')):,} | {int(g.mean('leaves')):,} | {r['max_depth']} | "
                f"{g.mean('refs_per_tri'):.2f} | {g.mean('mean_leaf_size'):.2f} | "
                f"{g.mean('bytes') / 2**20:.1f} | {g.mean('bytes') / g.triangles:.0f} | "
                f"{g.mean('sah'):.1f} |")
            warned += [(scene, m, w) for w in r.get("warnings", "").split("; ") if w]
    if warned:
        out.append("")
        out += [f"**Warning** ({scene_label(s)}, {m}): {w}." for s, m, w in warned]
    return out


# The paths a trace table shows, in its column order: (times column, label).
TRACE_PATHS = tuple((f"{p}_s", p.replace("_", "-")) for p in HITS_ONLY_PATHS) + (
    ("trace_s", "counters"),)


def _speed_field(g: Group, column: str, bold: bool) -> str:
    """`× Embree speed` of one path: the median of Embree's time over the
    path's, round by round, and the spread over the rounds."""
    x = g.per_round("embree_s", column)
    if x is None:
        return "—"
    med = _ratio_text(np.median(x))
    return f"{'**' + med + '**' if bold else med} ({_ratio_text(x.min())}–{_ratio_text(x.max())})"


def _ratio_text(x: float) -> str:
    """Two decimals, or two significant digits below 0.1, so that a slow path
    (e.g. a sanitizer build's) reads 0.004 rather than 0.00."""
    return f"{x:.2f}" if x >= 0.1 else f"{x:.2g}"


def _trace_table(res: Results, w: str) -> list[str]:
    """One workload: per scene, method and K, Embree's rate and every path's
    rate and speed against Embree's."""
    groups = [g for scene in res.scenes for m in res.methods for k in res.ks(m)
              if (g := res.get(scene, w, m, k)) is not None and g.has_embree()]
    paths = [(c, label) for c, label in TRACE_PATHS
             if any(r.get(c) for g in groups for r in g.rows)]
    head = "| scene | method | K | rays | Embree Mray/s |"
    head += "".join(f" {label} Mray/s | {label} × Embree speed |" for _, label in paths)
    out = ["", f"## {w.capitalize()} rays", "",
           head + " steps/ray | box tests/ray | tests/ray | wrong hits | grazing |",
           "|---|---|---:|---:|---:|" + "---:|---:|" * len(paths) + "---:|---:|---:|---:|---:|"]
    for g in groups:
        fields = [scene_label(g.scene), g.method, "" if g.k is None else str(g.k),
                 f"{int(g.rows[0]['rays']):,}", _f(_mrays(g, "embree_s"), "{:.2f}")]
        for i, (column, _) in enumerate(paths):
            # Bold: the first path shown, hits-only single rays where measured
            # (the figure the issue's targets are about), else the counters'.
            fields += [_f(_mrays(g, column), "{:.2f}"), _speed_field(g, column, i == 0)]
        grazing = sum(int(r["grazing"]) for r in g.rows)
        fields += [f"{g.mean('steps'):.1f}", _f(box_tests(g), "{:.1f}"),
                   f"{g.mean('tests'):.2f}", str(wrong_hits(g)), str(grazing)]
        out.append("| " + " | ".join(fields) + " |")
    return out


def box_tests(g: Group) -> float | None:
    """Ray-box tests per ray (a BVH's counter; 0 on kd and BSP trees), None
    in rows from before the counter."""
    values = [r.get("box_tests") for r in g.rows]
    return None if any(v in ("", None) for v in values) else g.mean("box_tests")


# The bench spec's normal-based ^Kd trees, of which the side-by-side table
# shows the fastest per scene and workload.
BEST_KD_METHODS = ("bsp_wn+kd", "bsp_cn+kd")

SIDE_BY_SIDE = ("The three structures on one kernel against Embree: kd, the faster of the "
                "normal-based ^Kd trees (`best ^Kd`, chosen per scene and rays by its "
                "hits-only time) and the BVH (`bvh`: binned SAH, 8-wide nodes, no K), each traced "
                "on the hits-only single-ray path in the same rounds as Embree. `× Embree "
                "speed` is Embree's time over the tree's (above 1: faster than Embree); "
                "`kd ÷ BVH` and `best ÷ BVH` the per-round time ratios to the BVH (above 1: "
                "the BVH is faster), the structure's share of the gap, since the kernel is "
                "the same; steps, box tests and triangle tests are per ray. "
                "`docs/verdict.md` splits the gap into structure and kernel.")


GIVEN_ORDER = ("The kd and BSP trees' hits-only path traces a batch of incoherent rays "
               "sorted by their origins and directions (`ray_order=\"auto\"`, the default, for random "
               "rays in the scene's box, whose walks are long enough to pay for the sort; "
               "core/src/trace/ray_order.hpp), then returns the hits in the caller's order; "
               "Embree traces the rays as given. `kd × Embree speed, given order` is kd's "
               "hits-only path on the same rays kept in the given order "
               "(`ray_order=\"given\"`), timed in the same rounds; `kd ÷ BVH` and "
               "`best ^Kd ÷ BVH` are taken in the given order for both trees, so that "
               "the structures are compared on one walk without the sort.")


def _speed(g: Group, column: str) -> float | None:
    x = g.per_round("embree_s", column)
    return None if x is None else float(np.median(x))


def _time_ratio(a: Group, b: Group, column: str, column_b: str | None = None) -> float | None:
    """Median of the per-round ratios of `a`'s time over `b`'s, both taken
    from their rounds' Embree partners (each tree's trial has its own rounds:
    a's time / its Embree over b's time / its Embree); `b`'s from `column_b`
    when given."""
    ra, rb = a.per_round(column, "embree_s"), b.per_round(column_b or column, "embree_s")
    if ra is None or rb is None:
        return None
    return float(np.median(ra) / np.median(rb))


def side_by_side_table(res: Results, w: str, explain: bool = True) -> list[str]:
    """Per scene: kd, the best ^Kd tree and the BVH against Embree on `w`'s
    rays, with the columns' explanation when `explain`; [] when the run has
    no BVH or no kd."""
    column = next((c for c, _ in TRACE_PATHS
                   if any(r.get(c) for g in res.groups.values() for r in g.rows)), "trace_s")
    # Random rays are also timed in the caller's order (tracers.py): kd's
    # speed then shows beside the spatial order's.
    given = any(r.get("given_order_s") for g in res.groups.values() if g.workload == w
                for r in g.rows)
    out = []
    for scene in res.scenes:
        kd, bvh = res.kd(scene, w), res.get(scene, w, "bvh", None)
        if kd is None or bvh is None or not (kd.has_embree() and bvh.has_embree()):
            continue
        best = [g for m in BEST_KD_METHODS for k in res.ks(m)
                if (g := res.get(scene, w, m, k)) is not None and g.has_embree()]
        best_g = max(best, key=lambda g: _speed(g, column) or 0.0) if best else None
        fields = [scene_label(scene), f"{kd.triangles:,}", _f(_mrays(kd, "embree_s"), "{:.2f}")]
        fields.append(_f(_speed(kd, column), "{:.2f}"))
        if given:
            fields.append(_f(_speed(kd, "given_order_s"), "{:.2f}"))
        for g in (best_g, bvh):
            fields.append("—" if g is None else _f(_speed(g, column), "{:.2f}"))
        # The structures' ratio on one walk: both trees in the given order.
        ours = "given_order_s" if given else column
        fields += [_f(_time_ratio(kd, bvh, ours), "{:.2f}"),
                   "—" if best_g is None else f"{best_g.method} {best_g.k}: "
                   + _f(_time_ratio(best_g, bvh, ours), "{:.2f}")]
        fields += [" / ".join("—" if g is None else f"{g.mean('steps'):.1f}"
                              for g in (kd, best_g, bvh)),
                   _f(box_tests(bvh), "{:.1f}"),
                   " / ".join("—" if g is None else f"{g.mean('tests'):.2f}"
                              for g in (kd, best_g, bvh)),
                   str(wrong_hits(bvh))]
        out.append("| " + " | ".join(fields) + " |")
    if not out:
        return []
    label = dict(TRACE_PATHS).get(column, column)
    given_head = " kd × Embree speed, given order |" if given else ""
    return (["", f"## {w.capitalize()} rays: kd, the best ^Kd and the BVH against Embree "
             f"({label})", ""] + ([SIDE_BY_SIDE, ""] if explain else []) +
            ([GIVEN_ORDER, ""] if given else []) + [
             "| scene | triangles | Embree Mray/s | kd × Embree speed |" + given_head +
             " best ^Kd × Embree "
             "speed | BVH × Embree speed | kd ÷ BVH time | best ^Kd ÷ BVH time | steps/ray kd "
             "/ best / BVH | BVH box tests/ray | tests/ray kd / best / BVH | BVH wrong hits |",
             "|---|---:|---:|---:|" + ("---:|" if given else "") +
             "---:|---:|---:|---:|---:|---:|---:|---:|"] + out)


def benchmark_markdown(rows: list[dict], command: str, meta: dict | None = None) -> str:
    """docs/benchmark.md: build and trace of each method against Embree, and
    kd, the best ^Kd tree and the BVH side by side."""
    res = Results(rows)
    out = _header("Benchmark: BSP Lab trees vs Embree", command, meta, BENCH_COLUMNS)
    out += _build_table(res)
    for i, w in enumerate(res.workloads):
        out += side_by_side_table(res, w, explain=i == 0)
    for w in res.workloads:
        out += _trace_table(res, w)
    return "\n".join(out) + "\n"


def family_markdown(rows: list[dict], command: str, meta: dict | None = None) -> str:
    """docs/bsp_benchmark.md: every method and K against kd and Embree."""
    res = Results(rows)
    out = _header("Benchmark: the BSP family against kd and Embree", command, meta,
                  FAMILY_COLUMNS)
    out += scope_lines(res)
    out += ["## Per scene and workload", ""] + summary_tables(res)
    out += ["## Kd and BSP nodes (the thesis's table 5.10 shape)", ""] + node_tables(res)
    return "\n".join(out) + "\n"


def scope_lines(res: Results) -> list[str]:
    """What the run covered: its scenes and K (the spec's full range, K = 3..10,
    takes hours on two cores, so the docs page usually runs a subset)."""
    ks = sorted({k for m in res.methods for k in res.ks(m) if k is not None})
    return [f"Scope: {', '.join(scene_label(s) for s in res.scenes)}; K = "
            f"{', '.join(map(str, ks))}; {len(res.methods)} methods. `make bench-family` runs "
            "the spec's full K = 3..10 (about 400 trees, hours on the 2-core machine).", ""]


def cull_markdown(rows: list[dict], command: str, meta: dict | None = None) -> str:
    """docs/cull_benchmark.md: leaf culling on against off on the same tree."""
    from .spec import variant_label
    res = Results(rows)
    out = _header("Benchmark: leaf culling with the ray segment's box", command, meta,
                  CULL_COLUMNS)
    cols = [w for w in ("primary", "ao") if w in res.workloads] or res.workloads
    head = "| scene | method | K | options | box MiB |"
    rule = "|---|---|---:|---|---:|"
    for w in cols:
        head += f" {w}: tests off → on | fewer tests | time on/off |"
        rule += "---|---:|---:|"
    out += [head + " answers differ |", rule + "---:|"]
    for g0 in res.groups.values():
        if g0.workload != cols[0]:
            continue
        line = (f"| {scene_label(g0.scene)} | {g0.method} | {'' if g0.k is None else g0.k} | "
                f"{variant_label(g0.variant)} | {g0.mean('box_bytes') / 2**20:.1f} |")
        differs = 0
        for w in cols:
            g = res.get(g0.scene, w, g0.method, g0.k, g0.variant)
            off, on = g.mean("tests"), g.mean("cull_tests")
            paired = [a / b for r in g.rows for a, b in zip(parse_times(r["cull_s"]),
                                                            parse_times(r["trace_s"]))]
            differs += sum(int(r["cull_differs"]) for r in g.rows)
            line += (f" {off:.2f} → {on:.2f} | {(1 - on / off) * 100 if off else 0:.0f} % | "
                     f"**{np.median(paired):.2f}** |")
        out.append(line + f" {differs} |")
    return "\n".join(out) + "\n"


def _value_and_spread(fit: dict, key: str) -> str:
    lo, hi = fit["spread"][key]
    return f"{key} {fit[key]:.3f} (IQR {lo:.3f} .. {hi:.3f})"


def calibration_lines(fit: dict) -> list[str]:
    """The fitted costs, one per line, as `python -m bsplab calibrate` prints
    them: each value with its interquartile range over resampled rounds, then the
    fit's quality and whether the builders' ratios are stable."""
    spread = fit.get("spread", {})
    out = []
    for key, value in fit.items():
        if key == "by_workload":
            out += [f"  {w}: " + ", ".join(_value_and_spread(f, k) for k in
                                           ("intersect_per_kd", "general_per_kd", "ns_kd_step"))
                    + f", r2 {f['r2']:.3f}" for w, f in value.items()]
            continue
        if key == "spread":
            continue
        if key in spread:
            lo, hi = spread[key]
            out.append(f"  {key:18} {value:.3f}   (IQR {lo:.3f} .. {hi:.3f})")
        elif isinstance(value, bool):
            out.append(f"  {key:18} {'yes' if value else 'no'}")
        elif isinstance(value, float):
            out.append(f"  {key:18} {value:.3f}")
        else:
            out.append(f"  {key:18} {value}")
    return out

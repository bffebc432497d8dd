"""Reports of experiment results: Markdown tables in the shape of the source
thesis's tables 5.1-5.10 (per method, rows K, columns scene x min/med/max of
the render time as a percentage of the kd-tree's; Kd/BSP node counts), a
summary per scene with ratios to kd and to Embree, and PNG plots.

Every time is first divided by Embree's time on the same rays measured right
beside it in the same cell (a paired ratio, which cancels most of a shared
machine's drift), then by the kd-tree's median of the same ratio."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .method_table import METHODS


@dataclass
class Group:
    """All rows of one (scene, workload, method, K): seeds and repetitions."""
    scene: str
    workload: str
    method: str
    k: int | None
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
            t = [float(x) for x in r["trace_s"].split()]
            e = [float(x) for x in r["embree_s"].split()] if r["embree_s"] else []
            out += [a / b for a, b in zip(t, e)] if len(e) == len(t) else t
        return np.array(out)

    def paired_with_kd(self) -> np.ndarray | None:
        """Per repetition: our time / the kd-tree's, traced right beside it."""
        out = []
        for r in self.rows:
            t = [float(x) for x in r["trace_s"].split()]
            k = [float(x) for x in r.get("kd_s", "").split()]
            if len(k) != len(t):
                return None
            out += [a / b for a, b in zip(t, k)]
        return np.array(out)

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
        key = (r["scene"], r["workload"], r["method"], _k(r["k"]))
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

    def get(self, scene, workload, method, k) -> Group | None:
        return self.groups.get((scene, workload, method, k))

    def kd(self, scene, workload) -> Group | None:
        return self.get(scene, workload, "kd", None)

    def pct_of_kd(self, g: Group) -> np.ndarray | None:
        """Render time as % of kd's, per repetition (the thesis's measure):
        against the kd traces paired with ours in the same cell, or else
        through Embree's paired times and the kd cell's median."""
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
                    wrong = sum(int(r["unexplained"]) for r in g.rows if r["unexplained"] != "")
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


def _method_k_tables(res: Results, title, column_names, cells_of) -> list[str]:
    """Per method but kd: a table with rows K and, per scene, the columns
    `column_names` filled by cells_of(group) (None: no such tree)."""
    out = []
    names = [scene_label(s) for s in res.scenes]
    for m in res.methods:
        if m == "kd":
            continue
        out += [f"#### {METHODS[m].label} (`{m}`): {title}", "",
                "| K | " + " | ".join(f"{n} {c}" for n in names for c in column_names) + " |",
                "|---:|" + "---:|" * (len(column_names) * len(names))]
        for k in res.ks(m):
            cells = []
            for s in res.scenes:
                row = cells_of(s, m, k)
                cells += ["—"] * len(column_names) if row is None else row
            out.append(f"| {'' if k is None else k} | " + " | ".join(cells) + " |")
        out.append("")
    return out


def thesis_tables(res: Results, workload: str) -> list[str]:
    """Tables 5.1-5.9: per method, rows K, columns scene x min/med/max (% of kd)."""
    def cells(scene, method, k):
        g = res.get(scene, workload, method, k)
        p = res.pct_of_kd(g) if g else None
        return None if p is None else [f"{p.min():.1f}", f"{np.median(p):.1f}", f"{p.max():.1f}"]
    return _method_k_tables(res, f"render time as % of kd, {workload} rays",
                            ("min", "med", "max"), cells)


def node_tables(res: Results) -> list[str]:
    """Table 5.10: kd vs general (BSP) node counts per method and K."""
    def cells(scene, method, k):
        g = res.get(scene, res.workloads[0], method, k)
        if g is None:
            return None
        a, b = int(g.mean("kd_nodes")), int(g.mean("general_nodes"))
        return [f"{a:,}", f"{b:,}", f"{a + b:,}"]
    return _method_k_tables(res, "interior nodes, Kd / BSP / total", ("Kd", "BSP", "total"),
                            cells)


def markdown(rows: list[dict], title: str = "Experiment results", meta: dict | None = None,
             plots: list[Path] | None = None, relative_to: Path | None = None) -> str:
    res = Results(rows)
    out = [f"# {title}", ""]
    if meta:
        run = meta.get("runs", [{}])[-1]
        mach = run.get("machine", {})
        out += [f"Machine: {mach.get('cpu', '?')}, {mach.get('cores', '?')} cores; "
                f"versions {mach.get('versions', {})}. Spec fingerprint "
                f"`{meta.get('fingerprint', '?')}`.", ""]
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
# Plots


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _grid(plt, n: int):
    cols = min(n, 4)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.4 * rows), squeeze=False)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    return fig, list(axes.flat)


def _save(plt, fig, axes, drawn: bool, title: str, path: Path) -> Path | None:
    """One legend under the panels (each label once, whichever panel has it)."""
    if not drawn:
        plt.close(fig)
        return None
    legend = {}
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            legend.setdefault(lab, h)
    fig.legend(list(legend.values()), list(legend), loc="lower center",
               ncol=min(5, len(legend)), fontsize=8, bbox_to_anchor=(0.5, 0.0))
    fig.suptitle(title)
    fig.tight_layout(rect=(0, 0.1, 1, 0.95))
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _method_series(res: Results, scene: str, workload: str, value) -> dict:
    series = {}
    for m in res.methods:
        pts = []
        for k in res.ks(m):
            g = res.get(scene, workload, m, k)
            if g is None or k is None:
                continue
            v = value(g)
            if v is not None:
                pts.append((k, v))
        if pts:
            series[m] = pts
    return series


def _plot_vs_k(res: Results, workload: str, value, ylabel: str, title: str, path: Path,
               kd_line: float | None = 100.0) -> Path | None:
    plt = _pyplot()
    fig, axes = _grid(plt, len(res.scenes))
    drawn = False
    for ax, scene in zip(axes, res.scenes):
        series = _method_series(res, scene, workload, value)
        for m, pts in series.items():
            ks, vs = zip(*pts)
            style = "-o" if len(pts) > 1 else "o"
            ax.plot(ks, vs, style, label=m, markersize=4,
                    color=f"C{res.methods.index(m) % 10}")
            drawn = True
        for m in res.methods:  # methods without K (BSP_IZE) as dotted levels
            g = res.get(scene, workload, m, None)
            if m != "kd" and g is not None and value(g) is not None:
                ax.axhline(value(g), lw=1.0, ls=":", color=f"C{res.methods.index(m) % 10}",
                           label=m)
                drawn = True
        kd = res.kd(scene, workload)
        if kd is not None and kd_line is not None:
            ax.axhline(kd_line if kd_line != "value" else value(kd), color="k", lw=0.8,
                       ls="--", label="kd")
        ax.set_title(scene_label(scene), fontsize=10)
        ax.set_xlabel("K")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    return _save(plt, fig, axes, drawn, title, path)


def _plot_levels(res: Results, path: Path, key: str, ylabel: str, title: str) -> Path | None:
    """A per-level count (split planes, distinct directions; thesis figs. 2.1 and 3.1)."""
    plt = _pyplot()
    fig, axes = _grid(plt, len(res.scenes))
    w = res.workloads[0]
    drawn = False
    for ax, scene in zip(axes, res.scenes):
        for m in res.methods:
            ks = [k for k in res.ks(m) if res.get(scene, w, m, k)]
            if not ks:
                continue
            k = ks[len(ks) // 2]  # the middle K of the sweep
            g = res.get(scene, w, m, k)
            dirs = g.levels(key)
            if dirs:
                ax.semilogy(range(len(dirs)), np.maximum(dirs, 1),
                            label=f"{m}" + ("" if k is None else f" K={k}"))
                drawn = True
        ax.set_title(scene_label(scene), fontsize=10)
        ax.set_xlabel("tree level")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    return _save(plt, fig, axes, drawn, title, path)


def plots(rows: list[dict], out_dir, prefix: str = "") -> list[Path]:
    """PNG plots: time vs K, tests and steps per ray, build time, per-level directions."""
    res = Results(rows)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    made = []

    def pct(g):
        p = res.pct_of_kd(g)
        return None if p is None else float(np.median(p))

    for w in res.workloads:
        made.append(_plot_vs_k(res, w, pct, "render time, % of kd",
                               f"Render time vs K ({w} rays; 100 = kd)",
                               out_dir / f"{prefix}time_{w}.png"))
        made.append(_plot_vs_k(res, w, lambda g: g.mean("tests"), "tests per ray",
                               f"Triangle tests per ray ({w} rays; dashed: kd)",
                               out_dir / f"{prefix}tests_{w}.png", kd_line="value"))
        made.append(_plot_vs_k(res, w, lambda g: g.mean("steps"), "steps per ray",
                               f"Node steps per ray ({w} rays; dashed: kd)",
                               out_dir / f"{prefix}steps_{w}.png", kd_line="value"))
    made.append(_plot_vs_k(res, res.workloads[0], res.build_x_kd, "build time, × kd",
                           "Build time vs K (1 = kd)", out_dir / f"{prefix}build.png",
                           kd_line=1.0))
    made.append(_plot_levels(res, out_dir / f"{prefix}levels_directions.png",
                             "level_directions", "distinct split directions",
                             "Distinct split directions per tree level (middle K)"))
    made.append(_plot_levels(res, out_dir / f"{prefix}levels_planes.png", "level_planes",
                             "split planes", "Split planes per tree level (middle K)"))
    return [p for p in made if p is not None]

"""PNG plots of experiment results (matplotlib, imported only when plotting):
time, tests and steps against K per scene, build time, and per-level counts."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .report import Results, scene_label


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

# SPDX-License-Identifier: GPL-3.0-or-later
"""Turn a run's statistics into the rows the panel (and the demo) show.

Pure Python: no bpy, so the headless demo prints the very same table.
The statistics are a dict of sections: `scene`, `build` (the tree's
`stats`), `render` (the render's stats) and `embree` (the comparison).
"""

import math
import textwrap

# Characters per line of a warning in the sidebar at its default width.
WARNING_WIDTH = 24


def _seconds(value):
    if value is None:
        return "-"
    if value < 1e-3:
        return "{:.0f} µs".format(value * 1e6)
    if value < 1.0:
        return "{:.1f} ms".format(value * 1e3)
    return "{:.2f} s".format(value)


def _count(value):
    if value is None:
        return "-"
    return "{:,}".format(int(value))


def _bytes(value):
    if value is None:
        return "-"
    value = float(value)
    for unit in ("B", "KiB", "MiB", "GiB"):
        if value < 1024.0 or unit == "GiB":
            return "{:.1f} {}".format(value, unit) if unit != "B" else "{:.0f} B".format(value)
        value /= 1024.0
    return "-"


def _rate(value):
    if value is None:
        return "-"
    for scale, suffix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if value >= scale:
            return "{:.2f} {}".format(value / scale, suffix)
    return "{:.0f}".format(value)


def _number(value, digits=2):
    if value is None:
        return "-"
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    return "{:.{}f}".format(value, digits)


def _agreement(embree):
    """The fraction of rays whose hits agree, whatever key the core used."""
    compare = embree.get("compare") or {}
    for key in ("agreement", "prim_agreement", "hit_agreement", "match_fraction"):
        if isinstance(compare.get(key), (int, float)):
            return compare[key]
    return None


def _tree_origin(build):
    """"reused" when the press re-used the previous press's tree (whose
    statistics, build time included, the rows then show), "new" when it
    built one; "-" for statistics from before the cache."""
    if "reused" not in build:
        return "-"
    return "reused" if build["reused"] else "new"


def embree_rows(embree):
    if not embree:
        return []
    if not embree.get("available", False):
        return [("Embree", embree.get("message", "not available"))]
    rows = [
        ("Embree Trace", _seconds(embree.get("embree_seconds"))),
        ("BSP Lab Trace", _seconds(embree.get("bsplab_seconds"))),
        ("Time Ratio", "{}x Embree".format(_number(embree.get("time_ratio")))),
    ]
    if "embree_reused" in embree:
        rows.append(("Embree Scene", "reused" if embree["embree_reused"] else "new"))
    compare = embree.get("compare") or {}
    agreement = _agreement(embree)
    if agreement is not None:
        rows.append(("Agreement", "{:.4%}".format(agreement)))
    if "rays" in compare and "agree" in compare:
        rows.append(("Disagreeing", _count(compare["rays"] - compare["agree"])))
        rows.append(("At Edges", _count(compare.get("grazing"))))
    if agreement is None:
        for key, value in sorted(compare.items()):
            if isinstance(value, (int, float)):
                rows.append((key.replace("_", " ").title(), _number(value, 4)))
    return rows


def sections(stats):
    """[(title, [(label, text), ...]), ...] for the statistics box.

    One short value per row: the sidebar is narrow.
    """
    if not stats:
        return []
    scene = stats.get("scene", {})
    build = stats.get("build", {})
    render = stats.get("render", {})
    out = [
        ("Scene", [
            ("Triangles", _count(scene.get("triangles"))),
            ("Objects", _count(scene.get("objects"))),
            ("Instances", _count(scene.get("instances"))),
        ]),
        ("Build", [
            ("Method", str(build.get("method", "-"))),
            ("Tree", _tree_origin(build)),
            ("Build Time", _seconds(build.get("build_seconds"))),
            ("Fingerprint", _seconds(build.get("fingerprint_seconds"))),
            ("Nodes", _count(build.get("nodes"))),
            ("Leaves", _count(build.get("leaves"))),
            ("Empty Leaves", _count(build.get("empty_leaves"))),
            ("Max Depth", _count(build.get("max_depth"))),
            ("Leaf Depth", _number(build.get("mean_leaf_depth"), 1)),
            ("Tris / Leaf", _number(build.get("mean_leaf_size"))),
            ("Max Leaf Tris", _count(build.get("max_leaf_size"))),
            ("References", _count(build.get("references"))),
            ("Duplication", "{}x".format(_number(build.get("duplication")))),
            ("Kd / General", "{} / {}".format(_count(build.get("kd_nodes")),
                                              _count(build.get("general_nodes")))),
            ("Memory", _bytes(build.get("bytes"))),
            ("Leaf Boxes", "{} ({})".format(build.get("leaf_boxes", "-"),
                                            _bytes(build.get("box_bytes")))),
        ]),
        ("Render", [
            ("Size", "{} x {}".format(render.get("width", "-"), render.get("height", "-"))),
            ("Render Time", _seconds(render.get("seconds"))),
            ("Rays/s", _rate(render.get("rays_per_second"))),
            ("Kernel", "{}{}".format(render.get("kernel", "-"),
                                     ", packets" if render.get("packets") else "")),
            ("Steps / Ray", _number(render.get("mean_steps"))),
            ("Tests / Ray", _number(render.get("mean_tests"))),
            ("Culled / Ray", _number(render.get("mean_culled")) if render.get("cull", True)
             else "off"),
            ("Hits", _count(render.get("hits"))),
        ]),
    ]
    embree = embree_rows(stats.get("embree"))
    if embree:
        out.append(("Embree", embree))
    return out


def warnings(stats):
    """The tree's warnings (a degenerate tree: one huge leaf, or a tree far
    too small for the scene), each as a sentence; [] when the tree is sound."""
    build = (stats or {}).get("build") or {}
    return [str(w) for w in build.get("warnings") or ()]


def warning_lines(warning, width=WARNING_WIDTH):
    """One warning wrapped into lines short enough for the sidebar; its head
    ("degenerate tree: ...") becomes a line of its own."""
    head, sep, rest = warning.partition(": ")
    if sep and len(head) < width:
        return [head[:1].upper() + head[1:] + ":"] + (textwrap.wrap(rest, width) or [])
    return textwrap.wrap(warning, width) or [warning]


def table(stats):
    """The statistics as plain text, one `label: value` line per row."""
    lines = []
    for title, rows in sections(stats):
        lines.append(title)
        width = max(len(label) for label, _ in rows)
        for label, text in rows:
            lines.append("  {:<{}}  {}".format(label, width, text))
        if title == "Build":
            for warning in warnings(stats):
                lines.append("  WARNING: {}".format(warning))
    return "\n".join(lines)

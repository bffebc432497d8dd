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
    rows = []
    if embree.get("structure"):
        rows += COMPARED_ROWS[embree["structure"]](embree)
    rows += [
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
        # The oracle's verdict on the disagreeing rays (bsplab.oracle.compare):
        # Embree's own errors apart from ours; rows for the keys present
        # (statistics from before the exact verdict have only grazing).
        for key, label in VERDICT_ROWS:
            if key in compare:
                rows.append((label, _count(compare[key])))
    if agreement is None:
        for key, value in sorted(compare.items()):
            if isinstance(value, (int, float)):
                rows.append((key.replace("_", " ").title(), _number(value, 4)))
    return rows


# The oracle's classes of disagreeing rays, as the panel names them: Embree
# exactly wrong where ours is the exact answer; ours within float rounding
# of an edge or of the segment's ends; ours exactly wrong; undecided.
VERDICT_ROWS = (("embree_wrong", "Embree Wrong"), ("grazing", "At Edges"),
                ("at_ends", "At Segment Ends"), ("bsplab_wrong", "BSP Lab Wrong"),
                ("undecided", "Undecided"))


def _flattened_rows(embree):
    """A two-level build's hits against Embree's on the flattened scene,
    matched by the triangle's index in it."""
    return [("Embree Traced", "flattened scene"),
            ("Embree Tris", _count(embree.get("embree_triangles"))),
            ("Hits Matched", "by flat triangle")]


def _same_triangles_rows(_embree):
    return [("Embree Traced", "same triangles")]


# What the Embree comparison compared, by the tree's kind (the comparison's
# "structure", jobs/embree_check.py), short enough for the sidebar.
COMPARED_ROWS = {"bsp": _same_triangles_rows, "bvh": _same_triangles_rows,
                 "two_level": _flattened_rows}


# What a tree is made of (the build statistics' "structure"), as the panel
# names it.
STRUCTURE_NAMES = {"bsp": "split planes", "bvh": "BVH (boxes)"}


def mesh_structure(build):
    """The structure of the trees that hold the triangles: a flat tree's own,
    a two-level build's mesh trees' ("mesh_structure")."""
    return build.get("mesh_structure", build.get("structure"))


def is_bvh(build):
    """Whether the rays step through BVH nodes (boxes, no split planes): a
    BVH, or a two-level build of BVH mesh trees."""
    return mesh_structure(build) == "bvh"


def _mesh_trees(build):
    """"2 built, 1 reused": what the press did with the mesh trees."""
    built, reused = build.get("mesh_trees_built"), build.get("mesh_trees_reused")
    if built is None or reused is None:
        return "-"
    return "{} built, {} reused".format(_count(built), _count(reused))


def _two_level_tree(build):
    """The Tree row of a two-level build: "reused" (nothing built), "top
    rebuilt" (every mesh tree re-used) or "new"."""
    if "reused" not in build:
        return "-"
    if build["reused"]:
        return "reused"
    if build.get("mesh_trees_built") == 0:
        return "top rebuilt"
    return "new"


def two_level_rows(build):
    """The Build rows of a two-level build: both levels, and what the
    flattened scene would hold."""
    structure = STRUCTURE_NAMES.get(build.get("mesh_structure"), "-")
    return [
        ("Built As", "two-level"),
        ("Method", str(build.get("method", "-"))),
        ("Build Quality", str(build.get("build_quality", "-"))),
        ("Structure", "BVH over {}".format(structure) if structure != "-" else "-"),
        ("Tree", _two_level_tree(build)),
        ("Mesh Trees", _mesh_trees(build)),
        ("Build Time", _seconds(build.get("build_seconds"))),
        ("Fingerprint", _seconds(build.get("fingerprint_seconds"))),
        ("Unique Meshes", _count(build.get("meshes"))),
        ("Instances", _count(build.get("instances"))),
        ("Top Nodes", _count(build.get("top_nodes"))),
        ("Top Memory", _bytes(build.get("top_bytes"))),
        ("Top Depth", _count(build.get("top_depth"))),
        ("Mesh Nodes", _count(build.get("bottom_nodes"))),
        ("Mesh Memory", _bytes(build.get("bottom_bytes"))),
        ("Memory", _bytes(build.get("bytes"))),
        ("Mesh Tris", _count(build.get("mesh_triangles"))),
        ("Flattened Tris", _count(build.get("instanced_triangles"))),
    ]


def flat_rows(build):
    """The Build rows of a flat tree. A BVH has no split planes, no kd or
    general nodes, no empty leaves and no duplicated references (each
    triangle is in one leaf): those rows are a kd or BSP tree's only, and a
    BVH shows its node layout's bytes instead."""
    bvh = is_bvh(build)
    rows = [
        ("Built As", "flatten"),
        ("Method", str(build.get("method", "-"))),
        ("Build Quality", str(build.get("build_quality", "-"))),
        ("Structure", STRUCTURE_NAMES.get(build.get("structure"), "-")),
        ("Tree", _tree_origin(build)),
        ("Build Time", _seconds(build.get("build_seconds"))),
        ("Fingerprint", _seconds(build.get("fingerprint_seconds"))),
        ("Nodes", _count(build.get("nodes"))),
        ("Leaves", _count(build.get("leaves"))),
    ]
    if not bvh:
        rows.append(("Empty Leaves", _count(build.get("empty_leaves"))))
    rows += [
        ("Max Depth", _count(build.get("max_depth"))),
        ("Leaf Depth", _number(build.get("mean_leaf_depth"), 1)),
        ("Tris / Leaf", _number(build.get("mean_leaf_size"))),
        ("Max Leaf Tris", _count(build.get("max_leaf_size"))),
        ("References", _count(build.get("references"))),
    ]
    if bvh:
        rows += [("SAH Cost", _number(build.get("sah_cost"))),
                 ("Memory", _bytes(build.get("bytes"))),
                 ("Node Bytes", _bytes(build.get("node_bytes")))]
    else:
        rows += [
            ("Duplication", "{}x".format(_number(build.get("duplication")))),
            ("Kd / General", "{} / {}".format(_count(build.get("kd_nodes")),
                                              _count(build.get("general_nodes")))),
            ("Memory", _bytes(build.get("bytes"))),
            ("Leaf Boxes", "{} ({})".format(build.get("leaf_boxes", "-"),
                                            _bytes(build.get("box_bytes")))),
        ]
    return rows


# The Build rows by the tree's kind (the build statistics' "structure").
BUILD_ROWS = {"bsp": flat_rows, "bvh": flat_rows, "two_level": two_level_rows}


def build_rows(build):
    """The Build section's rows; statistics without a "structure" (saved
    by an add-on before two-level builds) are a flat tree's."""
    return BUILD_ROWS.get(build.get("structure"), flat_rows)(build)


def render_rows(render, bvh):
    """The Render section's rows; a BVH's add its ray-box tests per ray."""
    rows = [
        ("Size", "{} x {}".format(render.get("width", "-"), render.get("height", "-"))),
        ("Render Time", _seconds(render.get("seconds"))),
        ("Rays/s", _rate(render.get("rays_per_second"))),
        ("Kernel", "{}{}".format(render.get("kernel", "-"),
                                 ", packets" if render.get("packets") else "")),
        ("Steps / Ray", _number(render.get("mean_steps"))),
    ]
    if bvh:
        rows.append(("Box Tests / Ray", _number(render.get("mean_box_tests"))))
    rows += [
        ("Tests / Ray", _number(render.get("mean_tests"))),
        ("Culled / Ray", _number(render.get("mean_culled")) if render.get("cull", True)
         else "off"),
        ("Hits", _count(render.get("hits"))),
    ]
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
        ("Build", build_rows(build)),
        ("Render", render_rows(render, is_bvh(build))),
    ]
    embree = embree_rows(stats.get("embree"))
    if embree:
        out.append(("Embree", embree))
    return out


def _ratio(a, b):
    """B / A as text; "-" when either is missing or A is 0."""
    if a is None or b is None or not a:
        return "-"
    return "{:.2f}".format(b / a)


def _mrays(render):
    rate = render.get("rays_per_second")
    return None if rate is None else rate / 1e6


# The A/B grid's rows: label, how to read the value of one tree's statistics
# (its "build", "render" and "embree" sections) and how to show it.
COMPARE_ROWS = (
    ("Build", lambda s: s["build"].get("build_seconds"), _seconds),
    ("Nodes", lambda s: s["build"].get("nodes"), _count),
    ("Memory", lambda s: s["build"].get("bytes"), _bytes),
    ("Steps/Ray", lambda s: s["render"].get("mean_steps"), _number),
    ("Boxes/Ray", lambda s: s["render"].get("mean_box_tests"), _number),
    ("Tests/Ray", lambda s: s["render"].get("mean_tests"), _number),
    ("Mray/s", lambda s: _mrays(s["render"]), _number),
    ("x Embree", lambda s: (s.get("embree") or {}).get("time_ratio"), _number),
)
# Rows shown only when A or B is a BVH: a kd or BSP tree tests no boxes.
BVH_ONLY_ROWS = ("Boxes/Ray",)


def tree_name(method, options):
    """A tree's method with its K, if it has one ("bsp_wn+kd K=4")."""
    k = (options or {}).get("k")
    return method if k is None else "{} K={}".format(method, k)


def compare_grid(stats):
    """The A/B comparison as (names, rows): names = (A's tree, B's tree) and
    rows = [(label, A, B, B/A), ...]; None when the run had no tree B.
    Sizes and counts of the same tree give a ratio of exactly 1; times are
    measured for each tree and vary."""
    if not stats or "b" not in stats:
        return None
    compare = stats.get("compare", {})
    a, b = stats, stats["b"]
    names = (tree_name(str(a["build"].get("method", "-")), compare.get("a_options")),
             tree_name(compare.get("b_method", b["build"].get("method", "-")),
                       compare.get("b_options")))
    rows = []
    any_bvh = is_bvh(a.get("build", {})) or is_bvh(b.get("build", {}))
    for label, value, show in COMPARE_ROWS:
        if label in BVH_ONLY_ROWS and not any_bvh:
            continue
        va, vb = value(a), value(b)
        rows.append((label, show(va), show(vb), _ratio(va, vb)))
    return names, rows


def compare_table(stats):
    """The A/B grid as plain text lines ([] without B)."""
    grid = compare_grid(stats)
    if grid is None:
        return []
    (name_a, name_b), rows = grid
    lines = ["A / B", "  A: {}".format(name_a), "  B: {}".format(name_b)]
    for row in [("", "A", "B", "B/A")] + rows:
        lines.append("  {:<10}{:>11}{:>11}{:>7}".format(*row))
    return lines


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
    return "\n".join(lines + compare_table(stats))

# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Ray Inspector" sub-panel: the pick and clear buttons, the inspected
ray's counts and its step-by-step list (of a two-level build: the top
level's steps, then each instance entered and the steps inside it)."""

from typing import NamedTuple

import bpy

from ..jobs import shown_build
from ..sidebar import BSPLabSubPanel
from ..state import STATE
from .operators import BSPLAB_OT_inspect_clear, BSPLAB_OT_inspect_pick

# Steps listed before "... N more": a kd ray on a big scene walks 50-100
# nodes, more than a sidebar shows usefully.
MAX_ROWS = 40
# The sidebar is narrow: the plane stands for the kind ("x = 0.5" is an x
# node), a leaf is "leaf", and the t range and counts are short.
STEP_HEADER = ("#", "node", "t range", "tests")


def hit_text(inspection, box):
    """The Hit row: the triangle and t, "none", or that the ray missed `box`."""
    totals = inspection["counts"]
    if inspection["missed_box"]:
        return "none: missed " + box
    if totals["hit_prim"] is None:
        return "none"
    return "{} at t {:.4g}".format(totals["hit_prim"], totals["hit_t"])


def node_count_row(totals, structure):
    """The row of the steps' node tests: a BVH has no general nodes, its
    steps test boxes; a kd or BSP tree's general steps."""
    if structure == "bvh":
        return ("Box Tests", str(totals["box_tests"]))
    return ("General", str(totals["general_steps"]))


def flat_count_rows(inspection):
    """(label, text) of one tree's walk's totals."""
    totals = inspection["counts"]
    hit = hit_text(inspection, "the tree box")
    return [
        ("Ray", inspection["source"]),
        ("Steps", "{} ({} leaves)".format(totals["steps"], totals["leaves"])),
        node_count_row(totals, inspection["structure"]),
        ("Tests", str(totals["tests"])),
        ("Culled", str(totals["culled"])),
        ("Hit", hit),
        ("Time", "{:.1f} ms".format(1000 * inspection["seconds"])),
    ]


def two_level_count_rows(inspection):
    """flat_count_rows() of a two-level walk: the top level's steps, the
    instances entered, the steps inside them (summed) and the hit's
    instance."""
    totals = inspection["counts"]
    hit = hit_text(inspection, "the scene's box")
    top_leaves = sum(1 for row in inspection["top_rows"] if row[1] == "leaf")
    rows = [
        ("Ray", inspection["source"]),
        ("Top Steps", "{} ({} leaves)".format(totals["top_steps"], top_leaves)),
        ("Instances", "{} entered".format(totals["instance_visits"])),
        ("Steps", "{} ({} leaves)".format(totals["steps"], totals["leaves"])),
        node_count_row(totals, inspection["mesh_structure"]),
        ("Tests", str(totals["tests"])),
        ("Hit", hit),
    ]
    if totals["hit_instance"] is not None:
        rows.append(("In", instance_text(inspection, totals["hit_instance"],
                                         totals["hit_mesh"])))
    rows.append(("Time", "{:.1f} ms".format(1000 * inspection["seconds"])))
    return rows


def instance_text(inspection, instance, mesh):
    """An instance as the panel names it (with the build's names)."""
    return shown_build.instance_text(instance, -1 if mesh is None else mesh,
                                     inspection.get("names"))


# The top level's step list: its nodes are boxes; a leaf lists its instances.
TOP_HEADER = ("#", "top node", "t range", "inst.")


def top_step_cells(row):
    """The texts of one top-level step (trace.top_rows)."""
    number, kind, t0, t1, instances = row
    return (str(number), kind, "{:.3g}-{:.3g}".format(t0, t1),
            ",".join(str(i) for i in instances))


def two_level_sections(inspection, limit=MAX_ROWS):
    """The two-level step lists as (title, header, rows of texts) sections:
    the top level's, then one per instance entered; at most `limit` rows in
    all, and how many more."""
    sections, left, more = [], limit, 0
    groups = [("Top level", TOP_HEADER, [top_step_cells(r) for r in inspection["top_rows"]])]
    for visit in inspection["visits"]:
        text = instance_text(inspection, visit["instance"], visit["mesh"])
        title = text[0].upper() + text[1:]
        groups.append((title + (" - hit" if visit["hit"] else ""), STEP_HEADER,
                       [step_cells(r) for r in visit["rows"]]))
    for title, header, rows in groups:
        if left <= 0:
            more += len(rows)
            continue
        sections.append((title, header, rows[:left]))
        more += max(0, len(rows) - left)
        left -= len(rows)
    return sections, more


def step_cells(row):
    """The texts of one step row (trace.step_rows)."""
    number, kind, plane, t0, t1, tests, culled = row
    tested = "" if kind != "leaf" else str(tests) + (" +{}c".format(culled) if culled else "")
    return (str(number), plane or kind, "{:.3g}-{:.3g}".format(t0, t1), tested)


def step_lines(inspection, limit=MAX_ROWS):
    """The step list's rows of texts, capped at `limit`, and how many more."""
    rows = inspection["rows"]
    return [step_cells(row) for row in rows[:limit]], max(0, len(rows) - limit)


def draw_step(layout, cells):
    """One row of the step list: the four texts in columns."""
    number, node, t_range, tests = cells
    split = layout.split(factor=0.12)
    split.label(text=number)
    split = split.split(factor=0.45)
    split.label(text=node)
    split = split.split(factor=0.75)
    split.label(text=t_range)
    split.label(text=tests)


class BSPLAB_PT_inspector(BSPLabSubPanel, bpy.types.Panel):
    bl_label = "Ray Inspector"

    def draw(self, context):
        layout = self.layout
        row = layout.row(align=True)
        row.operator(BSPLAB_OT_inspect_pick.bl_idname, text="Pick Ray", icon='EYEDROPPER')
        row.operator(BSPLAB_OT_inspect_clear.bl_idname, icon='X')
        inspection = STATE.inspection
        if inspection is None:
            layout.label(text="Pick a preview pixel or a viewport point", icon='INFO')
            return
        box = layout.box()
        col = box.column(align=True)
        for label, text in count_rows(inspection):
            split = col.split(factor=0.3)
            split.label(text=label)
            split.label(text=text)
        WALK_PANELS[inspection["structure"]].draw_steps(layout, inspection)


def draw_flat_steps(layout, inspection):
    """One tree's steps."""
    lines, more = step_lines(inspection)
    box = layout.box()
    col = box.column(align=True)
    for cells in [STEP_HEADER] + lines:
        draw_step(col, cells)
    if more:
        col.label(text="... {} more steps".format(more))


def draw_two_level_steps(layout, inspection):
    """The top level's steps, then each instance entered with its steps."""
    sections, more = two_level_sections(inspection)
    col = None
    for title, header, rows in sections:
        box = layout.box()
        col = box.column(align=True)
        col.label(text=title)
        for cells in [header] + rows:
            draw_step(col, cells)
    if more and col is not None:
        col.label(text="... {} more steps".format(more))


class WalkPanel(NamedTuple):
    """How the panel shows one kind of walk."""

    count_rows: object  # inspection -> [(label, text), ...]
    draw_steps: object  # (layout, inspection) -> None


# The panel by the inspected tree's kind (the inspection's "structure").
_FLAT = WalkPanel(flat_count_rows, draw_flat_steps)
WALK_PANELS = {"bsp": _FLAT, "bvh": _FLAT,
               "two_level": WalkPanel(two_level_count_rows, draw_two_level_steps)}


def count_rows(inspection):
    """(label, text) of the inspection's totals."""
    return WALK_PANELS[inspection["structure"]].count_rows(inspection)


classes = (BSPLAB_PT_inspector,)

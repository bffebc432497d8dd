# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Sweep K" sub-panel: the K sweep's settings, its button and the last
sweep's table (the plot is an image block)."""

import bpy

from ..sidebar import BSPLabSubPanel
from ..state import STATE
from . import experiment
from .operator import BSPLAB_OT_sweep_k


class BSPLAB_PT_sweep(BSPLabSubPanel, bpy.types.Panel):
    bl_label = "Sweep K"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        settings = context.scene.bsplab
        col = layout.column()
        col.prop(settings, "sweep_methods", text="")
        row = col.row(align=True)
        row.prop(settings, "sweep_k_min", text="K")
        row.prop(settings, "sweep_k_max", text="to")
        col.prop(settings, "sweep_repetitions")
        col.prop(settings, "sweep_workload")
        if STATE.job is None:
            col.operator(BSPLAB_OT_sweep_k.bl_idname, icon='GRAPH')
        table = settings.k_sweep_table
        if not table.get("methods"):
            return
        scene = table.get("scene", {})
        box = layout.box()
        box.label(text="{:,} triangles, {:,} {} rays".format(
            scene.get("triangles", 0), scene.get("rays", 0), scene.get("workload", "")))
        box.label(text="Time as % of kd (median of {})".format(scene.get("repetitions", "?")))
        for label, cells in table_rows(table):
            row = box.split(factor=0.4)
            row.label(text=label)
            sub = row.row()
            for text in cells:
                sub.label(text=text)
        box.label(text="Plot: image '{}'".format(experiment.PLOT_NAME), icon='IMAGE_DATA')


def table_rows(table):
    """(label, [% kd, tests/ray]) per method and K, for the panel."""
    rows = [("method (colour)", ["% kd", "tests"])]
    for m in table["methods"]:
        for p in m["points"]:
            k = "" if p["k"] is None else " K={}".format(p["k"])
            rows.append(("{}{} ({})".format(m["name"], k, m["colour"]),
                         ["{:.0f}".format(p["pct_kd"]), "{:.2f}".format(p["tests"])]))
    return rows


classes = (BSPLAB_PT_sweep,)

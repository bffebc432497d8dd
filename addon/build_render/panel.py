# SPDX-License-Identifier: GPL-3.0-or-later
"""Build & Render's panels: the main panel of the "BSP Lab" sidebar tab (the
method, its options, the render settings and the button or the running
job's progress) and its Statistics sub-panel."""

import bpy

from .. import backend, tree_options
from ..jobs.scene_reader import preview_size
from ..sidebar import MAIN_PANEL, BSPLabPanel, BSPLabSubPanel, draw_options
from ..state import STATE
from . import statistics
from .operator import BSPLAB_OT_build_render

# `UILayout.progress` was added in Blender 4.0; older versions get a
# read-only slider instead.
HAS_PROGRESS_BAR = "progress" in bpy.types.UILayout.bl_rna.functions


class BSPLAB_PT_main(BSPLabPanel, bpy.types.Panel):
    bl_label = "BSP Lab"
    bl_idname = MAIN_PANEL

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.bsplab

        if backend.bsplab_or_none() is None:
            box = layout.box()
            box.label(text="Core module 'bsplab' not installed", icon='ERROR')

        layout.prop(settings, "method")
        row = layout.row()
        row.prop(settings, "instances", expand=True)
        # Threads are drawn below with the render settings.
        draw_options(layout, settings, settings.method, tree_options.TREE_OPTIONS)

        layout.separator()
        col = layout.column()
        col.prop(settings, "preview_percentage", text="Preview")
        width, height = preview_size(context.scene.render, settings.preview_percentage)
        col.label(text="{} x {} px".format(width, height))
        col.prop(settings, "render_mode")
        if "threads" in tree_options.BUILD_OPTIONS:  # not without bsplab
            col.prop(settings, "threads")
        col.prop(settings, "cull")
        col.prop(settings, "count_steps")
        # Full width: the split layout would cut the checkbox's label short.
        row = layout.row()
        row.use_property_split = False
        row.prop(settings, "compare_with_embree")

        layout.separator()
        self.draw_button(context, layout)

    @staticmethod
    def draw_button(context, layout):
        job = STATE.job
        if job is None:
            layout.operator(BSPLAB_OT_build_render.bl_idname, icon='RENDER_STILL')
            return
        # Read from the job, not from a property: writing one every tick
        # would redraw all of Blender's editors.
        fraction = job.fraction()
        text = "{} {:.0%}".format(job.title, fraction)
        if HAS_PROGRESS_BAR:
            layout.progress(factor=fraction, type='BAR', text=text)
        else:
            layout.label(text=text, icon='TIME')
        layout.label(text="Esc to cancel")


def draw_compare_grid(layout, grid):
    """A, B and B/A side by side: four narrow columns fit the sidebar."""
    (name_a, name_b), rows = grid
    box = layout.box()
    box.label(text="A: " + name_a)
    box.label(text="B: " + name_b)
    flow = box.grid_flow(row_major=True, columns=4, even_columns=False, align=True)
    for cells in [("", "A", "B", "B/A")] + rows:
        for text in cells:
            flow.label(text=text)


class BSPLAB_PT_stats(BSPLabSubPanel, bpy.types.Panel):
    bl_label = "Statistics"

    def draw(self, context):
        layout = self.layout
        sections = statistics.sections(context.scene.bsplab.stats)
        if not sections:
            layout.label(text="Press Build & Render", icon='INFO')
            return
        grid = statistics.compare_grid(context.scene.bsplab.stats)
        if grid is not None:
            draw_compare_grid(layout, grid)
        for title, rows in sections:
            box = layout.box()
            box.label(text=title)
            col = box.column(align=True)
            for label, text in rows:
                row = col.split(factor=0.5)
                row.label(text=label)
                row.label(text=text)
            if title == "Build":
                # A degenerate tree (one huge leaf, or far too few nodes):
                # say so in red, wrapped to the sidebar's width.
                for warning in statistics.warnings(context.scene.bsplab.stats):
                    warn = box.column(align=True)
                    warn.alert = True
                    for i, line in enumerate(statistics.warning_lines(warning)):
                        warn.label(text=line, icon='ERROR' if i == 0 else 'BLANK1')


classes = (
    BSPLAB_PT_main,
    BSPLAB_PT_stats,
)

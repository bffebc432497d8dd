# SPDX-License-Identifier: GPL-3.0-or-later
"""The "BSP Lab" tab of the 3D Viewport's sidebar (N panel)."""

import bpy

from . import backend, camera, operators, properties, stats

# `UILayout.progress` was added in Blender 4.0; older versions get a
# read-only slider instead.
HAS_PROGRESS_BAR = "progress" in bpy.types.UILayout.bl_rna.functions


# The sidebar is narrow: the core's short labels instead of the properties' names.
SHORT_LABELS = {name: spec["short_label"] for name, spec in properties.OPTION_SCHEMA.items()}


class BSPLabPanel:
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "BSP Lab"


class BSPLAB_PT_main(BSPLabPanel, bpy.types.Panel):
    bl_label = "BSP Lab"
    bl_idname = "BSPLAB_PT_main"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.bsplab

        if backend.core_or_none() is None:
            box = layout.box()
            box.label(text="Core module 'bsplab' not installed", icon='ERROR')

        layout.prop(settings, "method")
        # Threads are drawn below with the render settings.
        draw_options(layout, settings, settings.method, properties.TREE_OPTIONS)

        layout.separator()
        col = layout.column()
        col.prop(settings, "preview_percentage", text="Preview")
        width, height = camera.preview_size(context.scene.render, settings.preview_percentage)
        col.label(text="{} x {} px".format(width, height))
        col.prop(settings, "render_mode")
        if "threads" in properties.BUILD_OPTIONS:  # not without the core
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
        job = operators.active_job()
        if job is None:
            layout.operator(operators.BSPLAB_OT_build_render.bl_idname, icon='RENDER_STILL')
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


def draw_options(layout, settings, method, names):
    """The method's build options among `names`, with the core's short labels."""
    params = backend.methods().get(method, {}).get("params", ())
    col = layout.column(align=True)
    for name in names:
        if name in params:
            col.prop(settings, name, text=SHORT_LABELS[name])


class BSPLAB_PT_compare(BSPLabPanel, bpy.types.Panel):
    """Tree B of the A/B comparison: its method, its options and the view."""

    bl_label = "Compare A/B"
    bl_idname = "BSPLAB_PT_compare"
    bl_parent_id = "BSPLAB_PT_main"
    bl_options = {'DEFAULT_CLOSED'}

    def draw_header(self, context):
        self.layout.prop(context.scene.bsplab_compare, "enabled", text="")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        compare = context.scene.bsplab_compare
        layout.active = compare.enabled
        layout.prop(compare, "method", text="B")
        draw_options(layout, compare, compare.method, properties.TREE_OPTIONS)
        layout.prop(compare, "view")


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


class BSPLAB_PT_stats(BSPLabPanel, bpy.types.Panel):
    bl_label = "Statistics"
    bl_idname = "BSPLAB_PT_stats"
    bl_parent_id = "BSPLAB_PT_main"

    def draw(self, context):
        layout = self.layout
        sections = stats.sections(context.scene.bsplab.stats)
        if not sections:
            layout.label(text="Press Build & Render", icon='INFO')
            return
        grid = stats.compare_grid(context.scene.bsplab.stats)
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
                for warning in stats.warnings(context.scene.bsplab.stats):
                    warn = box.column(align=True)
                    warn.alert = True
                    for i, line in enumerate(stats.warning_lines(warning)):
                        warn.label(text=line, icon='ERROR' if i == 0 else 'BLANK1')


class BSPLAB_PT_sweep(BSPLabPanel, bpy.types.Panel):
    bl_label = "Sweep K"
    bl_idname = "BSPLAB_PT_sweep"
    bl_parent_id = "BSPLAB_PT_main"
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
        if operators.active_job() is None:
            col.operator(operators.BSPLAB_OT_sweep_k.bl_idname, icon='GRAPH')
        table = settings.sweep
        if not table.get("methods"):
            return
        scene = table.get("scene", {})
        box = layout.box()
        box.label(text="{:,} triangles, {:,} {} rays".format(
            scene.get("triangles", 0), scene.get("rays", 0), scene.get("workload", "")))
        box.label(text="Time as % of kd (median of {})".format(scene.get("repetitions", "?")))
        for label, cells in sweep_rows(table):
            row = box.split(factor=0.4)
            row.label(text=label)
            sub = row.row()
            for text in cells:
                sub.label(text=text)
        box.label(text="Plot: image '{}'".format(sweep_plot_name()), icon='IMAGE_DATA')


def sweep_plot_name():
    from . import sweep
    return sweep.PLOT_NAME


def sweep_rows(table):
    """(label, [% kd, tests/ray]) per method and K, for the panel."""
    rows = [("method (colour)", ["% kd", "tests"])]
    for m in table["methods"]:
        for p in m["points"]:
            k = "" if p["k"] is None else " K={}".format(p["k"])
            rows.append(("{}{} ({})".format(m["name"], k, m["colour"]),
                         ["{:.0f}".format(p["pct_kd"]), "{:.2f}".format(p["tests"])]))
    return rows


classes = (
    BSPLAB_PT_main,
    BSPLAB_PT_compare,
    BSPLAB_PT_stats,
    BSPLAB_PT_sweep,
)

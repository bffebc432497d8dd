# SPDX-License-Identifier: GPL-3.0-or-later
"""The Sweep K operator: the K sweep (experiment.py) on the scene's own
triangles and camera, on a worker thread like Build & Render's job; the
table goes to `scene.bsplab.sweep_json`, the plot to its image block."""

import bpy

from ..jobs import preview
from ..jobs.job_operator import JobOperator
from ..jobs.scene_reader import read_camera_and_geometry
from ..jobs.worker import UserError
from . import experiment


def read_sweep(context, bsplab):
    """The K sweep's input, read from the scene; raise UserError if unusable."""
    scene = context.scene
    settings = scene.bsplab
    try:
        methods = experiment.parse_methods(settings.sweep_methods, bsplab.methods())
        experiment.plan(methods, bsplab.methods(), settings.sweep_k_min, settings.sweep_k_max)
    except experiment.KSweepError as ex:
        raise UserError(str(ex)) from ex
    cam, geometry = read_camera_and_geometry(context, bsplab)
    try:
        bsplab.check_triangles(geometry.triangles)
    except (TypeError, ValueError) as ex:
        raise UserError("BSP Lab cannot build the tree: {}".format(ex)) from ex
    return experiment.KSweepInput(
        triangles=geometry.triangles, camera=cam, methods=methods,
        k_min=settings.sweep_k_min, k_max=settings.sweep_k_max,
        repetitions=settings.sweep_repetitions, workload=settings.sweep_workload,
        scene_name=scene.name)


class BSPLAB_OT_sweep_k(JobOperator, bpy.types.Operator):
    """Build and trace every chosen method at every K of the range on this scene, beside kd and Embree; show the table and plot"""

    bl_idname = "bsplab.sweep_k"
    bl_label = "Sweep K"

    def make_job(self, context, bsplab):
        return experiment.KSweepJob(bsplab, read_sweep(context, bsplab))

    def apply(self, context, scene, job):
        scene.bsplab.sweep_json = experiment.table_json(job.result)
        preview.write_preview(job.result["plot"], name=experiment.PLOT_NAME)
        table = job.result["table"]
        best = min(((p["pct_kd"], m["name"], p["k"]) for m in table["methods"]
                    if m["name"] != "kd" for p in m["points"]), default=None)
        message = "BSP Lab Sweep K: {} trees".format(
            sum(len(m["points"]) for m in table["methods"]))
        if best is not None:
            message += "; fastest {}{} at {:.0f}% of kd's time".format(
                best[1], "" if best[2] is None else " K={}".format(best[2]), best[0])
        self.report({'INFO'}, message)
        return {'FINISHED'}


classes = (BSPLAB_OT_sweep_k,)

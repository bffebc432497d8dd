# SPDX-License-Identifier: GPL-3.0-or-later
"""The Build & Render operator: build the tree of the visible meshes (or
re-use the kept one) on a worker thread, render the scene camera's view,
show it in the preview image and the statistics in the panel.
"""

import json

import bpy

from .. import backend
from ..compare import images as compare_images
from ..drawing import legend
from ..jobs import preview, shown_build
from ..jobs.job_operator import JobOperator
from ..jobs.messages import check_result
from ..jobs.worker import UserError
from ..state import STATE
from .job import Job
from .scene_input import read_scene


def preview_image(result):
    """The render, and for a heat map its colour bar (0 .. the largest count,
    and the unit). A bsplab older than the add-on may lack the maximum (the
    legacy add-on runs on a separately installed bsplab): then the bar is left
    out rather than the render lost."""
    render = result["stats"]["render"]
    if "b" in result["stats"]:
        return compare_images.preview(result["image"], result["b_image"], result.get("counts"),
                                      render["mode"], result["stats"]["compare"]["view"],
                                      backend.heat_ramp())
    try:
        return legend.with_heat_bar(result["image"], render["mode"], render,
                                    backend.heat_ramp())
    except ValueError as ex:
        print("BSP Lab: preview without its colour bar:", ex)
        return result["image"]


def apply_result(scene, result):
    preview.write_preview(preview_image(result))
    scene.bsplab.stats_json = json.dumps(result["stats"])


class BSPLAB_OT_build_render(JobOperator, bpy.types.Operator):
    """Build the tree of the visible meshes and render the scene camera's view with it"""

    bl_idname = "bsplab.build_render"
    bl_label = "Build & Render"

    def make_job(self, context, bsplab):
        inp = read_scene(context, bsplab)
        if inp.b is None:
            STATE.tree_cache_b.clear()  # no B: don't hold its memory
        job = Job(bsplab, inp, cache=STATE.tree_cache, cache_b=STATE.tree_cache_b)
        shown_build.mark_job(job, context.view_layer)
        return job

    def apply(self, context, scene, job):
        try:
            check_result(job.result)
        except UserError as ex:
            return self._fail(str(ex))
        try:
            apply_result(scene, job.result)
        except ValueError as ex:  # an A/B preview too narrow for its split
            return self._fail("BSP Lab cannot show the preview: {}".format(ex))
        shown_build.record(scene, job, bpy.data.images[preview.IMAGE_NAME])
        stats = job.result["stats"]
        self.report({'INFO'}, build_report(stats) + b_report(stats))
        return {'FINISHED'}


def build_report(stats):
    """The status bar's line of a finished Build & Render (without B's part)."""
    build = stats["build"]
    seconds = build.get("build_seconds") or 0.0
    rendered = ", rendered in {:.3f} s".format(stats["render"].get("seconds", 0.0))
    return BUILD_REPORTS[build["structure"]](stats, build, seconds, rendered)


def two_level_report(stats, build, seconds, rendered):
    if build.get("reused"):
        built = "reused (built in {:.3f} s by an earlier press)".format(seconds)
    else:
        built = "built in {:.3f} s: {} mesh trees built, {} reused".format(
            seconds, build.get("mesh_trees_built", "?"), build.get("mesh_trees_reused", "?"))
    return ("BSP Lab: two-level, {} instances of {} meshes ({} triangles flattened), "
            "top level {} nodes, {}{}").format(
                build.get("instances", "?"), build.get("meshes", "?"),
                stats["scene"]["triangles"], build.get("top_nodes", "?"), built, rendered)


def flat_report(stats, build, seconds, rendered):
    built = ("tree reused (built in {:.3f} s by an earlier press)" if build.get("reused")
             else "built in {:.3f} s").format(seconds)
    return "BSP Lab: {} triangles, {} nodes, {}{}".format(
        stats["scene"]["triangles"], build.get("nodes", "?"), built, rendered)


# The status bar's line by the tree's kind (the build statistics' "structure").
BUILD_REPORTS = {"bsp": flat_report, "bvh": flat_report, "two_level": two_level_report}


def _flat_nodes(build):
    return build.get("nodes", "?")


def _top_nodes(build):
    return "{} top".format(build.get("top_nodes", "?"))


# B's node count in the report, by its kind: a two-level build's top level.
NODE_COUNTS = {"bsp": _flat_nodes, "bvh": _flat_nodes, "two_level": _top_nodes}


def b_report(stats):
    """The A/B part of Build & Render's report ("" without B)."""
    if "b" not in stats:
        return ""
    build = stats["b"]["build"]
    nodes = NODE_COUNTS[build["structure"]](build)
    return "; B: {} nodes, {}, rendered in {:.3f} s".format(
        nodes, "tree reused" if build.get("reused") else
        "built in {:.3f} s".format(build.get("build_seconds", 0.0)),
        stats["b"]["render"].get("seconds", 0.0))


classes = (BSPLAB_OT_build_render,)

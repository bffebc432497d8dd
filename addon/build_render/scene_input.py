# SPDX-License-Identifier: GPL-3.0-or-later
"""Main thread: Build & Render's input (job.JobInput) out of the scene's
settings, tree B's (compare/) and the scene read by jobs/scene_reader.py."""

from ..jobs.messages import TWO_LEVEL_CULL_MESSAGE
from ..jobs.scene_reader import read_camera_and_geometry
from ..jobs.tree_run import TWO_LEVEL, TreeChoice
from ..jobs.worker import UserError
from .job import JobInput


def checked_choice(methods, settings, tree=""):
    """The TreeChoice of `settings` (A's or B's: a method and its options);
    raise UserError for an unknown method or a K outside the method's range.
    `tree` ("Tree B: ") starts the message."""
    method = settings.method
    if method not in methods:
        raise UserError("{}Unknown tree method '{}'".format(tree, method))
    info = methods[method]
    params = info.get("params", ())
    min_k, max_k = info.get("min_k"), info.get("max_k")
    if "k" in params and min_k is not None and not min_k <= settings.k <= max_k:
        raise UserError("{}K must be in {}..{} for {}, not {}".format(
            tree, min_k, max_k, info.get("label", method), settings.k))
    return TreeChoice(method, settings.build_options(params))


def read_tree_b(scene, methods):
    """Tree B's TreeChoice when "Compare with B" is on (compare/), else
    None. B is built with A's thread count."""
    compare = scene.bsplab_compare
    if not compare.enabled:
        return None
    choice = checked_choice(methods, compare, tree="Tree B: ")
    if "threads" not in methods[choice.method].get("params", ()):
        return choice
    return TreeChoice(choice.method, dict(choice.options, threads=scene.bsplab.threads))


def read_scene(context, bsplab):
    """Copy everything Build & Render's job needs out of bpy; raise UserError if unusable."""
    scene = context.scene
    settings = scene.bsplab
    methods = bsplab.methods()
    a = checked_choice(methods, settings)
    b = read_tree_b(scene, methods)
    two_level = settings.instances == TWO_LEVEL
    if two_level and (settings.cull or settings.render_mode == "heat_culled"):
        raise UserError(TWO_LEVEL_CULL_MESSAGE)
    cam, geometry = read_camera_and_geometry(context, bsplab, two_level)
    return JobInput(
        triangles=None if two_level else geometry.triangles,
        instanced=geometry if two_level else None,
        objects=geometry.objects,
        instances=geometry.instances,
        camera=cam,
        method=a.method,
        options=a.options,
        mode=settings.render_mode,
        threads=settings.threads,
        cull=settings.cull,
        compare_with_embree=settings.compare_with_embree,
        count_steps=settings.count_steps,
        scene_name=scene.name,
        b=b,
        compare_view=scene.bsplab_compare.view,
    )

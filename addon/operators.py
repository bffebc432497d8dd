# SPDX-License-Identifier: GPL-3.0-or-later
"""The Build & Render and Sweep K operators.

The work is split in three so that bpy data is only touched on the main
thread: `read_scene()` copies everything the core needs into numpy arrays
and plain values, `jobs.Job.run()` builds and renders without touching bpy
(the core releases the GIL, so a worker thread keeps Blender responsive), and
`apply_result()` writes the preview image and the statistics.
"""

import json
import traceback

import bpy

from . import (backend, camera, compare, extract, inspector_store, legend, preview, sweep,
               tree_cache)
# The worker side (bpy-free, tested without Blender); re-exported because the
# operators and the Blender tests name them here.
from .jobs import (Job, JobInput, TreeChoice, UserError, check_result,  # noqa: F401
                   error_message, failure_report, foreign_embree_library, make_camera)


# The one job in flight, if any; the panel reads its progress.
_active_job = None

# The last Build & Render's tree, re-used while the scene's triangles and the
# build options are unchanged (see tree_cache.py).
_tree_cache = tree_cache.TreeCache()
# Tree B's of the A/B comparison, kept the same way (and forgotten when a
# press compares with no B).
_tree_cache_b = tree_cache.TreeCache()


def active_job():
    return _active_job


def kept_tree_cache():
    """The add-on's TreeCache (the tests look into it)."""
    return _tree_cache


def kept_tree_cache_b():
    """The TreeCache of the A/B comparison's tree B."""
    return _tree_cache_b


@bpy.app.handlers.persistent
def forget_kept_tree(*_args):
    """load_pre handler (and unregister): a tree of the previous file must
    never be re-used for the next, nor hold its memory."""
    _tree_cache.clear()
    _tree_cache_b.clear()


def add_handlers():
    if forget_kept_tree not in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.append(forget_kept_tree)


def remove_handlers():
    if forget_kept_tree in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(forget_kept_tree)
    forget_kept_tree()


# -----------------------------------------------------------------------------
# Main thread: read the scene


def read_camera_and_geometry(context, core):
    """The scene camera at the preview size and the visible triangles; raise
    UserError when either is missing or the camera is outside the core's
    ranges (bsplab.camera.RANGES, wide enough for any usable Blender camera)."""
    depsgraph = context.evaluated_depsgraph_get()
    try:
        cam = camera.scene_camera(context.scene, depsgraph,
                                  context.scene.bsplab.preview_percentage)
    except camera.CameraError as ex:
        raise UserError(str(ex)) from ex
    try:
        make_camera(core, cam)
    except (TypeError, ValueError) as ex:
        raise UserError("The scene camera '{}' cannot be previewed: {}".format(
            cam.name, ex)) from ex
    geometry = extract.scene_triangles(depsgraph)
    if geometry.triangle_count == 0:
        if geometry.instances == 0:
            raise UserError("No visible mesh in the scene: nothing to build a tree from")
        raise UserError("The visible meshes are empty: they have no faces to build a tree from")
    return cam, geometry


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
    """Tree B's TreeChoice when "Compare with B" is on, else None. B is built
    with A's thread count."""
    compare = scene.bsplab_compare
    if not compare.enabled:
        return None
    choice = checked_choice(methods, compare, tree="Tree B: ")
    if "threads" not in methods[choice.method].get("params", ()):
        return choice
    return TreeChoice(choice.method, dict(choice.options, threads=scene.bsplab.threads))


def read_scene(context, core):
    """Copy everything the job needs out of bpy; raise UserError if unusable."""
    scene = context.scene
    settings = scene.bsplab
    methods = core.methods()
    a = checked_choice(methods, settings)
    b = read_tree_b(scene, methods)
    cam, geometry = read_camera_and_geometry(context, core)
    return JobInput(
        triangles=geometry.triangles,
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


def read_sweep(context, core):
    """The Sweep K job's input, read from the scene; raise UserError if unusable."""
    scene = context.scene
    settings = scene.bsplab
    try:
        methods = sweep.parse_methods(settings.sweep_methods, core.methods())
        sweep.plan(methods, core.methods(), settings.sweep_k_min, settings.sweep_k_max)
    except sweep.SweepError as ex:
        raise UserError(str(ex)) from ex
    cam, geometry = read_camera_and_geometry(context, core)
    try:
        core.check_triangles(geometry.triangles)
    except (TypeError, ValueError) as ex:
        raise UserError("BSP Lab cannot build the tree: {}".format(ex)) from ex
    return sweep.SweepInput(
        triangles=geometry.triangles, camera=cam, methods=methods,
        k_min=settings.sweep_k_min, k_max=settings.sweep_k_max,
        repetitions=settings.sweep_repetitions, workload=settings.sweep_workload,
        scene_name=scene.name)


# -----------------------------------------------------------------------------
# Main thread: apply the result


def preview_image(result):
    """The render, and for a heat map its colour bar (0 .. the largest count,
    and the unit). A core older than the add-on may lack the maximum (the
    legacy add-on runs on a separately installed core): then the bar is left
    out rather than the render lost."""
    render = result["stats"]["render"]
    if "b" in result["stats"]:
        return compare.preview(result["image"], result["b_image"], result.get("counts"),
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


def _tag_redraw_sidebars(context):
    # Only the sidebars: redrawing whole 3D views ten times a second would
    # cost heavy scenes more than the job itself.
    for window in context.window_manager.windows:
        for area in window.screen.areas:
            if area.type != 'VIEW_3D':
                continue
            for region in area.regions:
                if region.type == 'UI':
                    region.tag_redraw()


def _set_job_state(context, running, progress=0.0):
    state = context.window_manager.bsplab_job
    state.is_running = running
    state.progress = progress


# -----------------------------------------------------------------------------
# The operator


class JobOperator:
    """Runs a job (see Job) modally on a worker thread when invoked from the UI,
    synchronously from execute(). Subclasses make the job and apply its result."""

    bl_options = {'REGISTER'}

    _job = None
    _timer = None

    @classmethod
    def poll(cls, context):
        if _active_job is not None:
            cls.poll_message_set_safe("A BSP Lab job is already running")
            return False
        return context.scene is not None

    @classmethod
    def poll_message_set_safe(cls, message):
        # `poll_message_set` exists from Blender 3.0 on.
        if hasattr(cls, "poll_message_set"):
            cls.poll_message_set(message)

    def _fail(self, message):
        self.report({'ERROR'}, message)
        return {'CANCELLED'}

    def make_job(self, context, core):
        raise NotImplementedError

    def apply(self, context, scene, job):
        """Write the finished job's result; return the operator's result set."""
        raise NotImplementedError

    def _prepare(self, context):
        """A job ready to run, or raise UserError."""
        try:
            core = backend.import_core()
        except backend.CoreMissing as ex:
            raise UserError(str(ex)) from ex
        try:
            return self.make_job(context, core)
        except UserError:
            raise
        except Exception as ex:
            # An unexpected failure reading the scene: report it, don't crash.
            traceback.print_exc()
            raise UserError("BSP Lab could not read the scene: {}: {}".format(
                type(ex).__name__, ex)) from ex

    def _finish(self, context, scene, job):
        if job.error is not None:
            level, message = failure_report(job)
            if level != 'ERROR':
                self.report({level}, message)
                return {'CANCELLED'}
            return self._fail(message)
        return self.apply(context, scene, job)

    def execute(self, context):
        try:
            job = self._prepare(context)
        except UserError as ex:
            return self._fail(str(ex))
        job.run()
        return self._finish(context, context.scene, job)

    def invoke(self, context, event):
        # Without a window there is no event loop to run a modal operator in.
        if bpy.app.background or context.window is None:
            return self.execute(context)
        global _active_job
        try:
            job = self._prepare(context)
        except UserError as ex:
            return self._fail(str(ex))
        self._job = _active_job = job
        job.start()
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        _set_job_state(context, True)
        _tag_redraw_sidebars(context)
        return {'RUNNING_MODAL'}

    def modal(self, context, event):
        try:
            return self._modal(context, event)
        except Exception as ex:
            # Never leave a job marked running (the button would stay
            # disabled) nor a timer behind.
            self._job.cancel()
            self._cleanup(context)
            return self._fail("BSP Lab failed: {}: {}".format(type(ex).__name__, ex))

    def _modal(self, context, event):
        job = self._job
        if event.type == 'ESC' and event.value == 'PRESS':
            job.cancel()
            return {'RUNNING_MODAL'}
        # Any timer will do (ours ticks every 0.1 s): polling is cheap.
        if event.type != 'TIMER':
            return {'PASS_THROUGH'}
        if job.is_alive():
            # The panel reads the job's progress itself: setting an RNA
            # property here would redraw every editor on each tick.
            _tag_redraw_sidebars(context)
            return {'RUNNING_MODAL'}
        return self._end(context)

    def cancel(self, context):
        # Blender calls this when the operator is aborted (e.g. file load).
        if self._job is not None:
            self._job.cancel()
            self._job.join(5.0)
        self._cleanup(context)

    def _cleanup(self, context):
        global _active_job
        if self._timer is not None:
            context.window_manager.event_timer_remove(self._timer)
            self._timer = None
        _active_job = None
        _set_job_state(context, False)
        _tag_redraw_sidebars(context)

    def _end(self, context):
        job = self._job
        self._cleanup(context)
        scene = bpy.data.scenes.get(job.input.scene_name) or context.scene
        return self._finish(context, scene, job)


class BSPLAB_OT_build_render(JobOperator, bpy.types.Operator):
    """Build the tree of the visible meshes and render the scene camera's view with it"""

    bl_idname = "bsplab.build_render"
    bl_label = "Build & Render"

    def make_job(self, context, core):
        inp = read_scene(context, core)
        if inp.b is None:
            _tree_cache_b.clear()  # no B: don't hold its memory
        job = Job(core, inp, cache=_tree_cache, cache_b=_tree_cache_b)
        inspector_store.build_started(job, context.view_layer)
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
        inspector_store.remember_build(scene, job, bpy.data.images[preview.IMAGE_NAME])
        stats = job.result["stats"]
        build = stats["build"]
        built = ("tree reused (built in {:.3f} s by an earlier press)" if build.get("reused")
                 else "built in {:.3f} s")
        self.report({'INFO'}, ("BSP Lab: {} triangles, {} nodes, " + built + ", rendered in {:.3f} s")
                    .format(stats["scene"]["triangles"], build.get("nodes", "?"),
                            build.get("build_seconds", 0.0),
                            stats["render"].get("seconds", 0.0))
                    + b_report(stats))
        return {'FINISHED'}


def b_report(stats):
    """The A/B part of Build & Render's report ("" without B)."""
    if "b" not in stats:
        return ""
    build = stats["b"]["build"]
    return "; B: {} nodes, {}, rendered in {:.3f} s".format(
        build.get("nodes", "?"), "tree reused" if build.get("reused") else
        "built in {:.3f} s".format(build.get("build_seconds", 0.0)),
        stats["b"]["render"].get("seconds", 0.0))


class BSPLAB_OT_sweep_k(JobOperator, bpy.types.Operator):
    """Build and trace every chosen method at every K of the range on this scene, beside kd and Embree; show the table and plot"""

    bl_idname = "bsplab.sweep_k"
    bl_label = "Sweep K"

    def make_job(self, context, core):
        return sweep.SweepJob(core, read_sweep(context, core))

    def apply(self, context, scene, job):
        scene.bsplab.sweep_json = sweep.table_json(job.result)
        preview.write_preview(job.result["plot"], name=sweep.PLOT_NAME)
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


def cancel_active_job():
    """Stop the running job (used on unregister); waits a little for it."""
    global _active_job
    if _active_job is not None:
        _active_job.cancel()
        _active_job.join(5.0)
        _active_job = None


classes = (
    BSPLAB_OT_build_render,
    BSPLAB_OT_sweep_k,
)

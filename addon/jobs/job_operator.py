# SPDX-License-Identifier: GPL-3.0-or-later
"""The base of the operators that run a worker job: Build & Render
(build_render/operator.py) and the K sweep (k_sweep/operator.py).

The work is split in three so that bpy data is only touched on the main
thread: the operator's `make_job()` copies everything the job needs into
numpy arrays and plain values (scene_reader.py), the job runs without
touching bpy (worker.py: bsplab releases the GIL, so a worker thread keeps
Blender responsive), and `apply()` writes the result.
"""

import traceback

import bpy

from .. import backend
from ..sidebar import tag_redraw_sidebars
from ..state import STATE
from .worker import UserError, failure_report


def _set_job_state(context, running, progress=0.0):
    state = context.window_manager.bsplab_job
    state.is_running = running
    state.progress = progress


class JobOperator:
    """Runs a job (a worker.WorkerJob) modally on a worker thread when
    invoked from the UI, synchronously from execute(). Subclasses make the
    job and apply its result."""

    bl_options = {'REGISTER'}

    _job = None
    _timer = None

    @classmethod
    def poll(cls, context):
        if STATE.job is not None:
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

    def make_job(self, context, bsplab):
        raise NotImplementedError

    def apply(self, context, scene, job):
        """Write the finished job's result; return the operator's result set."""
        raise NotImplementedError

    def _prepare(self, context):
        """A job ready to run, or raise UserError."""
        try:
            bsplab = backend.import_bsplab()
        except backend.BsplabMissing as ex:
            raise UserError(str(ex)) from ex
        try:
            return self.make_job(context, bsplab)
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
        try:
            job = self._prepare(context)
        except UserError as ex:
            return self._fail(str(ex))
        self._job = STATE.job = job
        job.start()
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        _set_job_state(context, True)
        tag_redraw_sidebars(context)
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
            tag_redraw_sidebars(context)
            return {'RUNNING_MODAL'}
        return self._end(context)

    def cancel(self, context):
        # Blender calls this when the operator is aborted (e.g. file load).
        if self._job is not None:
            self._job.cancel()
            self._job.join(5.0)
        self._cleanup(context)

    def _cleanup(self, context):
        if self._timer is not None:
            context.window_manager.event_timer_remove(self._timer)
            self._timer = None
        STATE.job = None
        _set_job_state(context, False)
        tag_redraw_sidebars(context)

    def _end(self, context):
        job = self._job
        self._cleanup(context)
        scene = bpy.data.scenes.get(job.input.scene_name) or context.scene
        return self._finish(context, scene, job)

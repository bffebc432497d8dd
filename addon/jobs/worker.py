# SPDX-License-Identifier: GPL-3.0-or-later
"""What runs on a worker thread, and its errors: the base of Build & Render's
job (build_render/job.py) and of the K sweep's (k_sweep/experiment.py).

Nothing here touches bpy: the operators copy the scene into numpy arrays
and plain values first, a job computes on a worker thread (bsplab releases
the GIL, so Blender stays responsive) and the main thread then reads
`result` or `error` (job_operator.py).
"""

import threading

import numpy as np


class UserError(Exception):
    """An error with a message meant for the user's eyes."""


class WorkerJob:
    """Base of the worker jobs: subclasses compute without touching bpy
    (`_compute`), say how far they are (`fraction`) and stop when asked
    (`cancel`); the operator polls `is_alive` and, once done, reads `result`
    or `error` on the main thread."""

    title = "Working"
    # Reported (as information, not an error) when the user cancelled the job.
    cancelled_message = "BSP Lab: cancelled"

    def __init__(self, bsplab, inp):
        self.bsplab = bsplab
        self.input = inp
        self.cancelled = False
        self.result = None
        self.error = None
        self._thread = None

    def _compute(self):
        raise NotImplementedError

    def run(self):
        try:
            self.result = self._compute()
        except BaseException as ex:  # Reported on the main thread.
            self.error = ex

    def start(self):
        # Daemon: quitting Blender mid-job must not wait for bsplab.
        self._thread = threading.Thread(target=self.run, name="BSP Lab: " + self.title,
                                        daemon=True)
        self._thread.start()

    def is_alive(self):
        return self._thread is not None and self._thread.is_alive()

    def join(self, timeout=None):
        if self._thread is not None:
            self._thread.join(timeout)

    def cancel(self):
        self.cancelled = True

    def fraction(self):
        return 0.0


def plain(value):
    """A job's results as plain values (numpy scalars and small arrays made
    Python's, large arrays named by their shape): the main thread stores
    them as JSON in the scene."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist() if value.size <= 16 else "array{}".format(value.shape)
    if isinstance(value, np.generic):
        return value.item()
    return value


def error_message(bsplab, ex):
    """The user's message for an exception raised by a job."""
    if isinstance(ex, UserError):
        return str(ex)
    if bsplab is not None and isinstance(ex, bsplab.Cancelled):
        return "BSP Lab: Build & Render cancelled; the previous preview is unchanged"
    if isinstance(ex, MemoryError):
        # bsplab's message names the limit and what the build needed.
        return "BSP Lab: the tree exceeds the memory budget: {}".format(ex)
    if isinstance(ex, (ValueError, TypeError)):
        # bsplab's checks: NaN/inf coordinates, options out of range.
        return "BSP Lab cannot build the tree: {}".format(ex)
    return "BSP Lab failed: {}: {}".format(type(ex).__name__, ex)


def failure_report(job):
    """(report level, message) of a job that ended with an error. A cancel is
    what the user asked for: information, not a red error."""
    if job.bsplab is not None and isinstance(job.error, job.bsplab.Cancelled):
        return 'INFO', job.cancelled_message
    return 'ERROR', error_message(job.bsplab, job.error)

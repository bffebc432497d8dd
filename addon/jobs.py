# SPDX-License-Identifier: GPL-3.0-or-later
"""A job that runs on a worker thread and reports back to the main thread.

Subclasses compute without touching bpy (`_compute`), say how far they are
(`fraction`) and stop when asked (`cancel`); the operator polls `is_alive`
and, once done, reads `result` or `error` on the main thread.
"""

import threading


class WorkerJob:
    title = "Working"

    def __init__(self, core, inp):
        self.core = core
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
        # Daemon: quitting Blender mid-job must not wait for the core.
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

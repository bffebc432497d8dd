"""Where experiment trials run: in this process, in a local process pool (the
default), or on a Dask distributed cluster (an existing scheduler, or a
local cluster started for the run). Every executor yields (trial, rows) as
trials finish, in any order; the runner writes them down.

An executor is given the function that runs one trial, `run_trial(spec, trial,
scene_data=None, progress=None) -> rows` (for the pools, a module-level
function, so that it pickles): it knows nothing of what a trial is."""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing

from .. import Cancelled

# How long a run waits for a named Dask scheduler to answer before it says
# it cannot reach it (Dask's own default is 30 s).
CONNECT_SECONDS = 10


def _run_trial(run_trial, spec, trial):
    return trial, run_trial(spec, trial)


def _check_cancel(progress) -> None:
    if progress is not None and progress.cancelled:
        raise Cancelled("cancelled")


class InlineExecutor:
    """In this process, one trial after another (the add-on, the tests)."""

    def __init__(self, run_trial):
        self.run_trial = run_trial

    def map(self, spec, todo, scene_data=None, progress=None):
        for trial in todo:
            _check_cancel(progress)
            data = scene_data.get(trial.scene) if scene_data else None
            yield trial, self.run_trial(spec, trial, data, progress=progress)

    def close(self):
        pass


class ProcessExecutor:
    """A local process pool. Each worker loads a scene once and keeps it while
    its trials follow one another (trials are ordered by scene)."""

    def __init__(self, run_trial, workers: int):
        self.run_trial = run_trial
        # spawn: the workers start clean, without the parent's threads.
        self.pool = cf.ProcessPoolExecutor(max_workers=workers,
                                           mp_context=multiprocessing.get_context("spawn"))

    def map(self, spec, todo, scene_data=None, progress=None):
        futures = [self.pool.submit(_run_trial, self.run_trial, spec, c) for c in todo]
        try:
            for f in cf.as_completed(futures):
                yield f.result()
                _check_cancel(progress)
        finally:
            for f in futures:
                f.cancel()

    def close(self):
        self.pool.shutdown(wait=True, cancel_futures=True)


class DaskExecutor:
    """Trials as tasks on a Dask distributed cluster: `scheduler` is the address
    of a running scheduler (workers need bsplab installed and the scene files
    at the same paths), or empty for a local cluster of `workers` processes."""

    def __init__(self, run_trial, workers: int, scheduler: str = ""):
        self.run_trial = run_trial
        try:
            from distributed import Client, LocalCluster
        except ImportError as e:
            raise RuntimeError("the dask executor needs 'dask[distributed]' installed") from e
        self.cluster = None
        if scheduler:
            try:
                self.client = Client(scheduler, timeout=CONNECT_SECONDS)
            except (OSError, TimeoutError, ValueError) as e:  # no scheduler there, a bad address
                raise RuntimeError(f"dask scheduler {scheduler}: cannot connect within "
                                   f"{CONNECT_SECONDS} s ({e}); is a scheduler running "
                                   "there?") from None
        else:
            self.cluster = LocalCluster(n_workers=workers, threads_per_worker=1,
                                        processes=True, dashboard_address=None)
            self.client = Client(self.cluster)

    def map(self, spec, todo, scene_data=None, progress=None):
        from distributed import as_completed
        # pure=False: identical trials may run again on purpose (repetitions).
        futures = [self.client.submit(_run_trial, self.run_trial, spec, c, pure=False,
                                      key=f"trial-{i}-{c.key}")
                   for i, c in enumerate(todo)]
        try:
            for f in as_completed(futures):
                yield f.result()
                _check_cancel(progress)
        finally:
            self.client.cancel(futures)

    def close(self):
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def make(spec, run_trial, inline: bool = False):
    """The executor `spec` asks for (`inline` forces this process)."""
    if inline or spec.executor == "inline":
        return InlineExecutor(run_trial)
    if spec.executor == "dask":
        return DaskExecutor(run_trial, spec.workers, spec.scheduler)
    return ProcessExecutor(run_trial, spec.workers)

"""Where experiment cells run: in this process, in a local process pool (the
default), or on a Dask distributed cluster (an existing scheduler, or a
local cluster started for the run). Every executor yields (cell, rows) as
cells finish, in any order; the runner writes them down.

An executor is given the function that runs one cell, `run_cell(spec, cell,
scene_data=None, progress=None) -> rows` (for the pools, a module-level
function, so that it pickles): it knows nothing of what a cell is."""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing

from .. import Cancelled

# How long a run waits for a named Dask scheduler to answer before it says
# it cannot reach it (Dask's own default is 30 s).
CONNECT_SECONDS = 10


def _run_cell(run_cell, spec, cell):
    return cell, run_cell(spec, cell)


def _check_cancel(progress) -> None:
    if progress is not None and progress.cancelled:
        raise Cancelled("cancelled")


class InlineExecutor:
    """In this process, one cell after another (the add-on, the tests)."""

    def __init__(self, run_cell):
        self.run_cell = run_cell

    def map(self, spec, todo, scene_data=None, progress=None):
        for cell in todo:
            _check_cancel(progress)
            data = scene_data.get(cell.scene) if scene_data else None
            yield cell, self.run_cell(spec, cell, data, progress=progress)

    def close(self):
        pass


class ProcessExecutor:
    """A local process pool. Each worker loads a scene once and keeps it while
    its cells follow one another (cells are ordered by scene)."""

    def __init__(self, run_cell, workers: int):
        self.run_cell = run_cell
        # spawn: the workers start clean, without the parent's threads.
        self.pool = cf.ProcessPoolExecutor(max_workers=workers,
                                           mp_context=multiprocessing.get_context("spawn"))

    def map(self, spec, todo, scene_data=None, progress=None):
        futures = [self.pool.submit(_run_cell, self.run_cell, spec, c) for c in todo]
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
    """Cells as tasks on a Dask distributed cluster: `scheduler` is the address
    of a running scheduler (workers need bsplab installed and the scene files
    at the same paths), or empty for a local cluster of `workers` processes."""

    def __init__(self, run_cell, workers: int, scheduler: str = ""):
        self.run_cell = run_cell
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
        # pure=False: identical cells may run again on purpose (repetitions).
        futures = [self.client.submit(_run_cell, self.run_cell, spec, c, pure=False,
                                      key=f"cell-{i}-{c.key}")
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


def make(spec, run_cell, inline: bool = False):
    """The executor `spec` asks for (`inline` forces this process)."""
    if inline or spec.executor == "inline":
        return InlineExecutor(run_cell)
    if spec.executor == "dask":
        return DaskExecutor(run_cell, spec.workers, spec.scheduler)
    return ProcessExecutor(run_cell, spec.workers)

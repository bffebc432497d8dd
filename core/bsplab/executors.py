"""Where experiment cells run: in this process, in a local process pool (the
default), or on a Dask distributed cluster (an existing scheduler, or a
local cluster started for the run). Every executor yields (cell, rows) as
cells finish, in any order; the runner writes them down."""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing


def _run_cell(spec, cell):
    from .experiment import run_cell
    return cell, run_cell(spec, cell)


class InlineExecutor:
    """In this process, one cell after another (the add-on, the tests)."""

    def map(self, spec, todo, scene_data=None, progress=None):
        from .experiment import run_cell
        for cell in todo:
            if progress is not None and progress.cancelled:
                from . import Cancelled
                raise Cancelled("cancelled")
            data = scene_data.get(cell.scene) if scene_data else None
            yield cell, run_cell(spec, cell, data, progress=progress)

    def close(self):
        pass


class ProcessExecutor:
    """A local process pool. Each worker loads a scene once and keeps it while
    its cells follow one another (cells are ordered by scene)."""

    def __init__(self, workers: int):
        # spawn: the workers start clean, without the parent's threads.
        self.pool = cf.ProcessPoolExecutor(max_workers=workers,
                                           mp_context=multiprocessing.get_context("spawn"))

    def map(self, spec, todo, scene_data=None, progress=None):
        futures = [self.pool.submit(_run_cell, spec, c) for c in todo]
        try:
            for f in cf.as_completed(futures):
                yield f.result()
                if progress is not None and progress.cancelled:
                    from . import Cancelled
                    raise Cancelled("cancelled")
        finally:
            for f in futures:
                f.cancel()

    def close(self):
        self.pool.shutdown(wait=True, cancel_futures=True)


class DaskExecutor:
    """Cells as tasks on a Dask distributed cluster: `scheduler` is the address
    of a running scheduler (workers need bsplab installed and the scene files
    at the same paths), or empty for a local cluster of `workers` processes."""

    def __init__(self, workers: int, scheduler: str = ""):
        try:
            from distributed import Client, LocalCluster
        except ImportError as e:
            raise RuntimeError("the dask executor needs 'dask[distributed]' installed") from e
        self.cluster = None
        if scheduler:
            self.client = Client(scheduler)
        else:
            self.cluster = LocalCluster(n_workers=workers, threads_per_worker=1,
                                        processes=True, dashboard_address=None)
            self.client = Client(self.cluster)

    def map(self, spec, todo, scene_data=None, progress=None):
        from distributed import as_completed
        # pure=False: identical cells may run again on purpose (repetitions).
        futures = [self.client.submit(_run_cell, spec, c, pure=False, key=f"cell-{i}-{c.key}")
                   for i, c in enumerate(todo)]
        try:
            for f in as_completed(futures):
                yield f.result()
                if progress is not None and progress.cancelled:
                    from . import Cancelled
                    raise Cancelled("cancelled")
        finally:
            self.client.cancel(futures)

    def close(self):
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def make(spec, inline: bool = False):
    if inline or spec.executor == "inline":
        return InlineExecutor()
    if spec.executor == "dask":
        return DaskExecutor(spec.workers, spec.scheduler)
    return ProcessExecutor(spec.workers)

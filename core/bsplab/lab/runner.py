"""The experiment runner: a spec expands into cells (`cells.cells`), an
executor runs the cells not yet in the results file (`cells.run_cell`), and
the rows go to the results store as cells finish."""

from __future__ import annotations

import sys
import time
from typing import Callable

from . import executors
from .cells import cells, run_cell
from .spec import Spec
from .store import ResultsFile


class _Bar:
    """Cells done, the current cell and the time left on stderr: a tqdm bar
    where tqdm is installed, else one line per cell (Blender's Python may
    lack tqdm; the add-on runs quiet anyway)."""

    def __init__(self, total: int, done: int, note: str):
        try:
            from tqdm import tqdm
        except ImportError:
            tqdm = None
        self.bar = None
        if tqdm is not None:
            self.bar = tqdm(total=total, initial=done, unit="cell", dynamic_ncols=True,
                            bar_format="{n_fmt}/{total_fmt} cells |{bar}| "
                                       "[{elapsed}<{remaining}] {desc}")
        self.update(0, note)

    def update(self, step: int, label: str) -> None:
        if self.bar is None:
            print(label, file=sys.stderr, flush=True)
            return
        self.bar.set_description_str(label, refresh=False)
        self.bar.update(step)
        self.bar.refresh()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def run(spec: Spec, out, *, fresh: bool = False, executor=None,
        on_progress: Callable[[int, int, str], None] | None = None,
        scene_data: dict | None = None, progress=None, quiet: bool = False) -> list[dict]:
    """Runs every cell not yet in `out`; returns all rows (old and new).

    `scene_data` maps scene names to in-memory SceneData (the add-on's
    scene), which forces the inline executor. `progress` (a bsplab.Progress)
    lets another thread cancel between and inside cells."""
    results = ResultsFile(out, spec, fresh=fresh)
    finished = results.done()
    everything = cells(spec)
    todo = [c for c in everything if c.key not in finished]
    total = len(everything)
    done = total - len(todo)
    if executor is None:  # before the bar: a scheduler it cannot reach is said plainly
        executor = executors.make(spec, run_cell, inline=scene_data is not None)
    bar = None if quiet else _Bar(total, done, f"{done} cells already in {results.csv}"
                                  if done else "starting")
    start = time.perf_counter()
    try:
        for cell, rows in executor.map(spec, todo, scene_data=scene_data, progress=progress):
            results.add(rows)
            done += 1
            if bar:
                bar.update(1, cell.label())
            if on_progress:
                on_progress(done, total, cell.label())
    finally:
        if bar:
            bar.close()
        executor.close()
    results.finish(time.perf_counter() - start)
    return results.rows

"""The experiment runner: a spec expands into trials (`trials.trials`), an
executor runs the trials not yet in the results file (`trials.run_trial`), and
the rows go to the results store as trials finish."""

from __future__ import annotations

import sys
import time
from typing import Callable

from . import executors
from .trials import trials, run_trial
from .spec import Spec
from .store import ResultsFile


class _Bar:
    """Trials done, the current trial and the time left on stderr: a tqdm bar
    where tqdm is installed, else one line per trial (Blender's Python may
    lack tqdm; the add-on runs quiet anyway)."""

    def __init__(self, total: int, done: int, note: str):
        try:
            from tqdm import tqdm
        except ImportError:
            tqdm = None
        self.bar = None
        if tqdm is not None:
            self.bar = tqdm(total=total, initial=done, unit="trial", dynamic_ncols=True,
                            bar_format="{n_fmt}/{total_fmt} trials |{bar}| "
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
    """Runs every trial not yet in `out`; returns all rows (old and new).

    `scene_data` maps scene names to in-memory SceneData (the add-on's
    scene), which forces the inline executor. `progress` (a bsplab.Progress)
    lets another thread cancel between and inside trials."""
    results = ResultsFile(out, spec, fresh=fresh)
    finished = results.done()
    everything = trials(spec)
    todo = [c for c in everything if c.key not in finished]
    total = len(everything)
    done = total - len(todo)
    if executor is None:  # before the bar: a scheduler it cannot reach is said plainly
        executor = executors.make(spec, run_trial, inline=scene_data is not None)
    bar = None if quiet else _Bar(total, done, f"{done} trials already in {results.csv}"
                                  if done else "starting")
    start = time.perf_counter()
    try:
        for trial, rows in executor.map(spec, todo, scene_data=scene_data, progress=progress):
            results.add(rows)
            done += 1
            if bar:
                bar.update(1, trial.label())
            if on_progress:
                on_progress(done, total, trial.label())
    finally:
        if bar:
            bar.close()
        executor.close()
    results.finish(time.perf_counter() - start)
    return results.rows

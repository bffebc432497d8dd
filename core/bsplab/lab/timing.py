"""The one timing protocol of the lab: paired rounds.

A shared machine's speed drifts by tens of percent within a minute, and that
drift hits our memory-bound traversals harder than Embree's. So a time is
never compared with one taken at another moment: every round traces the
method under test and its references (the scene's kd-tree, Embree, the same
tree with culling on...) on the same rays, one right after the other, in an
order that rotates from round to round so that no tracer always runs first
(warm caches) or last. Each figure a report shows is then the median over
the rounds of a per-round ratio (`PairedTimes.ratio`), or a median time.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np


@dataclass
class Tracer:
    """One thing to time: `run()` traces and returns its result; `seconds`,
    when given, reads the time the tracer measured itself after a run (Embree
    through embreex times its own loop, without the Python around it)."""
    run: Callable[[], object]
    seconds: Callable[[], float] | None = None


@dataclass
class PairedTimes:
    """Per tracer, its time in every round (seconds) and its last result."""
    seconds: dict[str, list[float]] = field(default_factory=dict)
    results: dict[str, object] = field(default_factory=dict)

    def median(self, name: str) -> float:
        return float(np.median(self.seconds[name]))

    def ratios(self, name: str, reference: str) -> np.ndarray:
        """`name`'s time over `reference`'s, round by round."""
        return np.asarray(self.seconds[name]) / np.asarray(self.seconds[reference])

    def ratio(self, name: str, reference: str) -> float:
        """The median of the per-round ratios (below 1: `name` is faster)."""
        return float(np.median(self.ratios(name, reference)))


def paired_rounds(tracers: dict[str, Tracer], rounds: int,
                  between_rounds: Callable[[], None] | None = None) -> PairedTimes:
    """Runs every tracer once per round, `rounds` times, in a rotating order.

    `between_rounds` is called after each round (the runner raises there
    when the user cancelled)."""
    if rounds < 1:
        raise ValueError(f"rounds must be at least 1, got {rounds}")
    if not tracers:
        raise ValueError("nothing to time: no tracers")
    names = list(tracers)
    out = PairedTimes({name: [] for name in names})
    for r in range(rounds):
        shift = r % len(names)
        for name in names[shift:] + names[:shift]:
            tracer = tracers[name]
            start = time.perf_counter()
            out.results[name] = tracer.run()
            elapsed = time.perf_counter() - start
            out.seconds[name].append(tracer.seconds() if tracer.seconds else elapsed)
        if between_rounds is not None:
            between_rounds()
    return out


def format_times(seconds: list[float]) -> str:
    """The rounds' times as a results file's trial holds them."""
    return " ".join(f"{x:.6g}" for x in seconds)


def parse_times(text: str) -> list[float]:
    return [float(x) for x in text.split()] if text else []

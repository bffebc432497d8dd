"""`bsplab.Progress`: the core's progress and cancel flag, with its
arguments checked in Python.

The core's class takes no arguments, and given some, nanobind answers with
its raw signature dump; this subclass says plainly what is wrong. It is
still the core's type, so the builds and traces take it as they are."""

from __future__ import annotations

from . import _core


class Progress(_core.Progress):
    """Progress of a build or trace, 0..1 in `value`; `cancel()` from any
    thread stops the work (it raises bsplab.Cancelled); `reset()` readies it
    for the next job."""

    def __init__(self, *args, **kwargs):
        if args or kwargs:
            given = ", ".join([repr(a) for a in args] + [f"{k}={v!r}" for k, v in kwargs.items()])
            raise TypeError(f"bsplab.Progress() takes no arguments, got ({given}); a new "
                            "Progress starts at value 0, not cancelled")
        super().__init__()

"""Which tracing kernels run on this CPU."""

from __future__ import annotations

from . import _core


def cpu_features() -> dict:
    """The instruction-set levels of the tracing kernels (docs/api.md):
    `supported`, the levels this CPU runs, lowest first (of "sse2", "avx2",
    "avx512"); `selected`, the one every trace uses; `forced`, the value of
    the environment variable BSPLAB_ISA that chose a lower level, or None;
    `packet_width`, the rays per packet of the selected level's packet kernel
    (`Tree.intersect(..., packets=True)`).

    The choice is made once per process, at the first trace or call here.
    Raises ValueError when BSPLAB_ISA names an unknown level or one this CPU
    lacks."""
    return _core.cpu_features()

"""The ray segment's ends (docs/api.md, "Tracing"): a hit counts on the
open segment tmin < t < tmax. A hit exactly at tmax is rejected, one just
below it accepted; a hit exactly at tmin is rejected; tmin == tmax never
hits. Embree's segment is closed (tnear <= t <= tfar), the oracle's
at_ends class."""

from __future__ import annotations

import numpy as np
import pytest

import bsplab
from bsplab import instanced_scenes

# Straight down onto the unit cube's top face from z = 5: the hit is at
# t = 4 exactly (every value here is exact in float32).
ORIGIN = np.array([[0.3, 0.4, 5.0]], np.float32)
DOWN = np.array([[0.0, 0.0, -1.0]], np.float32)
HIT_T = np.float32(4.0)
ABOVE = np.nextafter(HIT_T, np.float32(np.inf))
BELOW = np.nextafter(HIT_T, np.float32(0))


def _traced(tree, tmin, tmax, **kw):
    return tree.intersect(ORIGIN, DOWN, tmin=tmin, tmax=tmax, **kw)


@pytest.mark.parametrize("method", list(bsplab.methods()))
def test_a_hit_at_tmax_is_rejected_and_just_inside_accepted(method):
    tree = bsplab.build(instanced_scenes.cube(), method)
    for kw in ({"counters": True}, {"counters": False}, {"counters": False, "packets": True}):
        at = _traced(tree, 0.0, HIT_T, **kw)
        assert at["prim"][0] == -1 and np.isinf(at["t"][0]), (method, kw)
        inside = _traced(tree, 0.0, ABOVE, **kw)  # the hit lies just below tmax
        assert inside["prim"][0] >= 0 and inside["t"][0] == HIT_T, (method, kw)
        assert _traced(tree, 0.0, BELOW, **kw)["prim"][0] == -1
        # The start is open too: a segment from the hit on does not see it,
        # and tmin == tmax is empty, even on the surface.
        assert _traced(tree, HIT_T, np.inf, **kw)["t"][0] == 5.0  # the bottom face
        assert _traced(tree, BELOW, np.inf, **kw)["t"][0] == HIT_T
        assert _traced(tree, HIT_T, HIT_T, **kw)["prim"][0] == -1


def test_an_instanced_trace_has_the_same_open_ends():
    it = bsplab.build_instanced([instanced_scenes.cube()], [0],
                                instanced_scenes.affine(np.eye(3), (0, 0, 0))[None])
    assert it.intersect(ORIGIN, DOWN, tmax=HIT_T)["instance"][0] == -1
    assert it.intersect(ORIGIN, DOWN, tmax=ABOVE)["t"][0] == HIT_T


def test_embree_accepts_a_hit_at_tfar():
    """The difference the oracle allows (at_ends): Embree's segment is
    closed."""
    oracle = pytest.importorskip("bsplab.oracle")
    pytest.importorskip("embreex", reason="embreex is the oracle")
    ref = oracle.EmbreeTracer(instanced_scenes.cube()).intersect(ORIGIN, DOWN, tmax=HIT_T)
    assert ref["prim"][0] >= 0 and ref["t"][0] == HIT_T

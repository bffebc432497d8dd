"""The hits-only path's SIMD leaf test (core/src/trace/kernels/leaf_simd.hpp)
against the counting path's one-triangle-at-a-time test, on leaves built to
be hard for it: big leaves (blocks of 4, 8 and 16 lanes and a remainder),
exact ties (the same triangle several times: the first in leaf order must
win), slivers, and rays through shared edges and vertices, whose edge
functions are exactly zero in float and are recomputed in double.
test_isa_levels.py runs the same scene on every instruction-set level."""

from __future__ import annotations

import numpy as np
import pytest

import bsplab

HITS = ("t", "prim", "u", "v")


def big_leaf_scene() -> np.ndarray:
    """A 4 x 4 grid of squares (two triangles each) in z = 0, a triangle five
    times over and twice more with the other winding in z = 1 (exact ties),
    and two slivers: 41 triangles."""
    tris = []
    for i in range(4):
        for j in range(4):
            a, b, c, d = (i, j, 0), (i + 1, j, 0), (i + 1, j + 1, 0), (i, j + 1, 0)
            tris += [(a, b, c), (a, c, d)]
    tie = ((0, 0, 1), (2, 0, 1), (0, 2, 1))
    tris += [tie] * 5 + [(tie[0], tie[2], tie[1])] * 2
    tris += [((0, 0, 0.5), (4, 4, 0.5), (4, 4 + 1e-5, 0.5)),
             ((0, 4, 0.25), (4, 0, 0.25), (4, 1e-6, 0.25))]
    return np.asarray(tris, np.float32)


def lattice_rays(seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Rays down through every vertex, edge midpoint and square centre of the
    grid (straight down, and tilted by dyadic steps, so that the sheared
    edge functions are exact zeros on the edges), and random rays."""
    g = np.arange(0, 4.01, 0.5, dtype=np.float32)
    x, y = (a.ravel() for a in np.meshgrid(g, g))
    origins, directions = [], []
    for tilt in ((0, 0), (0.25, 0), (0.125, -0.25)):
        o = np.stack([x - 3 * tilt[0], y - 3 * tilt[1], np.full_like(x, 3)], axis=1)
        origins.append(o)
        directions.append(np.tile(np.float32([tilt[0], tilt[1], -1]), (len(x), 1)))
    rng = np.random.default_rng(seed)
    o = rng.uniform(-1, 5, (3000, 3)).astype(np.float32)
    d = rng.normal(size=(3000, 3)).astype(np.float32)
    origins.append(o)
    directions.append(d)
    return np.concatenate(origins), np.concatenate(directions).astype(np.float32)


# leaf_size 64 keeps all 41 triangles in one leaf; max_depth 1..3 gives leaves
# of 25, 17 and 10 (SIMD blocks from 8 up), the default tree leaves of 7 at most.
TREES = [dict(leaf_size=64), dict(max_depth=1), dict(max_depth=2), dict(max_depth=3), dict()]


def assert_same_bytes(a: dict, b: dict, what: str) -> None:
    for key in HITS:
        assert np.array_equal(a[key].view(np.uint8), b[key].view(np.uint8)), (
            f"{what}: {key} differs on {int((a[key] != b[key]).sum())} rays")


def tree_id(options: dict) -> str:
    return ",".join(f"{k}={v}" for k, v in options.items()) or "default"


@pytest.mark.parametrize("options", TREES, ids=tree_id)
@pytest.mark.parametrize("cull", [False, True])
def test_simd_leaves_give_the_counting_paths_hits(options, cull):
    tris = big_leaf_scene()
    tree = bsplab.build(tris, "kd", **options)
    o, d = lattice_rays()
    rng = np.random.default_rng(5)
    short = rng.random(len(o)) < 0.3
    tmax = np.where(short, rng.uniform(0.5, 4, len(o)), np.inf).astype(np.float32)
    for lo, hi in ((0.0, np.inf), (0.0, tmax), (2.5, np.inf)):
        counted = tree.intersect(o, d, tmin=lo, tmax=hi, cull=cull, threads=1)
        fast = tree.intersect(o, d, tmin=lo, tmax=hi, cull=cull, threads=1, counters=False)
        assert_same_bytes(counted, fast, f"{options} cull={cull} tmin={lo}")


def test_leaf_size_does_not_change_the_distances():
    # A triangle's t, u, v are computed the same way whatever block and lane
    # it lands in: trees with leaves of 1 to 41 triangles agree on every
    # distance, bit for bit.
    tris = big_leaf_scene()
    o, d = lattice_rays()
    results = [bsplab.build(tris, "kd", **opts).intersect(o, d, threads=1, counters=False)
               for opts in TREES]
    for r in results[1:]:
        assert np.array_equal(r["t"].view(np.uint32), results[0]["t"].view(np.uint32))


def test_no_ray_slips_through_the_grids_shared_edges():
    # Every vertical ray over the grid, vertices and edges included, hits it
    # (or the tie triangles and slivers above it): the double recompute of
    # exactly-zero edge functions works in the SIMD lanes.
    tris = big_leaf_scene()
    o, d = lattice_rays()
    vertical = slice(0, 81)
    assert np.all(d[vertical] == np.float32([0, 0, -1]))
    tree = bsplab.build(tris, "kd", leaf_size=64)
    hits = tree.intersect(o[vertical], d[vertical], threads=1, counters=False)
    assert np.all(hits["prim"] >= 0)


def test_the_first_of_equal_triangles_wins():
    # Rays into the tie triangle's interior: seven triangles at exactly the
    # same t. Within one leaf the scalar loop keeps the first in leaf order
    # (strict <); the SIMD blocks must keep the same one, in every tree.
    tris = big_leaf_scene()
    o = np.float32([[0.3, 0.4, 3], [1.1, 0.2, 3], [0.25, 1.5, 3]])
    d = np.tile(np.float32([0, 0, -1]), (3, 1))
    for opts in TREES:
        tree = bsplab.build(tris, "kd", **opts)
        fast = tree.intersect(o, d, threads=1, counters=False)
        counted = tree.intersect(o, d, threads=1)
        assert np.all((fast["prim"] >= 32) & (fast["prim"] < 39)), opts
        assert np.all(fast["t"] == 2.0)
        assert np.array_equal(fast["prim"], counted["prim"]), opts

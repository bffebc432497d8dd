"""The BVH (method "bvh", issue 23): its builder's promises (the SAH against
a full-sweep reference, determinism, memory limit, cancel, progress, bad
input), its geometry queries (node boxes, node_at, trace_path's boxes), its
counters, and its hits against Embree and the kd tree on box-specific scenes
and rays: many overlapping boxes, flat boxes of axis-aligned quads,
zero-thickness boxes, rays along box faces. (The ray families, the paths and
the fuzzer run every method, the BVH among them: test_ray_families.py,
test_paths_agree.py, test_fuzz.py.)"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

import bsplab
from bsplab import agreement, fuzz, oracle, scenes
from bsplab.tree import COUNTERS, KINDS
from conftest import cancelled_once_held

embreex = pytest.importorskip("embreex", reason="embreex is the oracle")

# The builder's defaults (builders/bvh_build.hpp): a node of more than
# MAX_LEAF triangles is split even where the SAH prefers a leaf.
MAX_LEAF = 16
BOX, LEAF = KINDS.index("box"), KINDS.index("leaf")


def soup(n: int, seed: int = 0, size: float = 0.05) -> np.ndarray:
    rng = np.random.default_rng(seed)
    a = rng.random((n, 1, 3), dtype=np.float32)
    return (a + size * rng.random((n, 3, 3), dtype=np.float32)).astype(np.float32)


def walk(tree):
    """(index, depth, lo, hi, is_leaf, first, count) of every node, from the raw bytes."""
    raw = np.frombuffer(tree._tree.arrays()["bvh_nodes"], np.uint8).reshape(-1, 32)
    f = raw.view(np.float32).reshape(-1, 8)
    u = raw.view(np.uint32).reshape(-1, 8)
    return f[:, 0:3], f[:, 4:7], u[:, 3], u[:, 7]


# --- the builder -----------------------------------------------------------------

def full_sweep_sah(tris: np.ndarray, ct: float, ci: float, leaf_size: int = 1) -> float:
    """The SAH cost of a top-down BVH that tries every object split on every
    axis (sorted centroids, all n - 1 boundaries) with the builder's leaf
    rule: the reference the binned builder is held to."""
    lo, hi = tris.min(axis=1).astype(np.float64), tris.max(axis=1).astype(np.float64)
    c = (lo + hi) / 2

    def area(l, h):
        d = np.maximum(h - l, 0)
        return 2 * (d[..., 0] * d[..., 1] + d[..., 1] * d[..., 2] + d[..., 2] * d[..., 0])

    root_area = area(lo.min(0), hi.max(0))
    total = 0.0
    stack = [np.arange(len(tris))]
    while stack:
        idx = stack.pop()
        n = len(idx)
        a = area(lo[idx].min(0), hi[idx].max(0))
        best = None
        if n > leaf_size:
            for axis in range(3):
                o = idx[np.argsort(c[idx, axis], kind="stable")]
                l_lo, l_hi = np.minimum.accumulate(lo[o]), np.maximum.accumulate(hi[o])
                r_lo = np.minimum.accumulate(lo[o][::-1])[::-1]
                r_hi = np.maximum.accumulate(hi[o][::-1])[::-1]
                i = np.arange(1, n)
                cost = ct * a + ci * (area(l_lo[:-1], l_hi[:-1]) * i +
                                      area(r_lo[1:], r_hi[1:]) * (n - i))
                k = int(np.argmin(cost))
                if best is None or cost[k] < best[0]:
                    best = (cost[k], o[: k + 1], o[k + 1:])
        if best is None or (n <= MAX_LEAF and not best[0] < ci * n * a):
            total += ci * n * a / root_area
            continue
        total += ct * a / root_area
        stack += [best[1], best[2]]
    return total


@pytest.mark.parametrize("scene", ["room", "fan"])
def test_sah_within_five_percent_of_a_full_sweep(scene):
    tris = scenes.generate(scene)
    tree = bsplab.build(tris, "bvh")
    live = tris[np.abs(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])).sum(1) > 0]
    # With the BVH's own costs (the registry's: its intersect_cost is not kd's).
    costs = bsplab.methods()["bvh"]["defaults"]
    ct = costs.get("traversal_cost", bsplab.option_schema()["traversal_cost"]["default"])
    ref = full_sweep_sah(live.astype(np.float64) * tree._tree.scale, ct, costs["intersect_cost"])
    ours = tree.stats["sah_cost"]
    assert ours <= 1.05 * ref, (scene, ours, ref)
    assert ours >= 0.9 * ref, (scene, ours, ref)  # the same cost formula, not a cheaper one


def test_the_tree_is_what_its_stats_say():
    tris = scenes.generate("room")
    tree = bsplab.build(tris, "bvh")
    s = tree.stats
    assert tree.structure == s["structure"] == "bvh"
    assert bsplab.build(tris, "kd").structure == "bsp"
    lo, hi, first, bits = walk(tree)
    interior = bits == 0xFFFFFFFF
    assert len(bits) == s["nodes"] == 2 * s["leaves"] - 1
    assert s["node_bytes"] == 32 * s["nodes"]
    # The binary nodes, refs and triangles, plus the 8-wide layout the walk
    # traces: 256-byte nodes, each lane's binary node (for the counters) and
    # the triangles in leaf order.
    assert s["wide_width"] == 8
    assert s["wide_bytes"] == (256 + 32) * s["wide_nodes"] + 40 * s["references"]
    assert s["bytes"] == 32 * s["nodes"] + 4 * s["references"] + 36 * s["triangles"] + s["wide_bytes"]
    assert 0 < s["wide_nodes"] < s["interior_nodes"] / 2
    assert s["kd_nodes"] == s["general_nodes"] == 0 and s["interior_nodes"] == interior.sum()
    refs = np.frombuffer(tree._tree.arrays()["refs"], np.uint32)
    # Every live triangle once, in exactly one leaf whose box holds it.
    assert sorted(refs) == sorted(set(range(len(tris))) - set(np.flatnonzero(
        np.abs(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])).sum(1) == 0)))
    t = tree._tree.triangles
    for i in np.flatnonzero(~interior):
        held = t[refs[first[i]: first[i] + bits[i]]]
        assert (held.min(axis=(0, 1)) >= lo[i]).all() and (held.max(axis=(0, 1)) <= hi[i]).all()
        assert 1 <= bits[i] <= MAX_LEAF
    # Children are pairs inside their parent's box.
    for i in np.flatnonzero(interior):
        for c in (first[i], first[i] + 1):
            assert (lo[c] >= lo[i]).all() and (hi[c] <= hi[i]).all()
    assert s["max_depth"] <= s["depth_limit"]


def test_the_same_tree_on_any_thread_count():
    # Big enough for spawned subtrees and the parallel binning of the root.
    tris = soup(80_000, seed=3)
    one = bsplab.build(tris, "bvh", threads=1).node_bytes()
    for threads in (2, 3):
        assert bsplab.build(tris, "bvh", threads=threads).node_bytes() == one


def test_options_change_the_tree():
    tris = scenes.generate("fan")
    base = bsplab.build(tris, "bvh")
    for opts in ({"bins": 4}, {"leaf_size": 8}, {"traversal_cost": 4.0}, {"max_depth": 3}):
        other = bsplab.build(tris, "bvh", **opts)
        assert other.node_bytes() != base.node_bytes(), opts
    assert bsplab.build(tris, "bvh", max_depth=3).stats["max_depth"] <= 3
    big = bsplab.build(tris, "bvh", leaf_size=8).stats
    assert big["leaves"] < base.stats["leaves"]
    with pytest.raises(ValueError, match="bins"):
        bsplab.build(tris, "bvh", bins=1)
    with pytest.raises(TypeError, match="unknown build option"):
        bsplab.build(tris, "kd", bins=8)


def test_memory_limit_stops_the_build():
    tris = soup(50_000)
    with pytest.raises(MemoryError, match=r"^bvh build needs more than 2 MB \(memory_limit_mb=2\)"):
        bsplab.build(tris, "bvh", memory_limit_mb=2)
    s = bsplab.build(tris, "bvh", memory_limit_mb=64).stats
    assert 0 < s["peak_bytes"] <= 64 * 2**20


def test_cancel_and_progress():
    tris = soup(200_000, seed=1)
    p = bsplab.Progress()
    bsplab.build(tris, "bvh", progress=p)
    assert p.value == pytest.approx(1.0, abs=1e-9)
    p = bsplab.Progress()
    p.cancel()
    with pytest.raises(bsplab.Cancelled):
        bsplab.build(tris, "bvh", progress=p)
    # Cancelled from another thread while it builds: its 50th node waits
    # for the cancel, so the build cannot have finished first.
    p = bsplab.Progress()
    p.hold_at_check(50)
    with cancelled_once_held(p) as seen, pytest.raises(bsplab.Cancelled):
        bsplab.build(tris, "bvh", progress=p, threads=2)
    assert len(seen) == 1 and seen[0] < 1 and p.value < 1


def test_bad_input():
    tris = scenes.generate("room").copy()
    tris[5, 1, 2] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        bsplab.build(tris, "bvh")
    with pytest.raises(ValueError, match="no triangles"):
        bsplab.build(np.zeros((0, 3, 3), np.float32), "bvh")
    # Only degenerate triangles: an empty tree that every ray misses.
    flat = np.zeros((4, 3, 3), np.float32)
    flat[:, 1] = 1.0
    tree = bsplab.build(flat, "bvh")
    assert tree.stats["nodes"] == 1 and tree.stats["references"] == 0
    h = tree.intersect(np.zeros((3, 3), np.float32) - 1, np.ones((3, 3), np.float32))
    assert (h["prim"] == -1).all() and np.isinf(h["t"]).all()
    assert tree.node_at((0.5, 0.5, 0.5)) is None


def test_tree_hash_is_recorded():
    # The recorded BVH trees (tree_hashes.json) are what a build gives now.
    from test_tree_hashes import RECORDED
    tris = scenes.generate("room")
    digest = hashlib.sha256(bsplab.build(tris, "bvh").node_bytes()).hexdigest()
    assert RECORDED["room/bvh"][0] == digest


# --- geometry queries -------------------------------------------------------------

def test_node_boxes():
    tris = scenes.generate("room")
    tree = bsplab.build(tris, "bvh")
    lo, hi, first, bits = walk(tree)
    b = tree.node_boxes(3)
    assert b["lo"].shape == b["hi"].shape == (len(b["node"]), 3) and b["lo"].dtype == np.float32
    assert b["depth"][0] == 0 and b["node"][0] == 0 and b["depth"].max() == 3
    assert (np.diff(b["depth"]) >= 0).all()  # level by level
    assert (b["leaf"] == (bits[b["node"]] != 0xFFFFFFFF)).all()
    np.testing.assert_array_equal(b["lo"], lo[b["node"]] / np.float32(tree._tree.scale))
    np.testing.assert_allclose(b["lo"][0], tree.bounds[0])
    np.testing.assert_allclose(b["hi"][0], tree.bounds[1])
    full = tree.node_boxes(64)
    assert len(full["node"]) == tree.stats["nodes"] and not full["cut"]
    cut = tree.node_boxes(64, max_boxes=10)
    assert cut["cut"] and len(cut["node"]) == 10
    sub = tree.node_boxes(1, root=int(first[0]))
    assert sub["node"][0] == first[0] and sub["depth"][0] == 0 and len(sub["node"]) <= 3
    with pytest.raises(ValueError, match="split planes, not boxes"):
        bsplab.build(tris, "kd").node_boxes(2)
    with pytest.raises(ValueError, match="a BVH has no split planes: use node_boxes"):
        tree.split_polygons(2)
    with pytest.raises(ValueError, match="a BVH has no split planes: use node_boxes"):
        tree.leaf_cells()


def test_node_at_is_the_first_leaf_holding_the_point():
    tris = scenes.generate("room")
    tree = bsplab.build(tris, "bvh")
    lo, hi, first, bits = walk(tree)
    scale = tree._tree.scale
    rng = np.random.default_rng(2)
    points = tris[rng.integers(0, len(tris), 50)].astype(np.float64).mean(axis=1)
    for p in points:
        node, depth = tree.node_at(p)
        assert bits[node] != 0xFFFFFFFF
        q = np.float32(p * scale)
        assert (lo[node] <= q).all() and (q <= hi[node]).all()
        at1 = tree.node_at(p, max_depth=1)
        assert at1[1] == 1 and at1[0] in (first[0], first[0] + 1)
    lo_w, hi_w = np.array(tree.bounds)
    assert tree.node_at(hi_w + 1.0) is None


def test_trace_path_records_the_boxes_the_ray_entered():
    tris = scenes.generate("room")
    tree = bsplab.build(tris, "bvh")
    lo_w, hi_w = np.array(tree.bounds)
    o = (lo_w - 0.5 * (hi_w - lo_w)).astype(np.float32)
    d = ((lo_w + hi_w) / 2 - o).astype(np.float32)
    p = tree.trace_path(o, d)
    h = tree.intersect(o[None], d[None])
    assert p["prim"] == h["prim"][0] >= 0 and p["box_tests"] == h["box_tests"][0] > 0
    assert set(p["kind"]) <= {BOX, LEAF} and p["kind"][0] == BOX
    assert p["box_lo"].shape == (p["steps"], 3) and np.isfinite(p["box_lo"]).all()
    assert np.isnan(p["plane"]).all()
    # The ray's range in each box lies on the box (within rounding).
    for (t0, t1), blo, bhi in zip(p["t_range"], p["box_lo"], p["box_hi"]):
        assert t0 <= t1
        mid = o + 0.5 * (t0 + t1) * d.astype(np.float64)
        pad = 1e-5 * (1 + np.abs(mid))
        assert (mid >= blo - pad).all() and (mid <= bhi + pad).all()
    kd_path = bsplab.build(tris, "kd").trace_path(o, d)
    assert np.isnan(kd_path["box_lo"]).all() and kd_path["box_tests"] == 0


# --- counters ------------------------------------------------------------------------

def test_counters_of_a_bvh_and_of_a_kd_tree():
    tris = scenes.generate("room")
    rays = agreement.FamilyRays(tris, 300, seed=4, families=["random_inside", "outside_in"])
    bvh, kd = bsplab.build(tris, "bvh"), bsplab.build(tris, "kd")
    for o, d, tmax, _ in rays.rays.values():
        h, k = bvh.intersect(o, d, tmax=tmax), kd.intersect(o, d, tmax=tmax)
        assert set(COUNTERS) <= set(h) and "box_tests" in COUNTERS
        assert (k["box_tests"] == 0).all() and (h["general_steps"] == 0).all()
        assert (h["culled"] == 0).all()
        # One box test at the root, eight at every wide node visited (the
        # walk of the 8-wide layout, all eight lanes in one test).
        entered = h["steps"] > 0
        assert (h["box_tests"][entered] % 8 == 1).all()
        assert (h["box_tests"][entered] > 1).all()
        assert (h["steps"] <= h["box_tests"]).all()
        # Culling is a no-op on a BVH: the same answers and counts.
        c = bvh.intersect(o, d, tmax=tmax, cull=True)
        for key in ("t", "prim", "u", "v") + COUNTERS:
            np.testing.assert_array_equal(c[key], h[key])


# --- hits: box-specific scenes and rays -------------------------------------------

def overlapping_boxes(n: int, seed: int) -> np.ndarray:
    """n axis-aligned boxes on a grid of eighths, most overlapping, some flat
    (zero thickness on one axis: a pair of quads) or sharing faces."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        a = rng.integers(-8, 8, 3)
        b = a + rng.integers(0, 6, 3)
        b[rng.integers(0, 3)] = a[rng.integers(0, 3)] if rng.random() < 0.3 else b[0]
        lo, hi = np.minimum(a, b) / 8, np.maximum(a, b) / 8
        hi = np.where(hi > lo, hi, lo)  # zero thickness kept: flat boxes
        out.append(fuzz._box_tris(lo, hi))
    tris = np.concatenate(out).astype(np.float32)
    return tris


def quads(n: int, seed: int) -> np.ndarray:
    """Axis-aligned quads (zero-thickness boxes) in few planes, many coplanar."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        axis = rng.integers(0, 3)
        u, v = (axis + 1) % 3, (axis + 2) % 3
        o = rng.integers(-6, 6, 3) / 4
        s = rng.integers(1, 5, 2) / 4
        a = o.copy(); b = o.copy(); c = o.copy(); d = o.copy()
        b[u] += s[0]; c[u] += s[0]; c[v] += s[1]; d[v] += s[1]
        out += [[a, b, c], [a, c, d]]
    return np.array(out, np.float32)


def box_face_rays(tree, n: int, seed: int):
    """Rays lying in the planes of BVH box faces (a face's coordinate, the
    direction's component on that axis 0), aimed at box corners and edges,
    and rays through box corners from outside."""
    rng = np.random.default_rng(seed)
    b = tree.node_boxes(64)
    lo, hi = b["lo"].astype(np.float64), b["hi"].astype(np.float64)
    k = rng.integers(0, len(lo), n)
    corner = np.where(rng.random((n, 3)) < 0.5, lo[k], hi[k])
    s_lo, s_hi = np.array(tree.bounds)
    ext = s_hi - s_lo
    o = rng.uniform(s_lo - 0.5 * ext, s_hi + 0.5 * ext, (n, 3))
    axis = rng.integers(0, 3, n)
    half = n // 2
    o[np.arange(half), axis[:half]] = corner[np.arange(half), axis[:half]]
    d = corner - o
    d[np.arange(half), axis[:half]] = 0.0
    ok = np.abs(d).sum(axis=1) > 0
    return o[ok].astype(np.float32), d[ok].astype(np.float32)


def assert_agrees_with_embree(tris, o, d, what):
    tree = bsplab.build(tris, "bvh")
    ref = oracle.EmbreeTracer(tris).intersect(o, d)
    kd = bsplab.build(tris, "kd").intersect(o, d, counters=False)
    for counters in (True, False):
        h = tree.intersect(o, d, counters=counters)
        c = oracle.compare(h, ref, triangles=tris, origins=o, directions=d)
        assert len(c["failing"]) == 0, (what, counters, c["failing"][:5])
        leak = oracle.leaks(h, ref, triangles=tris, origins=o, directions=d)
        assert len(leak) == 0, (what, counters, leak[:5])
    # Where the kd tree agrees with Embree too, the same bits.
    ck = oracle.compare(kd, ref, triangles=tris, origins=o, directions=d)
    both = np.setdiff1d(np.arange(len(o)), np.concatenate([ck["failing"], c["failing"]]))
    np.testing.assert_array_equal(h["prim"][both], kd["prim"][both])
    np.testing.assert_array_equal(h["t"][both].view(np.uint32), kd["t"][both].view(np.uint32))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_overlapping_and_flat_boxes(seed):
    for tris, what in ((overlapping_boxes(40, seed), "boxes"), (quads(60, seed), "quads")):
        tree = bsplab.build(tris, "bvh")
        o, d = box_face_rays(tree, 3000, seed)
        assert_agrees_with_embree(tris, o, d, f"{what} seed {seed} box faces")
        rays = agreement.FamilyRays(tris, 200, seed=seed)
        for name, c in rays.check(tree).items():
            assert len(c["failing"]) == 0 and len(c["leaks"]) == 0, (what, seed, name)


def test_box_face_rays_on_the_room():
    tris = scenes.generate("room")
    o, d = box_face_rays(bsplab.build(tris, "bvh"), 5000, 7)
    assert_agrees_with_embree(tris, o, d, "room box faces")

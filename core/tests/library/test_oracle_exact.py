"""The oracle's exact verdict (oracle.compare over bsplab.exact) on every ray
where a tree and Embree disagree: at scales where Embree's float test fails,
on instanced scenes with the transform's slack, on answers made wrong on
purpose, on rays exactly through edges and lying in faces' planes; and the
double-precision filter never loses the exact first hit."""

from __future__ import annotations

import numpy as np
import pytest

import bsplab
from bsplab import exact, instanced_scenes, oracle, ray_families

embreex = pytest.importorskip("embreex", reason="embreex is the oracle")

# Every ray lands in exactly one of these (oracle.compare's docstring).
CLASSES = ("agree", "embree_wrong", "grazing", "at_ends", "degenerate", "bsplab_wrong",
           "undecided")


def assert_partition(c):
    assert sum(c[k] for k in CLASSES) == c["rays"], {k: c[k] for k in CLASSES}
    assert len(c["failing"]) == c["bsplab_wrong"] + c["undecided"]
    assert len(c["embree_wrong_rays"]) == c["embree_wrong"]


def test_a_cube_at_1e16_every_embree_miss_is_judged_embree_wrong():
    """Embree's float test, its rounding relative to the coordinates' size,
    misses all 1,000 outside-in rays of a cube scaled by 1e16; we hit every
    one, and exactly so: no ray is left failing or undecided."""
    tris = (instanced_scenes.cube().astype(np.float64) * 1e16).astype(np.float32)
    o, d, tmax = ray_families.family("outside_in", tris, 1000, seed=0)
    ref = oracle.EmbreeTracer(tris).intersect(o, d, tmax=tmax)
    ours = bsplab.build(tris, "kd").intersect(o, d, tmax=tmax)
    assert (ref["prim"] < 0).all() and (ours["prim"] >= 0).all()
    c = oracle.compare(ours, ref, triangles=tris, origins=o, directions=d, tmax=tmax)
    assert_partition(c)
    assert c["embree_wrong"] == 1000
    assert c["bsplab_wrong"] == c["undecided"] == len(c["failing"]) == 0


def _scaled_instance(exp10: int):
    rng = np.random.default_rng(exp10 + 100)
    s = 10.0 ** exp10
    mats = np.array([instanced_scenes.affine(instanced_scenes.rotation(rng) * s,
                                             rng.uniform(-1, 1, 3) * s)])
    return bsplab.build_instanced([instanced_scenes.cube()], [0], mats, "kd")


@pytest.mark.parametrize("exp10", [-30, -25, -20, -15, 15, 20, 25, 30])
def test_instances_at_extreme_scales_are_judged_exactly_with_slack(exp10):
    """A rotated cube instance at 1e-30..1e-15 and 1e15..1e30: Embree, on the
    flattened scene, misses about half the outside-in rays that hit the
    cube; the two-level trace hits them. With the transform's slack and the
    instances' exact world triangles (matrix times vertex, in rationals),
    every such ray is embree_wrong and none fails."""
    it = _scaled_instance(exp10)
    flat = it.flatten()
    o, d, tmax = ray_families.family("outside_in", flat, 150, seed=1)
    ref = oracle.EmbreeTracer(flat).intersect(o, d, tmax=tmax)
    h = it.intersect(o, d, tmax=tmax)
    ours = {"t": h["t"], "prim": h["flat_prim"].astype(np.int32)}
    slack = np.maximum(it.transform_slack(o, d, h["t"], h["instance"]),
                       it.transform_slack(o, d, ref["t"], it.instance_of(ref["prim"])))
    for scene in (oracle.instanced_scene(it), None):  # exact instances; flattened floats
        c = oracle.compare(ours, ref, triangles=flat, origins=o, directions=d, tmax=tmax,
                           slack=slack, scene=scene)
        assert_partition(c)
        assert c["hit_only_ours"] > 20
        assert c["embree_wrong"] == c["hit_only_ours"] == len(c["disagreeing"])
        assert len(c["failing"]) == 0


def test_a_wrong_answer_is_reported_bsplab_wrong():
    """Our hits made wrong on purpose, far from any edge: the face behind
    instead of the front one, and a miss where the ray hits. Both are
    bsplab_wrong (failing), and Embree's right answers are not blamed."""
    tris = instanced_scenes.cube()
    o = np.array([[0.3, 0.4, 5.0], [0.6, 0.2, 5.0], [0.7, 0.3, 5.0]], np.float32)
    d = np.array([[0, 0, -1]] * 3, np.float32)
    ref = oracle.EmbreeTracer(tris).intersect(o, d)
    good = bsplab.build(tris, "kd").intersect(o, d)
    assert (ref["prim"] == good["prim"]).all() and (ref["prim"] >= 0).all()
    c = oracle.compare(good, ref, triangles=tris, origins=o, directions=d)
    assert c["agree"] == 3 and len(c["failing"]) == 0
    wrong = {k: v.copy() for k, v in good.items()}
    behind = [k for k in range(len(tris)) if (tris[k][:, 2] == 0).all()
              and oracle.exact_hit_t(tris[k], o[0], d[0]) == 5]
    assert len(behind) == 1
    wrong["prim"][0], wrong["t"][0] = behind[0], np.float32(5.0)
    wrong["prim"][1], wrong["t"][1] = -1, np.inf
    c = oracle.compare(wrong, ref, triangles=tris, origins=o, directions=d)
    assert_partition(c)
    assert list(c["bsplab_wrong_rays"]) == list(c["failing"]) == [0, 1]
    assert c["embree_wrong"] == 0 and c["agree"] == 1


def test_a_ray_exactly_through_a_shared_edge_hits_both_triangles():
    """Straight down onto the top face's diagonal (0.5, 0.5, 1), exactly:
    both triangles of the face are hit at t = 4, a tie either side may
    report. A miss there is ours wrong, though within rounding of the edge
    (grazing); Embree's miss where we hit either is embree_wrong."""
    tris = instanced_scenes.cube()
    top = [k for k in range(len(tris)) if (tris[k][:, 2] == 1).all()]
    o = np.array([[0.5, 0.5, 5.0]], np.float32)
    d = np.array([[0, 0, -1]], np.float32)
    ray = exact.RayVerdict(exact.ExactScene.triangles(tris), o[0], d[0], 0.0, np.inf)
    assert ray.first_open == set(top) and all(ray.t[k] == 4 for k in top)
    assert ray.verdict(-1) == exact.WRONG
    hit = {"t": np.array([4.0], np.float32), "prim": np.array([top[1]], np.int32)}
    miss = {"t": np.array([np.inf], np.float32), "prim": np.array([-1], np.int32)}
    kw = dict(triangles=tris, origins=o, directions=d)
    c = oracle.compare(hit, miss, **kw)
    assert c["embree_wrong"] == 1 and len(c["failing"]) == 0
    c = oracle.compare(miss, hit, **kw)
    assert c["grazing"] == 1 and c["embree_wrong"] == 0 and len(c["failing"]) == 0


def test_a_hit_on_a_face_the_ray_lies_in_is_undecided():
    """Down the cube's side face x = 1 onto its top edge: the ray lies in
    the side face's plane (no crossing point: exact.UNDECIDED for a side
    that reports it) and hits the top face exactly on its edge."""
    tris = instanced_scenes.cube()
    side = [k for k in range(len(tris)) if (tris[k][:, 0] == 1).all()]
    top = [k for k in range(len(tris)) if (tris[k][:, 2] == 1).all()]
    o = np.array([1.0, 0.25, 3.0], np.float32)
    d = np.array([0, 0, -1], np.float32)
    ray = exact.RayVerdict(exact.ExactScene.triangles(tris), o, d, 0.0, np.inf)
    assert set(side) <= ray.in_plane
    assert ray.first_open and ray.first_open <= set(top)
    assert ray.verdict(side[0]) == exact.UNDECIDED
    assert ray.verdict(min(ray.first_open)) == exact.RIGHT


def test_ends_of_the_segment_open_for_us_closed_for_embree():
    """A ray that meets the top face at exactly t = tmax = 4: no hit on our
    open segment, Embree's hit on its closed one; compare calls that
    at_ends and blames neither side."""
    tris = instanced_scenes.cube()
    o = np.array([[0.3, 0.4, 5.0]], np.float32)
    d = np.array([[0, 0, -1]], np.float32)
    ray = exact.RayVerdict(exact.ExactScene.triangles(tris), o[0], d[0], 0.0, 4.0)
    assert not ray.first_open and len(ray.first_closed) == 1
    front = min(ray.first_closed)
    assert ray.t[front] == 4
    assert ray.verdict(-1) == exact.RIGHT and ray.verdict(front) == exact.WRONG
    assert ray.verdict(front, closed=True) == exact.RIGHT
    miss = {"t": np.array([np.inf], np.float32), "prim": np.array([-1], np.int32)}
    hit = {"t": np.array([4.0], np.float32), "prim": np.array([front], np.int32)}
    c = oracle.compare(miss, hit, triangles=tris, origins=o, directions=d, tmax=4.0)
    assert c["at_ends"] == 1 and c["embree_wrong"] == 0 and len(c["failing"]) == 0


@pytest.mark.parametrize("scale", [1.0, 1e16, 1e-20])
def test_the_filter_never_drops_the_exact_first_hit(scale):
    """RayVerdict (filter, then integers) against every triangle tested one
    by one in fractions (oracle.exact_hit_t), on rays through edges and
    vertices, in planes and along edges of a 128-triangle patch of the fan
    (slivers meeting at a vertex), scaled."""
    tris = (bsplab.scenes.generate("fan")[:128].astype(np.float64) * scale).astype(np.float32)
    scene = exact.ExactScene.triangles(tris)
    checked = 0
    for family in ("through_edges", "through_vertices", "in_planes", "along_edges",
                   "from_surfaces"):
        o, d, tmax = ray_families.family(family, tris, 12, seed=3)
        tmax = np.broadcast_to(np.asarray(tmax, np.float64), (len(o),))
        for i in range(len(o)):
            end = None if np.isinf(tmax[i]) else float(np.float32(tmax[i]))
            ts = [oracle.exact_hit_t(t, o[i], d[i]) for t in tris]
            ts = [t if t is not None and (end is None or t < end) else None for t in ts]
            hits = [t for t in ts if t is not None]
            got, t_got = exact.RayVerdict(scene, o[i], d[i], 0.0, tmax[i]).first_hit()
            if not hits:
                assert got == -1, (family, i)
                continue
            best = min(hits)
            assert t_got == best and got == ts.index(best), (family, i)
            checked += 1
    assert checked > 20

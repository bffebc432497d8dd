"""Property-based fuzzing: every method on random small scenes (boxes sharing
faces, tilted boxes, coplanar grids, slivers, degenerate and duplicated
triangles, soups, fans; at scales from 1e-3 to 1e3 and far from the origin),
every ray family, every hit checked against Embree with the double-precision
tie-break of `oracle.compare`.

Profiles: the default (CI) runs 150 fixed (derandomized) examples in a few
seconds; BSPLAB_FUZZ=long runs 20,000 fresh random ones. A failure prints
the scene spec; add it to fuzz_regressions.json (the replay test below then
keeps it on every method)."""

from __future__ import annotations

import itertools
import json
import os
from pathlib import Path

import numpy as np
import pytest

import bsplab
from bsplab import agreement, fuzz, oracle

hypothesis = pytest.importorskip("hypothesis")
embreex = pytest.importorskip("embreex", reason="embreex is the oracle")
from hypothesis import HealthCheck, given, settings, strategies as st  # noqa: E402

LONG = os.environ.get("BSPLAB_FUZZ") == "long"
# Under the sanitizers (core/tools/sanitize.sh) a third of the examples:
# each runs 3-5 times slower there.
SANITIZED = bool(os.environ.get("BSPLAB_EXPECT_CORE"))


def examples(n: int) -> int:
    return 20_000 if LONG else (n // 3 if SANITIZED else n)


METHODS = bsplab.methods()
REGRESSIONS = Path(__file__).with_name("fuzz_regressions.json")
RAYS_PER_FAMILY = 120

coord = st.integers(-16, 16)
point = st.tuples(coord, coord, coord)
small = st.integers(0, 40)


@st.composite
def part(draw, kinds=fuzz.KINDS) -> dict:
    kind = draw(st.sampled_from(kinds))
    p = {"kind": kind, "seed": draw(st.integers(0, 2**16))}
    if kind == "box":
        p.update(a=list(draw(point)), b=list(draw(point)))
    elif kind == "tilted_box":
        p.update(half=list(draw(st.tuples(small, small, small))), at=list(draw(point)))
    elif kind == "grid":
        p.update(axis=draw(st.integers(0, 2)), n=draw(small), size=draw(small),
                 at=list(draw(point)))
    elif kind == "sliver":
        p.update(count=draw(small), width_exp=draw(small), at=list(draw(point)))
    else:
        p.update(count=draw(small), at=list(draw(point)))
    return p


def fuzz_settings(n: int):
    """The fuzz tests' hypothesis settings, `n` examples in the default profile."""
    return settings(max_examples=examples(n), deadline=None, derandomize=not LONG,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


# Where the scenes lie: at the origin, off it, and far from it in scene
# sizes, where the trees build and walk in a local frame (core/src/frame.hpp).
OFFSETS = [(0, 0, 0), (1000, -2000, 500), (1e5, 0, 0), (1e6, -3e6, 2e5), (-1e7, 0, 5e6)]


def scene_specs_of(parts=None, **fields) -> st.SearchStrategy:
    """Scene specs: up to five parts (of fuzz.KINDS unless `parts`), at every
    scale and offset, with the method's `fields`."""
    return st.fixed_dictionaries({
        "parts": parts if parts is not None else st.lists(part(), min_size=1, max_size=5),
        "scale_exp": st.integers(-3, 3),
        "offset": st.sampled_from(OFFSETS),
        **fields,
    })


scene_specs = scene_specs_of(
    method=st.sampled_from(list(METHODS)),
    k=st.integers(1, 9),
)


def method_options(case: dict) -> dict:
    """The case's k, clamped to its method's range, for methods that take one."""
    info = METHODS[case["method"]]
    if "k" not in info["params"]:
        return {}
    return {"k": min(max(case["k"], info["min_k"]), info["max_k"])}


def assert_none(rays, what: str, label: str, case: dict, o, d, ours: dict, ref: dict) -> None:
    """Fails when `rays` (indices) is not empty, naming the scene and three
    of the rays with both answers."""
    e = np.asarray(rays, dtype=np.int64)[:3]
    assert len(rays) == 0, (
        f"{label}: {len(rays)} {what}; scene {json.dumps(case)}; e.g. o {o[e].tolist()} "
        f"d {d[e].tolist()}: ours {ours['prim'][e]} t {ours['t'][e]}, Embree {ref['prim'][e]} "
        f"t {ref['t'][e]}")


def check_spec(case: dict) -> None:
    tris = fuzz.build_scene(case["parts"], case["scale_exp"], case["offset"])
    n2 = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    if not np.any(np.abs(n2.astype(np.float64)).sum(axis=1) > 0):
        return  # nothing that can be hit: build() refuses scenes without triangles
    method, opts = case["method"], {**method_options(case), **case.get("options", {})}
    tree = bsplab.build(tris, method=method, **opts)
    rays = agreement.FamilyRays(tris, RAYS_PER_FAMILY, seed=len(tris))
    checked = rays.check(tree)
    for name, c in checked.items():
        o, d, _, ref = rays.rays[name]
        label = f"{method} {opts}"
        assert_none(c["failing"], f"{name} rays disagree with Embree", label, case, o, d,
                    c["hits"], ref)
        # A leak - a miss or a farther hit where Embree hits (oracle.leaks) -
        # is wrong even when the double-precision tie-break could explain it.
        assert_none(c["leaks"], f"{name} rays leak", label, case, o, d, c["hits"], ref)
    check_sorted_batch(tree, rays, {n: c["hits"] for n, c in checked.items()},
                       f"{method} {opts}", case)


def check_sorted_batch(tracer, rays, hits: dict, label: str, case: dict,
                       keys=("t", "prim", "u", "v")) -> None:
    """Every family's rays, repeated (three times at least) and shuffled into
    one batch of more than kOrderMinRays: the hits-only path traces it in
    spatial order (core/src/trace/ray_order.hpp) and must give each ray the
    hit in `hits` (per family: the answers Embree has just checked) bit for
    bit, in every one of `keys`. `tracer`: a Tree or an InstancedTree."""
    names = list(rays.rays)
    total = sum(len(rays.rays[n][0]) for n in names)
    copies = max(3, -(-4200 // max(total, 1)))  # past ray_order.hpp's kOrderMinRays
    o = np.concatenate([rays.rays[n][0] for n in names] * copies)
    d = np.concatenate([rays.rays[n][1] for n in names] * copies)
    tmax = np.concatenate([rays.rays[n][2] for n in names] * copies)
    want = {k: np.concatenate([hits[n][k] for n in names] * copies) for k in keys}
    perm = np.random.default_rng(len(o)).permutation(len(o))
    got = tracer.intersect(o[perm], d[perm], tmax=tmax[perm], counters=False,
                           ray_order="spatial")
    # Bit for bit (a NaN would not equal itself).
    differ = np.flatnonzero(np.any([got[k].view(np.uint32) != want[k][perm].view(np.uint32)
                                    for k in keys], axis=0))
    assert_none(differ, "rays differ in spatial order", label, case, o[perm], d[perm], got,
                {k: v[perm] for k, v in want.items()})


@fuzz_settings(150)
@given(scene_specs)
def test_every_method_agrees_with_embree_on_random_scenes(case):
    check_spec(case)


# The BVH on scenes with its own parts too (fuzz.BOX_KINDS: overlapping and
# flat boxes, axis-aligned quads), at every scale and offset.
box_scene_specs = scene_specs_of(
    st.lists(part(fuzz.KINDS + fuzz.BOX_KINDS), min_size=1, max_size=5),
    method=st.just("bvh"), k=st.just(1))


@fuzz_settings(60)
@given(box_scene_specs)
def test_the_bvh_agrees_with_embree_on_random_box_scenes(case):
    check_spec(case)


# Fast builds (build_quality="fast") of kd and the sweep builder, binned down
# to nodes of a few references so that the fuzzer's small scenes bin most of
# their levels.
fast_specs = scene_specs_of(
    method=st.sampled_from(["kd", "bsp_wn+kd", "bsp_ize+kd", "bsp_random"]),
    k=st.integers(3, 6),
    options=st.fixed_dictionaries({"build_quality": st.just("fast"),
                                   "fast_min_refs": st.sampled_from([2, 8, 64]),
                                   "fast_bins": st.sampled_from([2, 5, 32])}))


@fuzz_settings(60)
@given(fast_specs)
def test_fast_trees_agree_with_embree_on_random_scenes(case):
    check_spec(case)


# Fast kd builds that cut straddling triangles' boxes at the plane instead
# of clipping the triangles (fast_clip_min_refs), from a few nodes at the
# bottom to every split, with and without binned nodes above.
cut_specs = scene_specs_of(
    method=st.just("kd"),
    k=st.just(3),
    options=st.fixed_dictionaries({"build_quality": st.just("fast"),
                                   "fast_min_refs": st.sampled_from([8, 64, 1 << 20]),
                                   "fast_clip_min_refs": st.sampled_from([4, 12, 1 << 20]),
                                   "leaf_boxes": st.sampled_from(["triangle", "clipped"])}))


@fuzz_settings(40)
@given(cut_specs)
def test_fast_kd_trees_that_cut_boxes_agree_with_embree_on_random_scenes(case):
    check_spec(case)


def regressions() -> list[dict]:
    return json.loads(REGRESSIONS.read_text()) if REGRESSIONS.exists() else []


@pytest.mark.parametrize("case", regressions(), ids=lambda c: c.get("name", "case"))
def test_fuzz_regressions(case):
    """Scenes the fuzzer (or a user) once broke a tree with, replayed on
    every method."""
    for method in METHODS:
        check_spec({**case, "method": method})


# Instanced scenes (bsplab.build_instanced): a few meshes of the parts above,
# placed by instances of every matrix kind (fuzz.MATRIX_KINDS: exact grid
# moves and quarter turns that make instances share faces, random rotations,
# uneven scales, mirrors, shears, powers of ten), every bottom method, every
# ray family against Embree over the flattened scene with the transform's
# rounding as the only extra tolerance (InstancedTree.transform_slack).
instance = st.fixed_dictionaries({
    "mesh": st.integers(0, 2),
    "kind": st.sampled_from(fuzz.MATRIX_KINDS),
    "seed": st.integers(0, 2**16),
    "at": st.tuples(coord, coord, coord).map(list),
    "e": st.integers(-3, 3),
})
instanced_specs = st.fixed_dictionaries({
    "meshes": st.lists(st.lists(part(), min_size=1, max_size=3), min_size=1, max_size=3),
    "instances": st.lists(instance, min_size=1, max_size=12),
    "method": st.sampled_from(["kd", "bvh", "bsp_wn+kd", "bsp_cn", "rbsp"]),
    "k": st.integers(1, 9),
})


def check_instanced_spec(case: dict) -> None:
    meshes, idx, mats = fuzz.build_instanced_scene(case)
    live = [m for m in meshes if (np.abs(np.cross(m[:, 1] - m[:, 0], m[:, 2] - m[:, 0])
                                         .astype(np.float64)).sum(axis=1) > 0).any()]
    if len(live) < len(meshes) or not len(idx):
        return  # a mesh without a hittable triangle: build() refuses it
    method, opts = case["method"], {**method_options(case), **case.get("options", {})}
    it = bsplab.build_instanced(meshes, idx, mats, method, **opts)
    flat = it.flatten()
    rays = agreement.FamilyRays(flat, RAYS_PER_FAMILY // 2, seed=len(flat))
    checked = {}
    for (name, (o, d, tmax, ref)), packets in itertools.product(rays.rays.items(),
                                                                 (False, True)):
        h = it.intersect(o, d, tmax=tmax, counters=False, packets=packets)
        if not packets:
            checked[name] = h
        ours = {"t": h["t"], "prim": h["flat_prim"].astype(np.int32)}
        slack = np.maximum(it.transform_slack(o, d, h["t"], h["instance"]),
                           it.transform_slack(o, d, ref["t"], it.instance_of(ref["prim"])))
        c = oracle.compare(ours, ref, triangles=flat, origins=o, directions=d, tmax=tmax,
                           slack=slack)
        label = f"{method} {opts}{' packets' if packets else ''}"
        assert_none(c["failing"], f"{name} rays disagree with Embree", label, case, o, d,
                    ours, ref)
        if name in agreement.CROSSING_FAMILIES:
            leak = oracle.leaks(ours, ref, triangles=flat, origins=o, directions=d, tmax=tmax,
                                slack=slack)
            assert_none(leak, f"{name} rays leak", label, case, o, d, ours, ref)
    # Unless every mesh tree is a BVH, the batch is traced in spatial order.
    check_sorted_batch(it, rays, checked, f"{method} {opts}", case,
                       keys=("t", "prim", "u", "v", "instance"))


@fuzz_settings(40)
@given(instanced_specs)
def test_instanced_scenes_agree_with_embree_on_the_flattened_scene(case):
    check_instanced_spec(case)


# Instanced scenes the fuzzer once broke, replayed.
INSTANCED_REGRESSIONS = [
    # Two coincident rotated instances of one box: grazing rays hit copy 0
    # (at the exact plane distance) where Embree hit copy 1 at a t 1.1e-4
    # short: one surface, either copy right (oracle.compare's duplicates).
    {"meshes": [[{"kind": "box", "seed": 0, "a": [0, -10, 11], "b": [-3, 8, -10]}]],
     "instances": [{"mesh": 0, "kind": "rotate", "seed": 65536, "at": [0, 0, 0], "e": 0},
                   {"mesh": 0, "kind": "rotate", "seed": 65536, "at": [0, 0, 0], "e": 0}],
     "method": "kd", "k": 1},
    # A mirrored box: a ray through the shared edge of faces 3 and 7 hit 3
    # in Embree's flattened scene and grazing 7 (cos 0.0057) 2.7e-4 farther
    # in ours; Embree on our rounded object-space ray hits 7 there too. The
    # transform's slack (7e-7) carries the ray across the edge, and 7's
    # plane is slack / (|d| cos) farther along it (oracle._across_shared_edge).
    {"meshes": [[{"kind": "box", "seed": 0, "a": [2, 10, 0], "b": [2, 10, 0]}]],
     "instances": [{"mesh": 0, "kind": "mirror", "seed": 1275, "at": [0, 0, 0], "e": 0}],
     "method": "kd", "k": 1},
    # A zero-thickness box at 1e-3 scale: a ray 9e-8 from its rim hit the top
    # face in Embree's flattened scene and nothing in ours, nor in Embree's
    # on our rounded object-space ray. The rim's other triangle is a sliver
    # 1e-7 wide seen along the ray (cos 6e-4), under the slack of 5e-6: the
    # displaced ray passes beside it (mesh_edges.crosses_surface's slack).
    {"meshes": [[{"kind": "tilted_box", "seed": 29458, "half": [16, 16, 0], "at": [0, 0, 0]}],
                [{"kind": "box", "seed": 0, "a": [0, 0, 0], "b": [0, 0, 0]}],
                [{"kind": "soup", "seed": 65536, "count": 7, "at": [-9, 15, -10]},
                 {"kind": "box", "seed": 0, "a": [-5, 0, 12], "b": [-6, -6, -5]},
                 {"kind": "duplicate", "seed": 172, "count": 0, "at": [0, 0, 0]}]],
     "instances": [{"mesh": 0, "kind": "scale", "seed": 0, "at": [-8, -13, 15], "e": -3},
                   {"mesh": 2, "kind": "mirror", "seed": 2032, "at": [4, -14, 13], "e": 0},
                   {"mesh": 2, "kind": "mirror", "seed": 0, "at": [16, 16, -16], "e": 0}],
     "method": "kd", "k": 1},
    # The packet path on a ray along an edge: instance 1's kd tree hits it at
    # 0.430 with the segment to infinity and misses it cut at 0.687 (instance
    # 2's hit, which the single-ray walk met first), Embree 0.549: in-plane,
    # each answer within the oracle's rules, the two paths' differing.
    {"meshes": [[{"kind": "box", "seed": 86, "a": [-2, 15, 14], "b": [-4, -7, -9]}],
                [{"kind": "box", "seed": 86, "a": [-2, 15, 14], "b": [-4, -7, -9]}],
                [{"kind": "tilted_box", "seed": 3141, "half": [17, 31, 35], "at": [9, 10, 0]},
                 {"kind": "box", "seed": 936, "a": [-12, -1, 12], "b": [-14, -11, -4]},
                 {"kind": "tilted_box", "seed": 3141, "half": [17, 31, 35], "at": [9, 10, 0]}]],
     "instances": [{"at": [-8, -3, -11], "e": 0, "seed": 122, "kind": "shear", "mesh": 0},
                   {"seed": 73, "at": [-8, -3, -11], "mesh": 2, "e": 1, "kind": "turn"},
                   {"seed": 444, "mesh": 2, "at": [-8, -3, -11], "e": 0, "kind": "scale"}],
     "method": "kd", "k": 5},
]


@pytest.mark.parametrize("case", INSTANCED_REGRESSIONS)
def test_instanced_fuzz_regressions(case):
    check_instanced_spec(case)

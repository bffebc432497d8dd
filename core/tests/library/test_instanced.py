"""Instanced scenes in two levels (bsplab.build_instanced): every hit checked
against Embree's on the flattened scene, on every ray family, on the
instanced test scenes (rotations, non-uniform, mirrored and sheared scales,
touching, overlapping and nested instances, 1e-4 and 1e4 in one scene);
bit-identical to the mesh tree where the transform is exact; the bottom
trees shared; bad instances refused with their number."""

from __future__ import annotations

import numpy as np
import pytest

import bsplab
from bsplab import instanced_scenes, oracle, ray_families
from bsplab.render import geometric_normals

RAYS = 1000


@pytest.fixture(scope="module", params=sorted(instanced_scenes.TEST_SCENES))
def scene(request):
    return request.param, instanced_scenes.TEST_SCENES[request.param]()


def _flat_hits(h):
    return {"t": h["t"], "prim": h["flat_prim"].astype(np.int32)}


_families: dict = {}


def families_and_embree(name, flat):
    """Every family's rays and Embree's answers on a flattened scene, made
    once per scene for its three methods: the flattened triangles are the
    same whatever the method (checked: made again if not), and on the
    278k-triangle 'transformed' scene the families (its edges' tables) and
    Embree took about 60% of each case."""
    cached = _families.get(name)
    if cached is None or not np.array_equal(cached[0], flat):
        out = {}
        embree = oracle.EmbreeTracer(flat)
        for family in ray_families.FAMILIES:
            o, d, tmax = ray_families.family(family, flat, RAYS, seed=7)
            out[family] = (o, d, tmax, embree.intersect(o, d, tmax=tmax))
        _families[name] = cached = (flat.copy(), out)
    return cached[1]


@pytest.mark.parametrize("method", ["kd", "bvh", "bsp_wn+kd"])
def test_hits_agree_with_embree_on_the_flattened_scene(scene, method):
    name, (meshes, idx, mats) = scene
    opts = {"k": 4} if method.startswith("bsp") else {}
    it = bsplab.build_instanced(meshes, idx, mats, method, **opts)
    flat = it.flatten()
    failing = {}
    exact_scene = oracle.instanced_scene(it)
    for family, (o, d, tmax, ref) in families_and_embree(name, flat).items():
        # Both paths: single rays, and the packet path (groups through the
        # top level, the mesh trees' packet kernels; the same hits but where
        # a mesh tree's answer depends on the segment's end - docs/instances.md).
        for path, packets in (("single", False), ("packets", True)):
            ours = it.intersect(o, d, tmax=tmax, threads=1 + packets, counters=False,
                                packets=packets)
            # The only tolerance beyond the oracle's: the transform's rounding,
            # of the instance we hit and of the one Embree hit.
            slack = np.maximum(
                it.transform_slack(o, d, ours["t"], ours["instance"]),
                it.transform_slack(o, d, ref["t"], it.instance_of(ref["prim"])))
            c = oracle.compare(_flat_hits(ours), ref, triangles=flat, origins=o, directions=d,
                               tmax=tmax, slack=slack, scene=exact_scene)
            if len(c["failing"]):
                failing[f"{family} {path}"] = c["failing"][:5].tolist()
            leaked = oracle.leaks(_flat_hits(ours), ref, triangles=flat, origins=o,
                                  directions=d, tmax=tmax, slack=slack)
            assert leaked.size == 0, (name, method, family, path, leaked[:5])
    assert not failing, (name, method, failing)


def test_counting_path_gives_the_same_hits_and_counts_both_levels(scene):
    _, (meshes, idx, mats) = scene
    it = bsplab.build_instanced(meshes, idx, mats, "kd")
    flat = it.flatten()
    o, d, _ = ray_families.family("random_inside", flat, 2000, seed=3)
    fast = it.intersect(o, d, counters=False)
    counted = it.intersect(o, d, counters=True, threads=2)
    for k in ("t", "prim", "u", "v", "instance", "flat_prim"):
        np.testing.assert_array_equal(fast[k], counted[k], err_msg=k)
    hit = counted["instance"] >= 0
    assert hit.any()
    assert (counted["top_steps"][hit] >= 1).all()
    assert (counted["instance_visits"][hit] >= 1).all()
    assert (counted["tests"][hit] >= 1).all()
    # A ray's instance visits are at most the instances there are.
    assert counted["instance_visits"].max() <= len(idx)


@pytest.mark.parametrize("method", ["kd", "bvh"])
def test_an_identity_instance_traces_bit_for_bit_as_its_tree(method):
    tris = bsplab.scenes.generate("room")
    tree = bsplab.build(tris, method)
    it = bsplab.build_instanced([tree], [0], np.hstack([np.eye(3), np.zeros((3, 1))])[None])
    assert it.meshes[0] is tree  # a built tree is shared, not rebuilt
    for family in ("outside_in", "through_edges", "edges_in_split_planes", "random_inside"):
        o, d, tmax = ray_families.family(family, tris, 2000, seed=1)
        a = tree.intersect(o, d, tmax=tmax, counters=False)
        b = it.intersect(o, d, tmax=tmax, counters=False)
        for k in ("t", "prim", "u", "v"):
            np.testing.assert_array_equal(a[k], b[k], err_msg=f"{family} {k}")
        assert ((b["instance"] == 0) == (a["prim"] >= 0)).all()


def test_of_two_coincident_instances_the_first_is_hit():
    cube = instanced_scenes.cube()
    mats = np.array([instanced_scenes.affine(np.eye(3), (0, 0, 0))] * 3)
    it = bsplab.build_instanced([cube], [0, 0, 0], mats, "kd")
    o, d, _ = ray_families.family("outside_in", it.flatten(), 500, seed=2)
    h = it.intersect(o, d)
    hit = h["instance"] >= 0
    assert hit.sum() > 100
    assert (h["instance"][hit] == 0).all()  # the smallest flattened index of equal t


def test_bottom_trees_are_shared_and_the_top_level_is_small():
    meshes, idx, mats = instanced_scenes.scatter([instanced_scenes.cube(),
                                                  bsplab.scenes.generate("fan")], 2000, 100.0)
    it = bsplab.build_instanced(meshes, idx, mats, "kd")
    s = it.stats
    assert s["meshes"] == 2 and s["instances"] == 2000
    assert s["bottom_bytes"] == sum(bsplab.build(m, "kd").stats["bytes"] for m in meshes)
    assert s["instanced_triangles"] == sum(len(meshes[i]) for i in idx)
    assert s["top_bytes_per_instance"] <= 200
    # Moving instances rebuilds the top level only: the same trees, shared.
    moved = mats.copy()
    moved[:, :, 3] += 1.0
    again = bsplab.build_instanced(it.meshes, idx, moved, "kd")
    assert all(a is b for a, b in zip(again.meshes, it.meshes))
    o = np.array([[0.3, 0.2, 50.0]], np.float32) + moved[:1, :, 3].astype(np.float32)
    d = np.array([[0, 0, -1]], np.float32)
    assert again.intersect(o, d)["t"][0] == pytest.approx(
        it.intersect(o - 1.0, d)["t"][0], rel=1e-5)


def test_threads_give_the_same_hits():
    meshes, idx, mats = instanced_scenes.transformed()
    it = bsplab.build_instanced(meshes, idx, mats, "bvh")
    o, d, _ = ray_families.family("random_inside", it.flatten(), 3000, seed=4)
    a = it.intersect(o, d, threads=1, counters=False)
    b = it.intersect(o, d, threads=2, counters=False)
    for k in ("t", "prim", "instance"):
        np.testing.assert_array_equal(a[k], b[k])


@pytest.mark.parametrize("matrix, message", [
    (np.zeros((3, 4)), "instance 1: its matrix is singular"),
    (np.array([[1, 0, 0, 0], [0, 1, 0, 0], [1, 1, 0, 0]], float), "instance 1: its matrix is singular"),
    (np.array([[1, 0, 0, np.nan], [0, 1, 0, 0], [0, 0, 1, 0]]), "instance 1: its matrix has a non-finite"),
    (np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]], float), "not 0 0 0 1"),
])
def test_bad_matrices_are_refused_by_instance(matrix, message):
    cube = instanced_scenes.cube()
    good = np.eye(4)[:matrix.shape[0]] if matrix.shape[0] == 4 else np.eye(4)[:3]
    with pytest.raises(ValueError, match=message):
        bsplab.build_instanced([cube], [0, 0], np.array([good, matrix]), "kd")
    # The same refusal from the check alone (what the add-on asks before it
    # builds the mesh trees itself).
    with pytest.raises(ValueError, match=message):
        bsplab.check_instance_matrices(np.array([good, matrix]))


def test_the_matrix_check_is_the_builds_and_builds_nothing():
    m = np.array([np.eye(4), np.diag([2.0, -1.0, 1e-3, 1.0])])
    checked = bsplab.check_instance_matrices(m)
    assert checked.shape == (2, 3, 4) and checked.dtype == np.float64
    assert np.array_equal(checked, m[:, :3, :])
    # Near the core's limit (|det A| > 1e-12 |A|^3): just above passes, below fails.
    ok = np.diag([1.0, 1.0, 2e-12, 1.0])[:3]
    bad = np.diag([1.0, 1.0, 0.5e-12, 1.0])[:3]
    bsplab.check_instance_matrices([ok])
    with pytest.raises(ValueError, match="instance 0: its matrix is singular"):
        bsplab.check_instance_matrices([bad])
    # A singular instance fails the build before any mesh tree is built:
    # the progress of the mesh builds never moves.
    progress = bsplab.Progress()
    with pytest.raises(ValueError, match="instance 1: its matrix is singular"):
        bsplab.build_instanced([instanced_scenes.uv_sphere()], [0, 0],
                               np.array([np.eye(4)[:3], bad]), "kd", progress=progress)
    assert progress.value == 0.0
    bsplab.build_instanced([instanced_scenes.uv_sphere()], [0, 0],
                           np.array([np.eye(4)[:3], ok]), "kd", progress=progress)
    assert progress.value > 0.0


@pytest.mark.parametrize("kwargs, error, message", [
    ({"mesh_index": [0, 2]}, ValueError, "instance 1: mesh index 2 is out of range"),
    ({"mesh_index": [0.5, 1]}, TypeError, "mesh_index must be a 1-d array of integers"),
    ({"matrices": np.zeros((1, 3, 4))}, ValueError, "one matrix per instance"),
    ({"matrices": np.zeros((2, 3, 3))}, ValueError, r"shape \(M, 3, 4\)"),
    ({"meshes": []}, ValueError, "non-empty list"),
    ({"top": "kd"}, ValueError, "top"),
    ({"top_bins": 1}, ValueError, "top_bins"),
])
def test_bad_arguments_are_refused(kwargs, error, message):
    cube = instanced_scenes.cube()
    args = {"meshes": [cube, cube], "mesh_index": [0, 1],
            "matrices": np.array([np.eye(4)[:3]] * 2), **kwargs}
    with pytest.raises(error, match=message):
        bsplab.build_instanced(args.pop("meshes"), args.pop("mesh_index"), args.pop("matrices"),
                               "kd", **args)


@pytest.mark.parametrize("mode", ["shaded", "normal", "depth", "heat_steps"])
def test_render_matches_the_flattened_scene(mode):
    meshes, idx, mats = instanced_scenes.transformed(count=20)
    it = bsplab.build_instanced(meshes, idx, mats, "kd")
    flat = bsplab.build(it.flatten(), "kd")
    cam = bsplab.Camera.look_at((9, -7, 6), (0, 0, 0), fov_deg=45)
    a, sa = bsplab.render(it, cam, 64, 48, mode)
    b, sb = bsplab.render(flat, cam, 64, 48, mode)
    assert sa["hits"] > 500 and abs(sa["hits"] - sb["hits"]) <= 3
    if mode == "heat_steps":  # different trees: only the counting and the hits
        assert sa["counters"] and sa["mean_steps"] > 0
        return
    close = np.isclose(a, b, atol=2e-3).all(axis=2)
    assert close.mean() > 0.995, close.mean()


def test_hit_normals_are_the_flattened_triangles_normals():
    meshes, idx, mats = instanced_scenes.transformed(count=30)
    it = bsplab.build_instanced(meshes, idx, mats, "bvh")
    flat = it.flatten()
    o, d, _ = ray_families.family("outside_in", flat, 3000, seed=5)
    h = it.intersect(o, d, counters=False)
    ok = h["flat_prim"] >= 0
    n = it.hit_normals(h)[ok]
    ref = geometric_normals(flat, h["flat_prim"].astype(np.int64))[ok]
    assert (np.einsum("ij,ij->i", n, ref) > 0.999).all()


def test_packets_and_culling_flags():
    it = bsplab.build_instanced([instanced_scenes.cube()], [0], np.eye(4)[None, :3])
    o = np.array([[0.5, 0.5, 5.0]], np.float32)
    d = np.array([[0, 0, -1]], np.float32)
    assert it.intersect(o, d, counters=False, packets=True)["t"][0] == 4.0
    with pytest.raises(ValueError, match="culling"):
        it.intersect(o, d, cull=True)
    with pytest.raises(ValueError, match="hits only"):
        it.intersect(o, d, packets=True)


@pytest.mark.parametrize("method", ["kd", "bvh"])
def test_trace_path_replays_intersect_bit_for_bit(method):
    meshes, idx, mats = instanced_scenes.transformed(count=24)
    it = bsplab.build_instanced(meshes, idx, mats, method)
    flat = it.flatten()
    rays = [ray_families.family(f, flat, 60, seed=9) for f in
            ("outside_in", "random_inside", "through_edges", "short_segments")]
    o = np.concatenate([r[0] for r in rays])
    d = np.concatenate([r[1] for r in rays])
    tmax = np.concatenate([r[2] for r in rays])
    h = it.intersect(o, d, tmax=tmax, counters=True)
    for i in range(len(o)):
        p = it.trace_path(o[i], d[i], tmax=float(tmax[i]))
        assert p["instance"] == h["instance"][i] and p["prim"] == h["prim"][i], i
        assert np.float32(p["t"]) == h["t"][i] and np.float32(p["u"]) == h["u"][i], i
        for k in ("top_steps", "instance_visits", "steps", "tests", "box_tests"):
            assert p[k] == h[k][i], (i, k)
        assert len(p["top"]["node"]) == p["top_steps"] and len(p["instances"]) == p["instance_visits"]


def test_trace_path_rows_are_the_top_levels_nodes_in_walk_order():
    meshes, idx, mats = instanced_scenes.transformed(count=24)
    it = bsplab.build_instanced(meshes, idx, mats, "kd")
    boxes = it.top_boxes()
    row_of = {int(n): r for r, n in enumerate(boxes["node"])}
    arrays = it._scene.top_arrays()
    parent = {int(c): n for n in range(len(arrays["leaf"])) if not arrays["leaf"][n]
              for c in (arrays["first"][n], arrays["first"][n] + 1)}
    flat = it.flatten()
    o, d, tmax = ray_families.family("outside_in", flat, 80, seed=4)
    walked = 0
    for i in range(len(o)):
        p = it.trace_path(o[i], d[i], tmax=float(tmax[i]))
        top = p["top"]
        nodes = top["node"].tolist()
        if not nodes:
            continue
        walked += 1
        # The root first; every other node after its parent, each once,
        # with its own box.
        assert nodes[0] == 0 and len(set(nodes)) == len(nodes)
        seen = set()
        for k, n in enumerate(nodes):
            assert n == 0 or parent[n] in seen, (i, nodes)
            seen.add(n)
            r = row_of[n]
            assert np.array_equal(top["box_lo"][k], boxes["lo"][r])
            assert np.array_equal(top["box_hi"][k], boxes["hi"][r])
        t0, t1 = top["t_range"][:, 0], top["t_range"][:, 1]
        assert (t0 <= t1).all()
        # The instances entered are those of the leaves visited, in order.
        leaves = [int(x) for n in nodes if boxes["leaf"][row_of[n]]
                  for x in boxes["instances"][row_of[n]]]
        entered = [v["instance"] for v in p["instances"]]
        assert entered == [x for x in leaves if x in entered]
        if p["instance"] >= 0:
            assert p["instance"] in entered
            assert p["flat_prim"] == it.flat_offsets[p["instance"]] + p["prim"]
    assert walked > 40


def test_top_boxes_hold_their_instances():
    meshes, idx, mats = instanced_scenes.transformed(count=40)
    it = bsplab.build_instanced(meshes, idx, mats, "kd")
    b = it.top_boxes()
    held = np.concatenate([i for i in b["instances"]])
    assert sorted(held) == list(range(40))
    assert all(len(i) == 0 for i, leaf in zip(b["instances"], b["leaf"]) if not leaf)
    flat = it.flatten()
    for inst in range(40):
        tri = flat[it.flat_offsets[inst]:it.flat_offsets[inst] + len(meshes[idx[inst]])]
        row = next(r for r, i in enumerate(b["instances"]) if inst in i)
        assert (tri.reshape(-1, 3) >= b["lo"][row]).all() and (tri.reshape(-1, 3) <= b["hi"][row]).all()
    shallow = it.top_boxes(max_depth=2)
    assert shallow["depth"].max() == 2 and len(shallow["lo"]) <= 7


def test_the_memory_limit_is_sized_from_the_machine_and_its_message_suggests_two_levels():
    import os
    schema = bsplab.option_schema()
    default = schema["memory_limit_mb"]["default"]
    physical = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") / 2**20
    assert default == pytest.approx(0.5 * physical, abs=1.0)
    with pytest.raises(MemoryError, match="two levels"):
        bsplab.build(bsplab.scenes.generate("room"), "kd", memory_limit_mb=0.01)


def test_an_instances_own_tree_is_drawn_in_place():
    meshes, idx, mats = instanced_scenes.transformed(count=10)
    it = bsplab.build_instanced(meshes, idx, mats, "kd")
    boxes = it.top_boxes()
    for i in range(10):
        row = next(r for r, ins in enumerate(boxes["instances"]) if i in ins)
        lo, hi = boxes["lo"][row], boxes["hi"][row]
        cells = it.instance_leaf_cells(i, max_depth=4)
        pad = 1e-4 * np.abs(hi - lo).max()
        assert (cells["vertices"] >= lo - pad).all() and (cells["vertices"] <= hi + pad).all()
        poly = it.instance_split_polygons(i, 3)
        # Each polygon's vertices lie in its plane, carried to the world.
        for p in range(min(20, len(poly["offsets"]) - 1)):
            v = poly["vertices"][poly["offsets"][p]:poly["offsets"][p + 1]].astype(np.float64)
            n, d = poly["plane"][p, :3], poly["plane"][p, 3]
            assert np.abs(v @ n - d).max() <= 1e-4 * (1 + np.abs(v).max())
        # The point at an instance's first triangle's centre is in that instance.
        centre = it.to_world(i, meshes[idx[i]][0].mean(axis=0))
        found = it.instance_at(centre)
        assert found is not None
        assert it.instance_at((1e6, 0, 0)) is None
    bvh = bsplab.build_instanced(meshes, idx, mats, "bvh")
    b = bvh.instance_node_boxes(3, 2)
    assert b["corners"].shape[1:] == (8, 3)
    tri = bvh.flatten()[bvh.flat_offsets[3]:bvh.flat_offsets[3] + len(meshes[idx[3]])]
    root = b["corners"][0].astype(np.float64)
    # The root's corners span the instance's triangles (an oriented box).
    assert (tri.reshape(-1, 3).min(axis=0) >= root.min(axis=0) - 1e-4).all()
    assert (tri.reshape(-1, 3).max(axis=0) <= root.max(axis=0) + 1e-4).all()


def test_a_ray_beyond_float_range_in_object_space_is_no_error():
    tiny = instanced_scenes.affine(np.eye(3) * 1e-30, (0, 0, 0))
    it = bsplab.build_instanced([instanced_scenes.cube()], [0, 0],
                                np.array([tiny, instanced_scenes.affine(np.eye(3), (5, 0, 0))]))
    o = np.array([[3e38, 0.5, 0.5], [5.5, 0.5, 10]], np.float32)
    d = np.array([[-1, 0, 0], [0, 0, -1]], np.float32)
    h = it.intersect(o, d)
    assert h["instance"][1] == 1 and h["t"][1] == 9.0
    p = it.trace_path(o[0], d[0])
    assert p["instance"] == h["instance"][0]


def test_a_matrix_beyond_float_range_is_refused():
    huge = instanced_scenes.affine(np.eye(3) * 1e39, (0, 0, 0))
    with pytest.raises(ValueError, match="instance 0: its matrix carries the mesh beyond float"):
        bsplab.build_instanced([instanced_scenes.cube()], [0], huge[None])


# The oracle's transform-slack rule at a shared edge (oracle.leaks with slack):
# a flat triangle B (Embree's hit) and a steep neighbour A sharing B's edge
# y = 0, A's plane z = 100 y (cos 0.01 to a ray straight down), and a
# triangle C far below. A ray 1e-7 from the edge, displaced by the slack to
# y < 0, meets A 100 times the displacement lower.
_EDGE_TRIS = np.array([
    [[0, 0, 0], [1, 0, 0], [0, 1, 0]],              # B
    [[0, 0, 0], [1, 0, 0], [0.5, -0.01, -1]],       # A
    [[-1, -1, -2], [2, -1, -2], [0.5, 2, -2]],      # C
], np.float32)


@pytest.mark.parametrize("offset, ours, t, slack, leak", [
    (1e-7, 1, 1.0003, 3e-6, False),  # within slack of the edge, within 100 slack on A
    (1e-7, 1, 1.0003, 1e-7, True),   # farther along A than the slack allows
    (1e-3, 1, 1.0003, 3e-6, True),   # the ray passes far from the shared edge
    (1e-7, 2, 3.0, 3e-6, True),      # C shares no edge with B: through the surface
    (1e-7, -1, np.inf, 3e-6, True),  # a miss is always a leak here
])
def test_transform_slack_excuses_only_the_neighbour_across_a_shared_edge(
        offset, ours, t, slack, leak):
    o = np.array([[0.5, offset, 1]], np.float32)
    d = np.array([[0, 0, -1]], np.float32)
    ref = {"t": np.array([1.0], np.float32), "prim": np.array([0], np.int32)}
    got = {"t": np.array([t], np.float32), "prim": np.array([ours], np.int32)}
    bad = oracle.leaks(got, ref, triangles=_EDGE_TRIS, origins=o, directions=d,
                       slack=np.array([slack]))
    assert (bad.size == 1) == leak


# And a neighbour narrower than the slack seen along the ray: B as above and
# A's plane nearly along the ray (cos 3e-4, so not edge-on by PARALLEL_COS):
# seen from above it is a sliver 3e-4 wide, which a ray displaced by more
# may pass beside (a zero-thickness box's rim, fuzzed), missing both.
_SLIVER_TRIS = np.array([
    [[0, 0, 0], [1, 0, 0], [0, 1, 0]],              # B
    [[0, 0, 0], [1, 0, 0], [0.5, -3e-4, -1]],       # A
], np.float32)


@pytest.mark.parametrize("slack, leak", [(1e-3, False), (1e-4, True), (None, True)])
def test_transform_slack_lets_a_ray_pass_beside_a_sliver_neighbour(slack, leak):
    o = np.array([[0.5, 1e-7, 1]], np.float32)
    d = np.array([[0, 0, -1]], np.float32)
    ref = {"t": np.array([1.0], np.float32), "prim": np.array([0], np.int32)}
    miss = {"t": np.array([np.inf], np.float32), "prim": np.array([-1], np.int32)}
    bad = oracle.leaks(miss, ref, triangles=_SLIVER_TRIS, origins=o, directions=d,
                       slack=None if slack is None else np.array([slack]))
    assert (bad.size == 1) == leak


@pytest.mark.parametrize("method", ["kd", "bvh"])
def test_packets_give_the_same_hits_on_ragged_groups_and_ranges(method):
    # Groups of 8 consecutive rays walk the top level together: a count that
    # leaves a short last group in each thread's chunk, per-ray tmin / tmax
    # that cut some rays short inside a group, and camera rays in render's
    # tile order beside shuffled ones (coherent and divergent groups).
    meshes, idx, mats = instanced_scenes.TEST_SCENES["touching"]()
    it = bsplab.build_instanced(meshes, idx, mats, method)
    flat = it.flatten()
    o, d, _ = ray_families.family("inside_camera", flat, 2001, seed=11)
    rng = np.random.default_rng(4)
    n = len(o)
    tmin = np.where(rng.random(n) < 0.2, rng.uniform(0, 0.5, n), 0).astype(np.float32)
    tmax = np.where(rng.random(n) < 0.3, rng.uniform(0.5, 3, n), np.inf).astype(np.float32)
    for order in (np.arange(n), rng.permutation(n)):
        oo, dd = np.ascontiguousarray(o[order]), np.ascontiguousarray(d[order])
        single = it.intersect(oo, dd, tmin[order], tmax[order], counters=False)
        for threads in (1, 2):
            packed = it.intersect(oo, dd, tmin[order], tmax[order], counters=False,
                                  packets=True, threads=threads)
            for k in single:
                np.testing.assert_array_equal(packed[k], single[k], err_msg=k)
        assert (single["instance"] >= 0).mean() > 0.3  # the groups do hit instances


def test_to_object_undoes_to_world_by_the_cores_inverse():
    meshes, idx, mats = instanced_scenes.TEST_SCENES["transformed"]()
    it = bsplab.build_instanced(meshes, idx, mats, "bvh")
    p = np.random.default_rng(2).uniform(-1, 1, (50, 3))
    for i in range(len(idx)):
        back = it.to_object(i, it.to_world(i, p).astype(np.float64))
        np.testing.assert_allclose(back, p, atol=1e-5)
    with pytest.raises(ValueError):
        it.to_object(len(idx), p)

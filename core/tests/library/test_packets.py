"""Ray packets (`intersect(..., packets=True)`, core/src/trace/kernels/packet.hpp)
against the single-ray hits-only path: the same closest hits, bit for bit,
for every method, ray family and order (coherent camera tiles, or shuffled
rays whose packets split at every node), per-ray ranges, scaled trees, ray
counts that do not fill the last packet, and thread counts; and against
Embree on the shared scenes. Also the tile order that makes packets
coherent, and render(), which traces its hits-only modes as packets."""

from __future__ import annotations

import numpy as np
import pytest

import bsplab
from bsplab import scenes, workloads
from bsplab.camera import TILE, Camera, tile_order

from conftest import SCENE_IDS, load_scene
from test_hits_only import HITS, assert_same_hits, family_rays

METHODS = list(bsplab.methods())
WIDTH = bsplab.cpu_features()["packet_width"]


def single_and_packets(tree, o, d, **kw):
    single = tree.intersect(o, d, counters=False, **kw)
    packets = tree.intersect(o, d, counters=False, packets=True, **kw)
    return single, packets


@pytest.mark.parametrize("method", METHODS)
def test_packets_equal_single_rays(method):
    for scene_id in ("gen:room", "gen:tilted", "gen:grids"):
        tris = load_scene(scene_id)
        tree = bsplab.build(tris, method=method)
        o, d, tmin, tmax = family_rays(tris, 400, seed=11)
        # Shuffled: neighbouring lanes of one packet come from different
        # families, so packets split and lanes drop out early.
        shuffle = np.random.default_rng(3).permutation(len(o))
        po, pd = workloads.primary_rays(tris, 40, 28, tiles=True)
        cases = {"families": (o, d, 0.0, np.inf), "families per-ray range": (o, d, tmin, tmax),
                 "shuffled": (o[shuffle], d[shuffle], tmin[shuffle], tmax[shuffle]),
                 "camera tiles": (po, pd, 0.0, np.inf)}
        for name, (ro, rd, lo, hi) in cases.items():
            for threads in (1, 2):
                single, packets = single_and_packets(tree, ro, rd, tmin=lo, tmax=hi,
                                                     threads=threads)
                assert (single["prim"] >= 0).any(), (scene_id, name)
                assert_same_hits(single, packets, f"{scene_id} {method} {name} threads={threads}")


@pytest.mark.parametrize("count", [1, WIDTH - 1, WIDTH + 1, 3 * WIDTH + 5, 1024 + 7])
def test_ray_counts_that_leave_the_last_packet_part_empty(count):
    tris = scenes.generate("room")
    tree = bsplab.build(tris, method="rbsp+kd")
    o, d = workloads.primary_rays(tris, 64, 32, tiles=True)
    o, d = o[:count], d[:count]
    for threads in (1, 2):
        single, packets = single_and_packets(tree, o, d, threads=threads)
        assert_same_hits(single, packets, f"{count} rays threads={threads}")
    assert (single["prim"] >= 0).sum() > count // 2


@pytest.mark.parametrize("method", ["kd", "bsp_cn+kd", "bsp_wn"])
def test_packets_on_a_scaled_tree(method):
    # Rays go into the tree's scaled space and distances come back, as on
    # the single-ray path; a tmax just past a hit checks the rounding back.
    # The fan (9k triangles, general nodes on most walks) rather than the
    # spheres (48k): the same scaled path, builds 8-40 times faster (17 s ->
    # ~2 s a method under ASan + UBSan).
    tris = scenes.generate("fan") * np.float32(3e5)
    tree = bsplab.build(tris, method=method)
    assert tree.stats["scale"] != 1.0
    o, d, tmin, tmax = family_rays(tris, 300, seed=4)
    single, packets = single_and_packets(tree, o, d, tmin=tmin, tmax=tmax)
    assert_same_hits(single, packets, f"scaled {method}")
    assert (single["prim"] >= 0).sum() > len(o) // 10
    hit = single["prim"] >= 0
    near = np.where(hit, single["t"], np.inf).astype(np.float32)
    single, packets = single_and_packets(tree, o, d, tmax=near)
    assert_same_hits(single, packets, f"scaled {method}, tmax at the hits")


def test_packets_of_rays_in_a_plane_and_from_inside():
    # Rays lying in the root's kd split plane (NaN crossings) and along an
    # axis, mixed in packets with ordinary rays starting inside the scene.
    tris = scenes.generate("grids")
    tree = bsplab.build(tris, method="kd")
    root = np.frombuffer(tree.node_bytes()[:8], dtype=np.uint32)
    axis = int(root[1] & 3)
    assert axis < 3, "the root of a kd tree is a kd node"
    split = root[:1].view(np.float32)[0] / np.float32(tree.stats["scale"])
    lo, hi = tree.bounds
    rng = np.random.default_rng(9)
    n = 40 * WIDTH
    o = rng.uniform(lo, hi, (n, 3)).astype(np.float32)
    d = rng.normal(size=(n, 3)).astype(np.float32)
    o[::3, axis] = split
    d[::3, axis] = 0.0
    d[1::3, :] = 0.0
    d[1::3, axis] = np.where(rng.random(len(d[1::3])) < 0.5, -1.0, 1.0)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    single, packets = single_and_packets(tree, o, d)
    assert_same_hits(single, packets, "in-plane rays")
    assert (single["prim"][::3] >= 0).sum() > n // 12


def test_packets_trace_hits_only_and_without_culling():
    tree = bsplab.build(scenes.generate("room"), method="kd")
    o = np.zeros((4, 3), np.float32)
    d = np.ones((4, 3), np.float32)
    with pytest.raises(ValueError, match="counters are per-ray single-ray quantities"):
        tree.intersect(o, d, packets=True)
    with pytest.raises(ValueError, match="without leaf culling"):
        tree.intersect(o, d, counters=False, cull=True, packets=True)
    with pytest.raises(TypeError, match="packets must be True or False"):
        tree.intersect(o, d, counters=False, packets=1)
    assert set(tree.intersect(o, d, counters=False, packets=np.bool_(True))) == set(HITS)


def test_packet_width_is_the_levels_lanes():
    f = bsplab.cpu_features()
    assert f["packet_width"] == {"sse2": 4, "avx2": 8, "avx512": 16}[f["selected"]]


@pytest.mark.parametrize("tile", [TILE, 8])
@pytest.mark.parametrize("width, height", [(16, 16), (13, 9), (1, 20), (20, 1), (8, 8)])
def test_tile_order_visits_each_pixel_once_tile_by_tile(width, height, tile):
    order = tile_order(width, height, tile)
    assert sorted(order.tolist()) == list(range(width * height))
    y, x = np.divmod(order, width)
    tiles = (y // tile) * -(-width // tile) + x // tile
    assert (np.diff(tiles) >= 0).all(), "tiles one after another, row-major"
    # Inside a tile: row-major, so the first row of the first tile leads.
    first = order[: min(tile, width)]
    assert first.tolist() == list(range(min(tile, width)))


def test_tile_order_of_a_16_by_16_image():
    order = tile_order(16, 16, tile=8)
    # The first tile's rows 0 and 1, then on to row 7; then the tile to its right.
    assert order[:16].tolist() == list(range(8)) + list(range(16, 24))
    assert order[64:72].tolist() == list(range(8, 16))
    # The default tiles: a 16-ray packet is one 4 x 4 tile.
    assert TILE == 4
    assert tile_order(16, 16)[:16].tolist() == [0, 1, 2, 3, 16, 17, 18, 19, 32, 33, 34, 35,
                                                48, 49, 50, 51]
    with pytest.raises(ValueError, match="tile must be a positive integer"):
        tile_order(16, 16, tile=0)
    with pytest.raises(ValueError, match="width must be a positive integer"):
        tile_order(0, 16)


def test_camera_rays_in_tile_order():
    cam = Camera.look_at((0, -5, 1), (0, 0, 0), fov_deg=50)
    o, d = cam.rays(24, 17)
    to, td = cam.rays(24, 17, order="tiles")
    order = tile_order(24, 17)
    assert np.array_equal(to, o[order]) and np.array_equal(td, d[order])
    tris = scenes.generate("room")
    wo, wd = workloads.primary_rays(tris, 24, 17, tiles=True)
    io, id_ = workloads.primary_rays(tris, 24, 17)
    assert np.array_equal(wd, id_[order]) and np.array_equal(wo, io[order])
    with pytest.raises(ValueError, match="order must be one of"):
        cam.rays(8, 8, order="columns")


@pytest.mark.parametrize("mode", ["shaded", "normal", "depth"])
@pytest.mark.parametrize("method", ["kd", "bsp_wn+kd", "rbsp"])
def test_render_with_and_without_packets_gives_the_same_image(mode, method):
    tree = bsplab.build(scenes.generate("room"), method=method)
    cam = scenes.default_camera("room")
    image, stats = bsplab.render(tree, cam, 61, 37, mode, threads=2)
    single, single_stats = bsplab.render(tree, cam, 61, 37, mode, packets=False)
    assert stats["packets"] is True and single_stats["packets"] is False
    assert np.array_equal(image.view(np.uint32), single.view(np.uint32))
    assert stats["hits"] == single_stats["hits"] > 0


def test_render_packets_only_where_they_may():
    tree = bsplab.build(scenes.generate("room"), method="kd")
    cam = scenes.default_camera("room")
    assert bsplab.render(tree, cam, 8, 8, "heat_steps")[1]["packets"] is False
    assert bsplab.render(tree, cam, 8, 8, "shaded", cull=True)[1]["packets"] is False
    assert bsplab.render(tree, cam, 8, 8, "shaded", counters=True)[1]["packets"] is False
    with pytest.raises(ValueError, match="counters"):
        bsplab.render(tree, cam, 8, 8, "heat_steps", packets=True)
    with pytest.raises(TypeError, match="packets must be True, False or None"):
        bsplab.render(tree, cam, 8, 8, "shaded", packets="yes")


SHARED_IDS = [s for s in SCENE_IDS if s.startswith("shared:")]


@pytest.mark.skipif(not SHARED_IDS, reason="the shared scenes (/work/shared/scenes) are absent")
@pytest.mark.parametrize("scene_id", SHARED_IDS)
@pytest.mark.parametrize("method", ["kd", "bsp_wn+kd"])
def test_packets_agree_with_embree_on_shared_scenes(scene_id, method):
    pytest.importorskip("embreex", reason="embreex is the oracle")
    from bsplab import oracle
    from test_agreement import check_agreement
    tris = load_scene(scene_id)
    tree = bsplab.build(tris, method=method)
    emb = oracle.EmbreeTracer(tris)
    o, d = workloads.primary_rays(tris, 256, 256, tiles=True)
    hits = tree.intersect(o, d, counters=False, packets=True)
    c = check_agreement(tris, o, d, hits, emb.intersect(o, d))
    assert c["same_prim"] > 0.2 * len(o)
    assert_same_hits(tree.intersect(o, d, counters=False), hits, f"{scene_id} {method}")

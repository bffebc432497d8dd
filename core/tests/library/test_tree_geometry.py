"""The tree as geometry (split_polygons, leaf_cells, node_at) checked against
brute force on the node array, and the ray inspector's trace_path checked
against intersect(): the same hit bit for bit and the same counts."""

from __future__ import annotations

import functools

import numpy as np
import pytest

import bsplab
from bsplab import io, scenes, workloads
from bsplab.tree import KINDS, TEST_RESULTS

# kd, general-only and mixed (^Kd) trees, with fixed, per-node and
# triangle-plane directions.
GEOMETRY_METHODS = ("kd", "rbsp", "rbsp+kd", "bsp_cn+kd", "bsp_random", "bsp_ize")
GEOMETRY_SCENES = ("room", "fan")
LEAF, GENERAL = KINDS.index("leaf"), KINDS.index("general")


def small_k(method: str) -> dict:
    return {"k": 4} if "k" in bsplab.methods()[method]["params"] else {}


@functools.lru_cache(maxsize=None)
def tree_of(scene: str, method: str) -> bsplab.Tree:
    return bsplab.build(scenes.generate(scene), method=method, **small_k(method))


# --- brute force on the raw node array -------------------------------------

def decoded_nodes(tree):
    """Per node: kind code, the child above (interior) and the plane (n, d)
    in world units, decoded from the raw arrays as tree.hpp lays them out."""
    raw = tree._tree.arrays()
    bits = np.frombuffer(raw["nodes"], np.uint32).reshape(-1, 2)
    split = bits[:, 0].view(np.float32)
    planes = np.frombuffer(raw["planes"], np.float32).reshape(-1, 4)
    scale = tree.stats["scale"]
    kinds, above, plane = [], [], []
    for first, b in zip(bits[:, 0], bits[:, 1]):
        if b & 3 != 3:
            kinds.append(int(b & 3))
            above.append(int(b >> 2))
            n = np.zeros(3)
            n[b & 3] = 1.0
            plane.append((*n, float(split[len(kinds) - 1]) / scale))
        elif b & 7 == 3:
            kinds.append(LEAF)
            above.append(-1)
            plane.append((np.nan,) * 4)
        else:
            kinds.append(GENERAL)
            above.append(int(b >> 3))
            p = planes[first].astype(np.float64)
            plane.append((*p[:3], p[3] / scale))
    return np.array(kinds), np.array(above), np.array(plane)


def depths_from(kinds, above, root=0):
    """{node: depth below root} for every node of root's subtree."""
    out, todo = {}, [(root, 0)]
    while todo:
        i, d = todo.pop()
        out[i] = d
        if kinds[i] != LEAF:
            todo += [(i + 1, d + 1), (int(above[i]), d + 1)]
    return out


def walk_to(point, kinds, above, plane, max_depth=None):
    i, d = 0, 0
    while kinds[i] != LEAF and d != max_depth:
        n = plane[i]
        i = i + 1 if float(np.dot(n[:3], point)) < n[3] else int(above[i])
        d += 1
    return i, d


class CellGeometry:
    """The faces' planes and the cells' volumes of a leaf_cells() result,
    computed for every face at once: numpy over the flat arrays (cell by
    cell in Python, a whole tree's ~9000 cells took most of this file's
    time). Per face: its outward unit normal n and offset d (Newell's
    normal, turned away from its cell's centre, the mean of the cell's face
    vertices); `valid` is False for a sliver face collapsed in float32 (no
    plane, no area). Per cell: its volume as pyramids from that centre over
    its faces, the sum of height * area / 3 (0 for a flat cell, whose centre
    lies in its faces, and for a cell cut down to nothing, which has no
    faces)."""

    def __init__(self, cells):
        v = cells["vertices"].astype(np.float64)
        off = np.asarray(cells["offsets"], np.int64)
        coff = np.asarray(cells["cell_offsets"], np.int64)
        self.node, self.coff = np.asarray(cells["node"]), coff
        self.index = {int(node): c for c, node in enumerate(self.node)}
        n_faces, n_cells = len(off) - 1, len(coff) - 1
        counts = np.diff(off)
        face_of = np.repeat(np.arange(n_faces), counts)  # per vertex
        cell_of = np.repeat(np.arange(n_cells), np.diff(coff))  # per face
        nxt = np.arange(len(v)) + 1  # the next vertex around its face
        nxt[off[1:][counts > 0] - 1] = off[:-1][counts > 0]

        def per_face(x):
            return np.stack([np.bincount(face_of, x[:, k], n_faces) for k in range(3)], 1)

        def per_cell(x):
            return np.stack([np.bincount(cell_of, x[:, k], n_cells) for k in range(3)], 1)

        normal = per_face(np.cross(v, v[nxt]))
        length = np.linalg.norm(normal, axis=1)
        self.valid = length != 0.0
        n = normal / np.where(self.valid, length, 1.0)[:, None]
        vertex_sum = per_face(v)
        d = (n * vertex_sum).sum(1) / np.maximum(counts, 1)
        in_cell = np.maximum(np.bincount(cell_of, counts, n_cells), 1)
        centre = per_cell(vertex_sum) / in_cell[:, None]
        flip = (n * centre[cell_of]).sum(1) > d
        n[flip], d[flip] = -n[flip], -d[flip]
        self.n, self.d = n, d
        first = v[off[:-1][face_of]]
        area = 0.5 * np.abs((per_face(np.cross(v - first, v[nxt] - first)) * n).sum(1))
        height = np.abs(d - (n * centre[cell_of]).sum(1))
        self.volume = np.bincount(cell_of, np.where(self.valid, height * area / 3.0, 0.0),
                                  n_cells)

    def volume_of(self, node) -> float:
        return float(self.volume[self.index[int(node)]])

    def outside(self, points, cells=None):
        """(cells, points): how far each point lies outside each cell (<= 0:
        inside), for `cells` (indices; each with a face), else every cell."""
        cells = np.arange(len(self.node)) if cells is None else np.asarray(cells)
        sizes = self.coff[cells + 1] - self.coff[cells]
        faces = np.concatenate([np.arange(self.coff[c], self.coff[c + 1]) for c in cells])
        far = np.asarray(points, np.float64) @ self.n[faces].T - self.d[faces]
        far[:, ~self.valid[faces]] = -np.inf
        return np.maximum.reduceat(far, np.cumsum(sizes) - sizes, axis=1).T

    def outside_of(self, points, node):
        """How far each point lies outside the node's cell."""
        return self.outside(points, [self.index[int(node)]])[0]


def box_of(tree):
    lo, hi = (np.array(c, np.float64) for c in tree.bounds)
    return lo, hi


def tolerance(tree) -> float:
    lo, hi = box_of(tree)
    return 1e-5 * float(np.abs(np.concatenate([lo, hi])).max())


# --- split_polygons ---------------------------------------------------------

@pytest.mark.parametrize("scene", GEOMETRY_SCENES)
@pytest.mark.parametrize("method", GEOMETRY_METHODS)
def test_split_polygons_lie_in_their_plane_inside_their_cell(scene, method):
    tree = tree_of(scene, method)
    kinds, above, plane = decoded_nodes(tree)
    depth_of = depths_from(kinds, above)
    max_depth = 6
    out = tree.split_polygons(max_depth)
    assert not out["cut"]
    v, off = out["vertices"].astype(np.float64), out["offsets"]
    tol = tolerance(tree)
    levels = {d: CellGeometry(tree.leaf_cells(max_depth=d)) for d in range(max_depth + 1)}
    # Every interior node at depth <= 6 has its polygon, and nothing else
    # does - except the nodes that split a flat cell (a wall's own slab of
    # zero thickness), whose plane meets it in a segment, not a polygon.
    interior = {i for i, d in depth_of.items() if d <= max_depth and kinds[i] != LEAF}
    volume = float(np.prod(np.ptp(box_of(tree), axis=0)))
    flat = {i for i in interior if abs(levels[depth_of[i]].volume_of(i)) <= 1e-12 * volume}
    assert sorted(out["node"].tolist()) == sorted(interior - flat)
    for i, node in enumerate(out["node"]):
        node = int(node)
        assert out["depth"][i] == depth_of[node]
        assert out["kind"][i] == kinds[node]
        np.testing.assert_array_equal(out["plane"][i], plane[node])
        poly = v[off[i]:off[i + 1]]
        assert len(poly) >= 3
        n, d = plane[node][:3], plane[node][3]
        assert np.abs(poly @ n - d).max() <= tol * np.linalg.norm(n), (node, poly)
        assert levels[depth_of[node]].outside_of(poly, node).max() <= tol
        # Convex with its vertices in order around it, so its fan is its area.
        turns = np.cross(np.roll(poly, -1, 0) - poly, np.roll(poly, -2, 0) - np.roll(poly, -1, 0)) @ n
        assert (turns >= -tol * tol).all() or (turns <= tol * tol).all(), node
    # The fan triangles index the polygons' own vertices.
    assert out["triangles"].max() < len(v)
    assert len(out["triangles"]) == int((np.diff(off) - 2).sum())


def test_split_polygons_of_a_subtree_are_the_whole_trees_polygons():
    tree = tree_of("room", "bsp_cn+kd")
    whole = tree.split_polygons(8)
    kinds, above, _ = decoded_nodes(tree)
    root = int(whole["node"][5])
    sub = tree.split_polygons(3, root=root)
    below = depths_from(kinds, above, root)
    assert sub["node"][0] == root and sub["depth"][0] == 0
    where = {int(n): i for i, n in enumerate(whole["node"])}
    for i, node in enumerate(sub["node"]):
        assert sub["depth"][i] == below[int(node)] <= 3
        j = where[int(node)]
        np.testing.assert_array_equal(sub["vertices"][sub["offsets"][i]:sub["offsets"][i + 1]],
                                      whole["vertices"][whole["offsets"][j]:whole["offsets"][j + 1]])


def test_split_polygons_are_cut_level_by_level():
    tree = tree_of("room", "kd")
    out = tree.split_polygons(10, max_polygons=20)
    assert out["cut"] and len(out["node"]) == 20
    assert len(out["offsets"]) == 21
    # Level by level: the shallow levels come first and whole.
    assert (np.diff(out["depth"]) >= 0).all()
    full = tree.split_polygons(int(out["depth"][-1]) - 1)
    assert not full["cut"]
    np.testing.assert_array_equal(out["node"][:len(full["node"])], full["node"])
    assert not tree.split_polygons(10, max_polygons=10**7)["cut"]


def test_index_arrays_for_gpu_batches():
    from bsplab.polygons import edge_pairs, fan_triangles
    np.testing.assert_array_equal(fan_triangles([0, 4, 7]), [[0, 1, 2], [0, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(edge_pairs([0, 3, 5]), [[0, 1], [1, 2], [2, 0], [3, 4], [4, 3]])
    assert fan_triangles([0]).shape == (0, 3)
    with pytest.raises(ValueError, match="offsets must be"):
        fan_triangles([3, 1])


# --- leaf_cells and node_at -------------------------------------------------

@pytest.mark.parametrize("scene", GEOMETRY_SCENES)
@pytest.mark.parametrize("method", GEOMETRY_METHODS)
@pytest.mark.parametrize("max_depth", [0, 3, 7, None])
def test_cells_of_a_level_tile_the_root_box(scene, method, max_depth):
    tree = tree_of(scene, method)
    cells = tree.leaf_cells(max_depth=max_depth)
    assert not cells["cut"]
    geometry = CellGeometry(cells)
    lo, hi = box_of(tree)
    volume = float(np.prod(hi - lo))
    assert geometry.volume.sum() == pytest.approx(volume, rel=1e-6)
    kinds, above, plane = decoded_nodes(tree)
    depth_of = depths_from(kinds, above)
    for i, node in enumerate(cells["node"]):
        assert cells["depth"][i] == depth_of[int(node)]
        assert kinds[node] == LEAF or cells["depth"][i] == max_depth
        assert cells["kind"][i] == kinds[node]
    rng = np.random.default_rng(7)
    points = rng.uniform(lo, hi, (40, 3))
    # Flat cells (zero thickness) hold no random point: they are left out.
    solid = np.flatnonzero(geometry.volume > 1e-9 * volume)
    outside = geometry.outside(points, solid)
    nodes = list(geometry.node[solid])
    tol = tolerance(tree)
    for k, p in enumerate(points):
        # In exactly one cell: inside one (up to rounding), strictly in no other.
        assert (outside[:, k] <= tol).sum() >= 1
        assert (outside[:, k] < -tol).sum() <= 1
        found = tree.node_at(p, max_depth=max_depth)
        assert found == walk_to(p, kinds, above, plane, max_depth)
        assert outside[nodes.index(found[0]), k] <= tol


def test_leaf_cells_of_a_subtree_tile_its_cell():
    tree = tree_of("fan", "rbsp+kd")
    level = CellGeometry(tree.leaf_cells(max_depth=4))
    interior = set(np.flatnonzero(decoded_nodes(tree)[0] != LEAF))
    root = next(int(n) for n in level.node if n in interior)
    sub = tree.leaf_cells(root=root)
    total = CellGeometry(sub).volume.sum()
    assert total == pytest.approx(level.volume_of(root), rel=1e-6)
    assert (sub["kind"] == LEAF).all() and sub["depth"].min() >= 1


def test_leaf_cells_are_cut_at_max_cells():
    tree = tree_of("room", "kd")
    out = tree.leaf_cells(max_cells=7)
    assert out["cut"] and len(out["node"]) == 7 and len(out["cell_offsets"]) == 8
    # Each edge joins two vertices of one face.
    assert out["edges"].max() < len(out["vertices"])


def test_node_at_outside_the_box_is_none():
    tree = tree_of("room", "kd")
    lo, hi = box_of(tree)
    assert tree.node_at(hi + (hi - lo)) is None
    assert tree.node_at(lo, max_depth=0) == (0, 0)


# --- trace_path ---------------------------------------------------------------

def inspector_rays(tree, count, seed=3):
    """Rays from inside and outside the box at triangles, along the axes
    (parallel to kd planes) and lying in axis planes."""
    rng = np.random.default_rng(seed)
    tris = tree.triangles.astype(np.float64)
    lo, hi = box_of(tree)
    size = hi - lo
    origins = rng.uniform(lo - 0.3 * size, hi + 0.3 * size, (count, 3))
    targets = tris[rng.integers(0, len(tris), count)].mean(axis=1)
    d = targets - origins
    axis = rng.integers(0, 3, count // 4)
    d[: count // 4] = 0.0
    d[np.arange(count // 4), axis] = rng.choice([-1.0, 1.0], count // 4)
    d[count // 4: count // 2, rng.integers(0, 3)] = 0.0
    return origins.astype(np.float32), d.astype(np.float32)


def assert_path_is_intersects(tree, o, d, tmin=0.0, tmax=np.inf, cull=False):
    ref = tree.intersect(o, d, tmin, tmax, cull=cull)
    for i in range(len(o)):
        p = tree.trace_path(o[i], d[i], tmin, tmax, cull=cull)
        for key in ("t", "u", "v"):
            assert np.float32(p[key]).view(np.uint32) == ref[key][i].view(np.uint32), (i, key)
        for key in ("prim", "steps", "general_steps", "tests", "culled", "box_tests"):
            assert p[key] == ref[key][i], (i, key)
        assert len(p["node"]) == p["steps"]
        assert ((p["kind"] == GENERAL).sum()) == p["general_steps"]
        result = p["test_result"]
        assert np.isin(result, [TEST_RESULTS.index("miss"), TEST_RESULTS.index("hit")]).sum() == p["tests"]
        assert (result == TEST_RESULTS.index("culled")).sum() == p["culled"]
        assert (p["kind"][p["test_step"]] == LEAF).all()
        hits = np.flatnonzero(result == TEST_RESULTS.index("hit"))
        if p["prim"] >= 0:
            assert p["test_prim"][hits[-1]] == p["prim"]
            # Each hit closer than the last, or as close and of a smaller
            # triangle (the tie rule; a BVH's leaves may meet both).
            dt, dp = np.diff(p["test_t"][hits]), np.diff(p["test_prim"][hits].astype(np.int64))
            assert ((dt < 0) | ((dt == 0) & (dp < 0))).all()
        assert (p["t_range"][:, 0] <= p["t_range"][:, 1]).all()


@pytest.mark.parametrize("method", list(bsplab.methods()))
def test_trace_path_is_intersect_on_every_method(method):
    tree = bsplab.build(scenes.generate("room"), method=method, **small_k(method))
    o, d = inspector_rays(tree, 160)
    assert_path_is_intersects(tree, o, d)
    assert_path_is_intersects(tree, o[:60], d[:60], cull=True)
    assert_path_is_intersects(tree, o[:60], d[:60], tmin=0.5, tmax=9.0)


@pytest.mark.parametrize("boxes", ["triangle", "clipped"])
def test_trace_path_culls_as_intersect_does(boxes):
    tree = bsplab.build(scenes.generate("fan"), method="bsp_cn+kd", k=4, leaf_boxes=boxes)
    o, d = inspector_rays(tree, 120, seed=5)
    assert_path_is_intersects(tree, o, d, cull=True)


def test_trace_path_of_a_miss():
    tree = tree_of("room", "kd")
    lo, hi = box_of(tree)
    p = tree.trace_path(hi + 1.0, [1.0, 0.0, 0.0])
    assert p["prim"] == -1 and p["t"] == np.inf and p["steps"] == 0 and len(p["node"]) == 0


def test_geometry_on_a_shared_scene():
    d = workloads.shared_scenes_dir()
    if d is None or not (d / "bunny.ply").exists():
        pytest.skip("shared scenes absent")
    tree = bsplab.build(io.load_mesh(d / "bunny.ply"), method="bsp_cn+kd", k=4)
    cells = tree.leaf_cells(max_depth=6)
    lo, hi = box_of(tree)
    total = CellGeometry(cells).volume.sum()
    assert total == pytest.approx(float(np.prod(hi - lo)), rel=1e-6)
    assert len(tree.split_polygons(6)["node"]) > 0
    o, dirs = inspector_rays(tree, 80)
    assert_path_is_intersects(tree, o, dirs)


# --- bad input ----------------------------------------------------------------

@pytest.mark.parametrize("call, message", [
    (lambda t: t.split_polygons(-1), "max_depth must be >= 0"),
    (lambda t: t.split_polygons(2, root=10**9), "root must be <="),
    (lambda t: t.split_polygons(2, root=-1), "root must be >= 0"),
    (lambda t: t.split_polygons(2, max_polygons=-5), "max_polygons must be >= 0"),
    (lambda t: t.leaf_cells(max_depth=-2), "max_depth must be >= 0"),
    (lambda t: t.leaf_cells(root=10**9), "root must be <="),
    (lambda t: t.node_at([np.nan, 0, 0]), "point must be finite"),
    (lambda t: t.node_at([0, 0]), "point must be three numbers"),
    (lambda t: t.trace_path([np.nan, 0, 0], [1, 0, 0]), "origin must be finite"),
    (lambda t: t.trace_path([0, 0, 0], [0, 0, 0]), "direction must not be zero"),
    (lambda t: t.trace_path([0, 0, 0], [1, 0, np.inf]), "direction must be finite"),
    (lambda t: t.trace_path([0, 0, 0], [1, 0, 0], tmin=-1), "tmin must be >= 0"),
])
def test_bad_input_is_refused_clearly(call, message):
    with pytest.raises(ValueError, match=message):
        call(tree_of("room", "kd"))

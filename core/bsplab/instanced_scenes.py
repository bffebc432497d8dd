"""Generated instanced scenes (meshes, mesh_index, matrices) for
`bsplab.build_instanced`: the cases its correctness tests need - rotations,
non-uniform and mirrored scales, shear, instances that touch, overlap and
share faces, nested instancing, tiny and huge scales in one scene - and a
scatter of many instances. Deterministic for a seed."""

from __future__ import annotations

import numpy as np

from . import scenes


def flatten(meshes, mesh_index, matrices) -> np.ndarray:
    """The (T, 3, 3) float32 world triangles of every instance in order (each
    mesh's triangles in input order), transformed in double, rounded once:
    what InstancedTree.flatten gives for the same scene."""
    parts = []
    for mesh, m in zip(mesh_index, np.asarray(matrices, np.float64)):
        tris = np.asarray(meshes[mesh], np.float32).astype(np.float64)
        parts.append((tris @ m[:, :3].T + m[:, 3]).astype(np.float32))
    return np.concatenate(parts) if parts else np.zeros((0, 3, 3), np.float32)


def cube() -> np.ndarray:
    """The closed unit cube [0, 1]^3: 12 triangles, every edge shared."""
    c = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], np.float32)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = []
    for a, b, cc, d in quads:
        tris += [(a, b, cc), (a, cc, d)]
    return c[np.array(tris)]


def rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random rotation matrix (3, 3)."""
    q = rng.normal(size=4)
    a, b, c, d = q / np.linalg.norm(q)
    return np.array([[a*a + b*b - c*c - d*d, 2*(b*c - a*d), 2*(b*d + a*c)],
                     [2*(b*c + a*d), a*a - b*b + c*c - d*d, 2*(c*d - a*b)],
                     [2*(b*d - a*c), 2*(c*d + a*b), a*a - b*b - c*c + d*d]])


def affine(a: np.ndarray, t) -> np.ndarray:
    return np.hstack([np.asarray(a, np.float64), np.asarray(t, np.float64).reshape(3, 1)])


def _compose(outer: np.ndarray, inner: np.ndarray) -> np.ndarray:
    """outer o inner for 3 x 4 affine matrices (nested instancing)."""
    return affine(outer[:, :3] @ inner[:, :3], outer[:, :3] @ inner[:, 3] + outer[:, 3])


def transformed(seed: int = 0, count: int = 60):
    """Two meshes (the fan, the cube) under random rotations, non-uniform
    scales (1:4), mirrors (every third) and shears (every fifth), in a box
    where many overlap."""
    rng = np.random.default_rng(seed)
    meshes = [scenes.generate("fan"), cube()]
    mats, idx = [], []
    for i in range(count):
        a = rotation(rng) @ np.diag(rng.uniform(0.5, 2.0, 3))
        if i % 3 == 0:
            a = a @ np.diag([-1.0, 1.0, 1.0])
        if i % 5 == 0:
            a = a @ np.array([[1.0, rng.uniform(-0.7, 0.7), 0], [0, 1, 0], [0, 0, 1]])
        mats.append(affine(a, rng.uniform(-2, 2, 3)))
        idx.append(i % 2)
    return meshes, np.array(idx), np.array(mats)


def touching(n: int = 4):
    """An n x n x n stack of unit cubes, each its own instance, face to face:
    neighbouring instances share whole faces (rays along and through the
    shared faces, edges and corners), plus a second copy of the middle row
    overlapping it by half a cube."""
    meshes = [cube()]
    mats = [affine(np.eye(3), (x, y, z)) for x in range(n) for y in range(n) for z in range(n)]
    mats += [affine(np.eye(3), (x + 0.5, n // 2, n // 2)) for x in range(n)]
    return meshes, np.zeros(len(mats), np.int64), np.array(mats)


def nested(seed: int = 0):
    """Instances of instances: a group of three cubes, the group placed by
    four rotated and scaled matrices, each placement by two more (24
    instances, each matrix the product of three)."""
    rng = np.random.default_rng(seed)
    inner = [affine(np.eye(3) * 0.5, (i, 0, 0)) for i in range(3)]
    middle = [affine(rotation(rng) * rng.uniform(0.5, 1.5), rng.uniform(-2, 2, 3)) for _ in range(4)]
    outer = [affine(rotation(rng) * np.diag([1.0, 1.0, -1.0]), (0, 0, 0)),
             affine(np.eye(3) * 2.0, (5, 0, 0))]
    mats = [_compose(o, _compose(m, i)) for o in outer for m in middle for i in inner]
    return [cube()], np.zeros(len(mats), np.int64), np.array(mats)


def scales():
    """One mesh (the cube) at 1e-4, at 1 and at 1e4 in the same scene, the
    tiny ones beside the big one's faces and far from the origin."""
    mats = [affine(np.eye(3) * 1e4, (-5e3, -5e3, -5e3))]
    rng = np.random.default_rng(3)
    for _ in range(20):
        mats.append(affine(rotation(rng) * 1e-4, rng.uniform(-1, 1, 3) * 1e-3 + (5e3 + 1e-3, 0, 0)))
        mats.append(affine(rotation(rng), rng.uniform(-3, 3, 3)))
    return [cube()], np.zeros(len(mats), np.int64), np.array(mats)


def scatter(meshes: list, count: int, extent: float, seed: int = 0):
    """`count` instances of `meshes` with random rotations about z, scales
    0.5-1.5 and positions on a square of side `extent` (a forest)."""
    rng = np.random.default_rng(seed)
    mats = []
    for _ in range(count):
        a = rng.uniform(0, 2 * np.pi)
        rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
        p = np.append(rng.uniform(-extent / 2, extent / 2, 2), 0.0)
        mats.append(affine(rz * rng.uniform(0.5, 1.5), p))
    return list(meshes), rng.integers(0, len(meshes), count), np.array(mats)


# The correctness scenes, by name: () -> (meshes, mesh_index, matrices).
TEST_SCENES = {
    "transformed": transformed,
    "touching": touching,
    "nested": nested,
    "scales": scales,
}


def uv_sphere(rings: int = 20, segments: int = 25) -> np.ndarray:
    """A closed unit sphere of 2 x rings x segments triangles (the default
    1,000), every edge shared."""
    th = np.linspace(0, np.pi, rings + 1)
    ph = np.linspace(0, 2 * np.pi, segments + 1)
    p = np.stack([np.sin(th)[:, None] * np.cos(ph), np.sin(th)[:, None] * np.sin(ph),
                  np.repeat(np.cos(th)[:, None], segments + 1, axis=1)], axis=-1)
    p[:, -1] = p[:, 0]  # the seam: the same vertices, bit for bit
    p[0, :] = p[0, 0]
    p[-1, :] = p[-1, 0]
    a, b = p[:-1, :-1], p[:-1, 1:]
    c, d = p[1:, :-1], p[1:, 1:]
    tris = np.concatenate([np.stack([a, c, d], axis=2).reshape(-1, 3, 3),
                           np.stack([a, d, b], axis=2).reshape(-1, 3, 3)])
    return tris.astype(np.float32)


def _size(tris: np.ndarray) -> float:
    pts = tris.reshape(-1, 3)
    return float((pts.max(axis=0) - pts.min(axis=0)).max())


def grid(mesh: np.ndarray, side: int):
    """side x side copies of one mesh on a square grid, a tenth of its size
    apart (the issue's Suzanne grid, with any mesh)."""
    step = 1.1 * _size(mesh)
    lo = mesh.reshape(-1, 3).min(axis=0)
    mats = [affine(np.eye(3), (i * step - lo[0], j * step - lo[1], -lo[2]))
            for i in range(side) for j in range(side)]
    return [mesh], np.zeros(len(mats), np.int64), np.array(mats)


def city(blocks: int = 40, seed: int = 0):
    """A city: a blocks x blocks street grid of cube towers (uneven scales,
    the heights random) and, on every fifth block, an instance of the
    generated room as a building's interior."""
    rng = np.random.default_rng(seed)
    meshes = [cube(), scenes.generate("room")]
    room = meshes[1]
    room_size = _size(room)
    mats, idx = [], []
    for i in range(blocks):
        for j in range(blocks):
            if (i * blocks + j) % 5 == 0:
                a = np.eye(3) * (8.0 / room_size)
                mats.append(affine(a, (10.0 * i + 4, 10.0 * j + 4, 0)))
                idx.append(1)
                continue
            for _ in range(4):
                s = np.diag([rng.uniform(1, 4), rng.uniform(1, 4), rng.uniform(2, 30)])
                mats.append(affine(s, (10.0 * i + rng.uniform(0, 6), 10.0 * j + rng.uniform(0, 6), 0)))
                idx.append(0)
    return meshes, np.array(idx), np.array(mats)


def forest(count: int = 2000, seed: int = 0):
    """A forest: `count` instances of three meshes - the generated fan (a
    fern), a 1,000-triangle sphere (a bush), a tall stretched sphere (a
    tree) - with random rotations about z and scales, on a square sized for
    about one plant per 4 x 4 units."""
    tree = uv_sphere(24, 40) * np.array([1.0, 1.0, 4.0], np.float32)
    fan = scenes.generate("fan")
    fan = fan / np.float32(_size(fan))
    return scatter([fan, uv_sphere(), tree.astype(np.float32)], count,
                   4.0 * np.sqrt(count), seed)


# The benchmark's worlds, by name: () -> (meshes, mesh_index, matrices).
# "suzanne_grid" stands for the 100-Suzanne grid: 100 copies of the
# 69k-triangle bunny (shared scenes) - or, where they are absent, of the
# generated spheres (48k).
def _grid_mesh() -> np.ndarray:
    from . import workloads
    d = workloads.shared_scenes_dir()
    if d is not None and (d / "bunny.ply").exists():
        from . import io
        return io.load_mesh(d / "bunny.ply")
    return scenes.generate("spheres")


WORLDS = {
    "grid25": lambda: grid(_grid_mesh(), 5),
    "suzanne_grid": lambda: grid(_grid_mesh(), 10),
    "forest": forest,
    "city": city,
    "spheres10k": lambda: scatter([uv_sphere()], 10_000, 400.0, 1),
}

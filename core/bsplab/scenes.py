"""Deterministic generated test scenes (Z up, metres).

* `room`: a closed, tessellated box room with furniture and a table. Mostly
  axis-aligned geometry, with a few boxes rotated about Z.
* `spheres`: about 40 spheres (icospheres and UV spheres) resting on a ground plane.
* `fan`: sliver-triangle fans sharing centre vertices plus long needles, a
  stress case for split selection and for rays grazing shared edges.

Triangle counts depend only on the code, never on the random stream; the
random generator only places things, so counts stay fixed across numpy versions.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Callable, Union

import numpy as np

from .camera import Camera
from .io import write_ply

NAMES = ("room", "spheres", "fan")
# What a scene name may also be: a mesh file (read by bsplab.io) or a .blend
# (exported by a Blender process, camera included).
MESH_SUFFIXES = (".ply", ".obj")
FILE_SUFFIXES = MESH_SUFFIXES + (".blend",)

Mesh = tuple[np.ndarray, np.ndarray]  # (vertices (V,3) float64, faces (F,3) int64)


# -- primitive builders ----------------------------------------------------------


def _merge(meshes: list[Mesh]) -> Mesh:
    """Concatenate meshes, offsetting each one's indices past earlier vertices."""
    offsets = np.cumsum([0] + [len(v) for v, _ in meshes[:-1]])
    vertices = np.concatenate([v for v, _ in meshes])
    faces = np.concatenate([f + o for (_, f), o in zip(meshes, offsets)])
    return vertices, faces


def _grid(origin, du, dv, nu: int, nv: int) -> Mesh:
    """A parallelogram origin + [0,1]*du + [0,1]*dv split into nu x nv quads.

    Winding is counter-clockwise seen from the side du x dv points to.
    """
    s, t = np.meshgrid(np.linspace(0, 1, nu + 1), np.linspace(0, 1, nv + 1), indexing="ij")
    verts = (np.asarray(origin, float) + s[..., None] * np.asarray(du, float)
             + t[..., None] * np.asarray(dv, float)).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = (i * (nv + 1) + j).ravel()
    b, c, d = a + (nv + 1), a + (nv + 2), a + 1
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return verts, faces


def _box(center, size, n: int = 1, yaw_deg: float = 0.0) -> Mesh:
    """A box (rotated by yaw about Z), each side split n x n, normals outward."""
    h = np.asarray(size, float) / 2
    sides = []
    for axis in range(3):
        u, v = (axis + 1) % 3, (axis + 2) % 3
        for sign in (-1.0, 1.0):
            origin = np.zeros(3)
            origin[axis] = sign * h[axis]
            origin[u], origin[v] = -h[u], -h[v]
            du, dv = np.zeros(3), np.zeros(3)
            du[u], dv[v] = 2 * h[u], 2 * h[v]
            # du x dv points along +axis; swap them on the negative side to face outward.
            if sign < 0:
                du, dv = dv, du
            sides.append(_grid(origin, du, dv, n, n))
    verts, faces = _merge(sides)
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    return verts @ rot.T + np.asarray(center, float), faces


def _icosphere(center, radius: float, subdivisions: int) -> Mesh:
    """Icosahedron split `subdivisions` times (20 * 4^k triangles)."""
    p = (1 + math.sqrt(5)) / 2
    verts = [(-1, p, 0), (1, p, 0), (-1, -p, 0), (1, -p, 0), (0, -1, p), (0, 1, p),
             (0, -1, -p), (0, 1, -p), (p, 0, -1), (p, 0, 1), (-p, 0, -1), (-p, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
             (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
             (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    v = [np.array(x, float) / np.linalg.norm(x) for x in verts]
    for _ in range(subdivisions):
        midpoint: dict[tuple[int, int], int] = {}  # shared edges get one new vertex

        def mid(a: int, b: int) -> int:
            key = (min(a, b), max(a, b))
            if key not in midpoint:
                m = v[a] + v[b]
                v.append(m / np.linalg.norm(m))
                midpoint[key] = len(v) - 1
            return midpoint[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return np.array(v) * radius + np.asarray(center, float), np.array(faces)


def _uv_sphere(center, radius: float, segments: int, rings: int) -> Mesh:
    """Latitude/longitude sphere with triangle fans at the poles."""
    theta = np.linspace(0, math.pi, rings + 1)[1:-1]  # interior rings only
    phi = np.linspace(0, 2 * math.pi, segments, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring_verts = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    verts = np.concatenate([[[0, 0, 1]], ring_verts.reshape(-1, 3), [[0, 0, -1]]])
    south = len(verts) - 1
    k = np.arange(segments)
    k1 = (k + 1) % segments
    faces = [np.stack([np.zeros_like(k), 1 + k, 1 + k1], 1)]
    for r in range(rings - 2):
        a, b = 1 + r * segments, 1 + (r + 1) * segments
        faces += [np.stack([a + k, b + k, b + k1], 1), np.stack([a + k, b + k1, a + k1], 1)]
    last = 1 + (rings - 2) * segments
    faces.append(np.stack([last + k, np.full_like(k, south), last + k1], 1))
    return verts * radius + np.asarray(center, float), np.concatenate(faces)


def _fan(center, radius, axis_u, axis_v, count: int, start_deg: float = 0.0,
         span_deg: float = 360.0, jagged: float = 0.0) -> Mesh:
    """`count` sliver triangles sharing `center`, with rim points on an arc.

    `jagged` alternates the rim radius by that fraction, making the slivers
    uneven without changing their count.
    """
    closed = abs(span_deg - 360.0) < 1e-9
    n_rim = count if closed else count + 1
    ang = np.radians(start_deg + span_deg * np.arange(n_rim) / count)
    r = radius * (1 + jagged * (np.arange(n_rim) % 2))
    u, v = np.asarray(axis_u, float), np.asarray(axis_v, float)
    rim = np.asarray(center, float) + (r * np.cos(ang))[:, None] * u + (r * np.sin(ang))[:, None] * v
    verts = np.concatenate([[center], rim])
    k = np.arange(count)
    nxt = (k + 1) % n_rim
    return verts, np.stack([np.zeros_like(k), 1 + k, 1 + nxt], 1)


# -- scenes ----------------------------------------------------------------------


def _room() -> Mesh:
    """8 x 6 x 3 m room, ~0.5 m tessellation, furniture against the walls."""
    L, W, H = 8.0, 6.0, 3.0
    # Each side gets its own tessellation so cells are ~0.5 m squares (floor and
    # ceiling 16x12, walls 16x6 and 12x6); normals face into the room.
    shell = _merge([
        _grid((-L / 2, -W / 2, 0), (L, 0, 0), (0, W, 0), 16, 12),      # floor
        _grid((-L / 2, -W / 2, H), (0, W, 0), (L, 0, 0), 12, 16),      # ceiling
        _grid((-L / 2, -W / 2, 0), (0, 0, H), (L, 0, 0), 6, 16),       # wall y = -W/2
        _grid((-L / 2, W / 2, 0), (L, 0, 0), (0, 0, H), 16, 6),        # wall y = +W/2
        _grid((-L / 2, -W / 2, 0), (0, W, 0), (0, 0, H), 12, 6),       # wall x = -L/2
        _grid((L / 2, -W / 2, 0), (0, 0, H), (0, W, 0), 6, 12),        # wall x = +L/2
    ])
    # (centre xy, size, yaw): wardrobe, bookshelves, sofa parts, bed, desk, cabinets, crates.
    furniture = [
        ((-3.3, 2.6), (1.2, 0.6, 2.2), 0), ((-1.6, 2.75), (1.6, 0.35, 1.9), 0),
        ((3.55, 0.0), (0.7, 2.2, 0.45), 0), ((3.75, 0.0), (0.3, 2.2, 0.9), 0),
        ((2.6, -2.0), (2.0, 1.5, 0.5), 0), ((-3.6, -1.0), (0.5, 1.4, 0.8), 0),
        ((-2.2, -2.6), (0.9, 0.5, 1.1), 0), ((1.6, 2.3), (0.8, 0.8, 0.6), 25),
        ((0.5, -2.3), (0.6, 0.6, 0.6), -35), ((1.2, 1.2), (0.5, 0.5, 0.45), 15),
    ]
    parts = [shell] + [_box((x, y, s[2] / 2), s, n=2, yaw_deg=yaw) for (x, y), s, yaw in furniture]
    # Table: a top on four legs, turned a little to break axis alignment.
    tx, ty, yaw = -0.6, 0.2, 10.0
    c, s = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    parts.append(_box((tx, ty, 0.74), (1.6, 0.9, 0.04), n=3, yaw_deg=yaw))
    for lx, ly in ((-0.72, -0.38), (0.72, -0.38), (-0.72, 0.38), (0.72, 0.38)):
        parts.append(_box((tx + c * lx - s * ly, ty + s * lx + c * ly, 0.36), (0.06, 0.06, 0.72),
                          yaw_deg=yaw))
    return _merge(parts)


def _spheres() -> Mesh:
    """40 non-overlapping spheres on a 24 x 24 m ground; sizes and kinds cycle."""
    rng = np.random.default_rng(20240611)
    kinds: list[Callable[[np.ndarray, float], Mesh]] = [
        lambda c, r: _icosphere(c, r, 3),
        lambda c, r: _uv_sphere(c, r, 32, 16),
        lambda c, r: _icosphere(c, r, 2),
        lambda c, r: _uv_sphere(c, r, 48, 24),
    ]
    parts = [_grid((-12, -12, 0), (24, 0, 0), (0, 24, 0), 20, 20)]
    placed: list[tuple[np.ndarray, float]] = []
    while len(placed) < 40:
        r = 0.3 + 1.2 * rng.random() ** 2  # mostly small, a few large
        xy = (rng.random(2) - 0.5) * 2 * (11.5 - r)
        if all(np.linalg.norm(xy - q) > r + rq + 0.05 for q, rq in placed):
            placed.append((xy, r))
    for i, (xy, r) in enumerate(placed):
        parts.append(kinds[i % 4](np.array([xy[0], xy[1], r]), r))
    return _merge(parts)


def _fan_scene() -> Mesh:
    """Fans in axis planes and tilted planes, a cone fan, and long needles."""
    rng = np.random.default_rng(7)
    x, y, z = np.eye(3)
    d = np.array([1.0, 1.0, 1.0]) / math.sqrt(3)        # tilted plane normal
    tu = np.cross(d, z); tu /= np.linalg.norm(tu)
    tv = np.cross(d, tu)
    parts = [
        _fan((0, 0, 0), 4.0, x, y, 4096),                          # floor fan, axis plane z = 0
        _fan((0, 2.6, 2.2), 2.0, x, z, 1024),                      # upright fan, plane y = 2.6
        _fan((1.5, -1.5, 1.2), 3.0, tu, tv, 2048, 150.0, 90.0),    # ultra-thin wedge, tilted
        _fan((-2.6, -0.5, 1.8), 1.6, y, z, 1024, jagged=0.5),      # star, plane x = -2.6
    ]
    # Cone: apex above the floor fan's centre vertex, rim on a circle just above the floor.
    cone_v, cone_f = _fan((0, 0, 0), 1.5, x, y, 1024)
    cone_v[0] = (0, 0, 3.0)
    cone_v[1:, 2] = 0.3
    parts.append((cone_v, cone_f))
    # Needles: 10 m long, ~1 mm wide, random directions through the scene.
    for _ in range(48):
        a = rng.normal(size=3); a /= np.linalg.norm(a)
        side = np.cross(a, rng.normal(size=3)); side /= np.linalg.norm(side)
        mid = (rng.random(3) - 0.5) * np.array([6.0, 6.0, 3.0]) + np.array([0, 0, 1.5])
        parts.append((np.array([mid - 5 * a, mid + 5 * a - 5e-4 * side, mid + 5 * a + 5e-4 * side]),
                      np.array([[0, 1, 2]])))
    return _merge(parts)


def _rotation(axis, deg: float) -> np.ndarray:
    """Rodrigues' rotation matrix about `axis`."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    t = math.radians(deg)
    return np.eye(3) + math.sin(t) * k + (1 - math.cos(t)) * (k @ k)


def _cube() -> Mesh:
    """The unit cube [0, 1]^3, two triangles a face: every face lies in a face
    of the scene box (issue 10's first repro)."""
    return _box((0.5, 0.5, 0.5), (1.0, 1.0, 1.0), n=1)


def _grids() -> Mesh:
    """Stacked coplanar grids: three overlapping grids in the plane z = 0 with
    different tessellations and offsets, a grid 1e-4 above them, a vertical
    pair sharing the plane x = 0.25, and a closing box around it all."""
    parts = [
        _grid((-1, -1, 0), (2, 0, 0), (0, 2, 0), 8, 8),
        _grid((-0.7, -0.9, 0), (1.5, 0, 0), (0, 1.3, 0), 5, 7),
        _grid((-1, -1, 0), (0, 2, 0), (2, 0, 0), 3, 3),          # same plane, facing down
        _grid((-0.5, -0.5, 1e-4), (1, 0, 0), (0, 1, 0), 4, 4),
        _grid((0.25, -1, 0), (0, 2, 0), (0, 0, 1), 6, 3),
        _grid((0.25, -0.5, 0.2), (0, 0, 0.5), (0, 1, 0), 2, 2),
        _box((0, 0, 0.25), (2.0, 2.0, 1.5), n=2),
    ]
    return _merge(parts)


def _tilted() -> Mesh:
    """Boxes rotated about oblique axes, two of them sharing a tilted face,
    a box nested in another, and a tilted plane through the lot."""
    parts = []
    for i, (axis, deg, centre, size) in enumerate([
            ((1, 1, 0), 30, (0, 0, 0), (1, 1, 1)),
            ((1, 2, 3), 47, (2, 0.3, 0.2), (1.5, 0.5, 0.8)),
            ((0, 1, 1), 61, (-1.8, 0.5, -0.2), (0.6, 1.4, 0.6)),
            ((1, 1, 0), 30, (0, 0, 0), (0.5, 0.5, 0.5)),          # nested in the first
    ]):
        v, f = _box((0, 0, 0), size, n=1 + i % 2)
        parts.append((v @ _rotation(axis, deg).T + np.asarray(centre, float), f))
    # A second box glued to the first one's +x face (the two faces coincide).
    r = _rotation((1, 1, 0), 30)
    v, f = _box((1.0, 0, 0), (1, 1, 1), n=2)
    parts.append((v @ r.T, f))
    # A tilted plane cutting through the boxes.
    pv, pf = _grid((-3, -3, 0), (6, 0, 0), (0, 6, 0), 6, 6)
    parts.append((pv @ _rotation((1, -1, 0.5), 20).T, pf))
    return _merge(parts)


_BUILDERS: dict[str, Callable[[], Mesh]] = {"room": _room, "spheres": _spheres, "fan": _fan_scene,
                                            "cube": _cube, "grids": _grids, "tilted": _tilted}
# Small scenes made to break trees (faces in the scene box's planes, coplanar
# stacks, tilted and shared faces): traced by the ray-family agreement tests.
PROBE_NAMES = ("cube", "grids", "tilted")


# -- public API ------------------------------------------------------------------


def generate_mesh(name: str) -> tuple[np.ndarray, np.ndarray]:
    """`(vertices float32 (V,3), faces int32 (F,3))` of a generated scene."""
    if name not in _BUILDERS:
        raise ValueError(f"unknown scene {name!r}; expected one of {NAMES + PROBE_NAMES}")
    vertices, faces = _BUILDERS[name]()
    return vertices.astype(np.float32), faces.astype(np.int32)


def generate(name: str) -> np.ndarray:
    """Triangles `(N,3,3)` float32 of a generated scene."""
    vertices, faces = generate_mesh(name)
    return vertices[faces]


def default_camera(name: str) -> Camera:
    """A camera that frames the scene well for the demo (landscape images)."""
    views = {
        "room": ((3.6, -2.6, 1.7), (-1.0, 0.8, 0.8), 75.0),   # inside, from a corner
        "spheres": ((0.0, -25.0, 11.0), (0.0, -1.5, 0.0), 60.0),
        "fan": ((7.0, -7.5, 5.5), (0.0, 0.0, 1.2), 55.0),
    }
    if name not in views:
        raise ValueError(f"unknown scene {name!r}; expected one of {NAMES}")
    eye, target, fov = views[name]
    return Camera.look_at(eye, target, fov_deg=fov)


def main_write(out_dir: Union[str, Path]) -> list[Path]:
    """Write `<name>.ply` for every scene into `out_dir`; returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name in NAMES:
        path = out / f"{name}.ply"
        write_ply(path, *generate_mesh(name))
        paths.append(path)
    return paths


# -- loading any scene by name ---------------------------------------------------


def looks_like_file(name: str) -> bool:
    """A scene name that names a file rather than a generated or shared scene."""
    return Path(name).suffix.lower() in FILE_SUFFIXES or "/" in name


def shared_path(name: str) -> Path:
    """`<name>.ply` in the shared scenes folder; FileNotFoundError naming what
    else `name` could have been."""
    from . import workloads
    shared = workloads.shared_scenes_dir()
    if shared is None or not (shared / f"{name}.ply").is_file():
        here = sorted(p.stem for p in shared.glob("*.ply")) if shared is not None else []
        raise FileNotFoundError(
            f"no scene {name!r}: not a generated scene ({', '.join(NAMES + PROBE_NAMES)}), a "
            f"file, or a mesh in the shared scenes folder ({shared or 'not found'}"
            f"{': ' + ', '.join(here) if here else ''})")
    return shared / f"{name}.ply"


def load(name: str) -> np.ndarray:
    """Triangles `(N,3,3)` float32 of any scene name (see `load_with_camera`)."""
    return load_with_camera(name)[0]


def load_with_camera(name: str) -> tuple[np.ndarray, Camera | None]:
    """Triangles and the scene's own camera (None when it has none) of a
    generated scene, an existing .ply/.obj/.blend file (bsplab.io says what
    is wrong with a file it cannot read), or a shared mesh's name."""
    from . import io
    if name == "":  # Path("") is the current directory: let the reader say what "" is
        return io.load_mesh(name), None
    if name in NAMES + PROBE_NAMES:
        return generate(name), default_camera(name) if name in NAMES else None
    path = Path(name)
    if not path.exists():
        path = shared_path(name)
    if path.suffix.lower() == ".blend":
        return io.load_blend(path)
    return io.load_mesh(path), None

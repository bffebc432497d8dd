"""Ray workloads shared by the tests, the benchmark and the experiments:
primary rays from a camera that frames the scene, and incoherent rays."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .camera import Camera


def shared_scenes_dir() -> Path | None:
    """The team's benchmark meshes (../shared/scenes beside the checkout), or
    $BSPLAB_SHARED_SCENES; None when absent, so callers can skip cleanly."""
    env = os.environ.get("BSPLAB_SHARED_SCENES")
    candidates = [Path(env)] if env else []
    here = Path(__file__).resolve()
    candidates += [p / "shared" / "scenes" for p in here.parents]
    candidates += [Path.cwd().resolve().parent / "shared" / "scenes"]
    for c in candidates:
        if c.is_dir() and any(c.glob("*.ply")):
            return c
    return None


def shared_scene_paths() -> list[Path]:
    d = shared_scenes_dir()
    return sorted(d.glob("*.ply")) if d else []


def bounds(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    pts = triangles.reshape(-1, 3)
    return pts.min(axis=0).astype(np.float64), pts.max(axis=0).astype(np.float64)


def framing_camera(triangles: np.ndarray, fov_deg: float = 60.0) -> Camera:
    """A camera inside the upper corner region of the scene box looking at its
    centre: sees both the inside of rooms and the outside of objects. The up
    axis is the box's smallest-looking vertical guess: y when y spans less
    than both x and z (OBJ/PLY convention), else z (Blender's)."""
    lo, hi = bounds(triangles)
    centre, ext = (lo + hi) / 2, hi - lo
    up_axis = 1 if ext[1] <= min(ext[0], ext[2]) else 2
    offset = ext * 0.3
    offset[up_axis] = ext[up_axis] * 0.2
    up = np.zeros(3)
    up[up_axis] = 1.0
    return Camera.look_at(centre + offset, centre, up=tuple(up), fov_deg=fov_deg)


def primary_rays(triangles: np.ndarray, width: int, height: int,
                 camera: Camera | None = None, tiles: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Camera rays through the pixel centres, row by row, or with `tiles`
    tile by tile (camera.tile_order), the order ray packets trace fastest."""
    cam = camera or framing_camera(triangles)
    return cam.rays(width, height, order="tiles" if tiles else "image")


def random_rays(triangles: np.ndarray, count: int, seed: int = 1):
    """Origins uniform in the scene box, directions uniform on the sphere:
    the most incoherent workload there is."""
    lo, hi = bounds(triangles)
    rng = np.random.default_rng(seed)
    origins = rng.uniform(lo, hi, (count, 3)).astype(np.float32)
    d = rng.normal(size=(count, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return origins, d.astype(np.float32)


def ambient_occlusion_rays(triangles: np.ndarray, origins: np.ndarray, directions: np.ndarray,
                           hits: dict, samples: int = 1, seed: int = 2):
    """Incoherent secondary rays, as an ambient-occlusion pass casts them:
    from every primary hit point, `samples` cosine-weighted directions about
    the normal facing the viewer. Origins are lifted off the surface by a
    small fraction of the scene size so they do not re-hit their own
    triangle."""
    hit = hits["prim"] >= 0
    prim = hits["prim"][hit]
    tri = triangles[prim].astype(np.float64)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    d0 = directions[hit].astype(np.float64)
    n *= -np.sign(np.einsum("ij,ij->i", n, d0))[:, None]  # face the viewer
    p = origins[hit] + d0 * hits["t"][hit][:, None].astype(np.float64)
    lo, hi = bounds(triangles)
    p += n * (1e-4 * float(np.linalg.norm(hi - lo)))
    n = np.repeat(n, samples, axis=0)
    p = np.repeat(p, samples, axis=0)
    rng = np.random.default_rng(seed)
    r1, r2 = rng.random(len(n)), rng.random(len(n))
    # Cosine-weighted: uniform on the disc, lifted onto the hemisphere.
    r, phi = np.sqrt(r1), 2 * np.pi * r2
    local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - r1)], axis=1)
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    t1 = np.cross(n, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n, t1)
    d = local[:, :1] * t1 + local[:, 1:2] * t2 + local[:, 2:] * n
    return p.astype(np.float32), d.astype(np.float32)

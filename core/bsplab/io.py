"""Triangle mesh files: the readers' public entry points, and `.blend` scenes.

`read_mesh`/`load_mesh` choose a reader by extension: PLY, OBJ, OFF and STL
by bsplab's own strict readers (formats/ply.py, obj.py, off.py, stl.py),
glTF/GLB through trimesh (formats/via_trimesh.py, a glTF scene flattened to
world space). Every reader returns `(vertices float32 (V,3), faces int32 (F,3))`
checked the same way (formats/checks.py). `write_ply` writes binary PLY;
`load_blend` has Blender export a .blend's evaluated scene.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .formats import via_trimesh
from .formats.checks import MESH_FORMATS, PathLike, fan_triangulate, regular_file, suffixes
from .formats.obj import read_obj
from .formats.off import read_off
from .formats.ply import read_ply, write_ply
from .formats.stl import read_stl

__all__ = ["MESH_FORMATS", "fan_triangulate", "load_blend", "load_mesh", "read_mesh",
           "read_obj", "read_off", "read_ply", "read_stl", "write_ply"]


def read_mesh(path: PathLike) -> tuple[np.ndarray, np.ndarray]:
    """`(vertices, faces)` of a mesh file, its type chosen by extension:
    `.ply`, `.obj`, `.off` and `.stl` by bsplab's own readers (formats/),
    `.glb` and `.gltf` by trimesh (a glTF scene flattened to world space).
    The same checks apply to all: a regular file (not a directory, FIFO or
    device), finite float32 coordinates, indices that name a vertex."""
    regular_file(path)
    suffix = Path(path).suffix.lower()[1:]
    if suffix not in MESH_FORMATS:
        raise ValueError(f"{path}: unsupported mesh format {Path(path).suffix.lower()!r} "
                         f"(expected one of {suffixes()})")
    if suffix in via_trimesh.FORMATS:
        return via_trimesh.read(Path(path), suffix)
    return _READERS[suffix](path)


_READERS = {"ply": read_ply, "obj": read_obj, "off": read_off, "stl": read_stl}


def load_mesh(path: PathLike) -> np.ndarray:
    """Triangles `(N,3,3)` float32 of a mesh file (see read_mesh); a file
    without faces is a ValueError."""
    vertices, faces = read_mesh(path)
    if len(faces) == 0:
        raise ValueError(f"{path}: the mesh has no faces: no triangles")
    return np.ascontiguousarray(vertices[faces], dtype=np.float32).reshape(-1, 3, 3)


def load_blend(path: PathLike, blender: str | None = None, timeout: float = 600.0):
    """Triangles `(N,3,3)` float32 and the scene camera (a `Camera`, or None
    when the scene has none) of a .blend's evaluated scene, exactly as the
    add-on extracts them. Runs Blender: `blender` or $BSPLAB_BLENDER names a
    Blender executable (default `blender` on the PATH) or a Python with the
    `bpy` module. The script Blender runs ships inside this package
    (bsplab/blender/export_scene.py), so a wheel install reads .blend files too."""
    import shutil
    import subprocess
    import tempfile

    from .blender import EXPORT_SCRIPT
    from .camera import Camera

    try:
        regular_file(path, "a .blend file")
    except FileNotFoundError:
        raise FileNotFoundError(f"no .blend file {path}") from None
    path = Path(path)
    exe = blender or os.environ.get("BSPLAB_BLENDER") or "blender"
    if shutil.which(exe) is None:
        raise FileNotFoundError(f"reading {path.name} needs Blender: {exe!r} is not an "
                                "executable (set BSPLAB_BLENDER to a Blender or a Python "
                                "with the bpy module)")
    script = EXPORT_SCRIPT
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "scene.npz"
        if Path(exe).name.startswith("python"):
            cmd = [exe, str(script), "--", str(out), str(path.resolve())]
        else:
            cmd = [exe, "-b", str(path.resolve()), "--factory-startup", "-noaudio",
                   "--python-exit-code", "1", "--python", str(script), "--", str(out)]
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        if r.returncode != 0 or not out.exists():
            tail = "\n".join((r.stdout + r.stderr).strip().splitlines()[-8:])
            raise RuntimeError(f"Blender could not export {path.name} (exit {r.returncode}):\n"
                               f"{tail}")
        data = dict(np.load(out))
    tris = np.ascontiguousarray(data["triangles"], dtype=np.float32).reshape(-1, 3, 3)
    if len(tris) == 0:
        raise ValueError(f"{path.name}: the scene has no visible mesh triangles")
    camera = None
    if "camera_lens" in data:
        kw = {k[len("camera_"):]: data[k] for k in data
              if k.startswith("camera_") and k not in ("camera_size", "camera_error")}
        kw = {k: (v if k == "matrix_world" else v.item()) for k, v in kw.items()}
        try:
            camera = Camera(**kw)
        except (TypeError, ValueError) as e:
            raise ValueError(f"{path.name}: the scene camera cannot be used: {e}") from None
    return tris, camera

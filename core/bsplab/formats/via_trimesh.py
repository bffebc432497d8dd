"""Mesh files that trimesh parses for `bsplab.io`: glTF and GLB.

A glTF/GLB file is a scene: a graph of nodes, each placing a mesh with its
transform (one mesh may be placed many times). The trees want one list of
world-space triangles, so the scene is flattened here. trimesh is imported on
the first read, so `import bsplab` (inside Blender, say) does without it.
The file's structure is checked first (gltf_checks.py), so damage is named
rather than met as trimesh's internal errors. PLY, OBJ, OFF and STL have
bsplab's own stricter readers (ply.py, obj.py, off.py, stl.py say why).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from .checks import checked_vertices, check_indices, read_bytes
from .gltf_checks import GltfError, check_references, glb_parts, parse_json

# File types read here, by extension; trimesh names them the same way.
FORMATS = ("glb", "gltf")


def _trimesh():
    try:
        import trimesh
    except ImportError as exc:
        raise ImportError("reading glTF/GLB files needs trimesh: "
                          "pip install 'bsplab[mesh]' (or trimesh)") from exc
    return trimesh


def _arrays(geometry) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of one trimesh geometry; a point cloud has no faces
    and geometry without vertices (paths, text) contributes nothing."""
    vertices = np.asarray(getattr(geometry, "vertices", np.zeros((0, 3))), dtype=np.float64)
    faces = np.asarray(getattr(geometry, "faces", np.zeros((0, 3))))
    if faces.size == 0:
        faces = np.zeros((0, 3), dtype=np.int64)
    return vertices.reshape(-1, 3), faces.reshape(-1, 3).astype(np.int64)


def flatten(loaded) -> tuple[np.ndarray, np.ndarray]:
    """One (vertices float64, faces int64) pair in world space from what
    trimesh.load returned: a mesh as it is, a scene with every geometry
    placed by each node's transform, in the scene graph's node order."""
    if not hasattr(loaded, "graph"):
        return _arrays(loaded)
    vertices, faces, offset = [], [], 0
    for node in loaded.graph.nodes_geometry:
        transform, geometry_name = loaded.graph[node]
        local, local_faces = _arrays(loaded.geometry[geometry_name])
        # In double precision, so a far-off placement does not round twice.
        vertices.append(local @ transform[:3, :3].T + transform[:3, 3])
        faces.append(local_faces + offset)
        offset += len(local)
    if not vertices:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    return np.concatenate(vertices), np.concatenate(faces)


def read(path: Path, file_type: str) -> tuple[np.ndarray, np.ndarray]:
    """Checked (vertices float32, faces int32) of a file of one of FORMATS;
    a file that cannot be parsed is a ValueError "<path>: not a readable GLB
    file: <what is wrong>"."""
    data = read_bytes(path)
    what = f"{path}: not a readable {file_type.upper()} file"
    try:
        if file_type == "glb":
            doc, binary = glb_parts(data)
        else:
            doc, binary = parse_json(data), None
        check_references(doc, binary)
    except GltfError as e:
        raise ValueError(f"{what}: {e}") from None
    trimesh = _trimesh()
    try:
        # process=False: the file's vertices and faces as written (no merging,
        # no dropping of degenerate faces: the trees deal with those). A GLB
        # is parsed from the bytes checked above; a .gltf from its path, so
        # that its buffer files are found beside it.
        source = io.BytesIO(data) if file_type == "glb" else str(path)
        loaded = trimesh.load(source, file_type=file_type, process=False)
        vertices, faces = flatten(loaded)
    except Exception as exc:  # damage the checks above do not know, in trimesh's words
        detail = str(exc) or type(exc).__name__
        raise ValueError(f"{what}: {detail}") from None
    vertices = checked_vertices(vertices, str(path), lambda i: f"vertex {i}")
    return vertices, check_indices(faces, len(vertices), str(path))

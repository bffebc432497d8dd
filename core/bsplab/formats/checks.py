"""What every mesh reader's result must satisfy, and the pieces the readers share.

Coordinates become float32 for the trees, so a NaN, an infinity or a value
beyond float32's range is refused here rather than turning into a wrong tree;
an index must name a vertex. Messages start with the file's name.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Union

import numpy as np

PathLike = Union[str, Path]

# Every extension bsplab.io.read_mesh reads: PLY and OBJ by bsplab's own
# readers (ply.py, obj.py), the rest through trimesh (via_trimesh.py).
MESH_FORMATS = ("ply", "obj", "glb", "gltf", "stl", "off")


def suffixes(formats=MESH_FORMATS) -> str:
    """'.ply, .obj, ...' for messages."""
    return ", ".join("." + f for f in formats)


def fan_triangulate(counts: np.ndarray, flat: np.ndarray, name: str = "mesh") -> np.ndarray:
    """(F,3) triangles from polygons given as per-face sizes and concatenated indices.

    Polygon (v0, v1, ..., vk) becomes (v0, v1, v2), (v0, v2, v3), ...: vectorized
    with np.repeat so mixed polygon sizes cost no Python loop.
    """
    counts = np.asarray(counts, dtype=np.int64)
    if counts.size and counts.min() < 3:
        bad = int(np.argmax(counts < 3))
        raise ValueError(f"{name}: face {bad} has {counts[bad]} vertices (need at least 3)")
    starts = np.concatenate(([0], np.cumsum(counts)[:-1])) if counts.size else counts
    per_face = counts - 2
    first = np.repeat(starts, per_face)
    # j-th triangle of a face uses corners j+1 and j+2.
    j = np.arange(per_face.sum()) - np.repeat(np.cumsum(per_face) - per_face, per_face)
    flat = np.asarray(flat)
    return np.stack([flat[first], flat[first + j + 1], flat[first + j + 2]], axis=1)


def check_indices(faces: np.ndarray, n_vertices: int, name: str) -> np.ndarray:
    """Faces as int32 after checking every index is a valid vertex number."""
    if faces.size:
        lo, hi = faces.min(), faces.max()
        if lo < 0 or hi >= n_vertices:
            bad = lo if lo < 0 else hi
            raise ValueError(f"{name}: vertex index {int(bad)} out of range "
                             f"(file has {n_vertices} vertices)")
    return faces.astype(np.int32).reshape(-1, 3)


def face_of(counts: np.ndarray, corner: int) -> int:
    """The face holding the corner-th entry of the concatenated face lists."""
    return int(np.searchsorted(np.cumsum(counts), corner, side="right"))


FLOAT32_MAX = float(np.finfo(np.float32).max)


def checked_vertices(v: np.ndarray, name: str, where) -> np.ndarray:
    """float32 vertices after refusing NaN, infinite and beyond-float32
    coordinates; `where(i)` names vertex i (0-based) in the message."""
    v = np.asarray(v, dtype=np.float64)
    bad = ~np.isfinite(v).all(axis=1)
    why = "a NaN or infinite coordinate"
    if not bad.any():
        bad = (np.abs(v) > FLOAT32_MAX).any(axis=1)
        why = "a coordinate beyond the float32 range of +-3.4e38"
    if bad.any():
        i = int(np.argmax(bad))
        xyz = ", ".join(f"{x:g}" for x in v[i])
        raise ValueError(f"{name}: {where(i)} has {why} ({xyz})")
    return v.astype(np.float32)


def _kind_of(mode: int) -> str:
    """What a file that is not a regular file is, for messages."""
    for test, kind in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a named pipe"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return kind
    return "not a plain file"


def regular_file(path: PathLike, what: str = "") -> os.stat_result:
    """The stat of `path` (symbolic links followed) after refusing anything
    but a regular file: an empty path (which would mean the current
    directory), a directory, a FIFO or a device (reading one would block
    forever or never end, like /dev/zero), a missing file. The messages say
    which, and what was expected (`what`; default: a mesh file of MESH_FORMATS)."""
    what = what or f"a mesh file ({suffixes()})"
    if str(path) == "":
        raise ValueError(f"an empty path is not {what}")
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such file") from None
    except OSError as e:  # a loop of links, a name too long, no permission
        raise OSError(e.errno, f"{path}: cannot be read: {e.strerror}") from None
    if stat.S_ISDIR(st.st_mode):
        raise ValueError(f"{path}: is a directory, not {what}")
    if not stat.S_ISREG(st.st_mode):
        raise ValueError(f"{path}: not a regular file ({_kind_of(st.st_mode)}); expected "
                         f"{what}")
    return st


def read_bytes(path: PathLike) -> bytes:
    """The whole of a regular file. At most the size stat reported is read
    (plus one byte, to notice a file that grows meanwhile), so no file can be
    read without bound."""
    size = regular_file(path).st_size
    with open(path, "rb") as f:
        data = f.read(size + 1)
    if len(data) > size:
        raise ValueError(f"{path}: the file grew while it was read (it is being written?)")
    return data

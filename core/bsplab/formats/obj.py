"""Wavefront OBJ meshes: bsplab's own reader of `v` and `f` records.

bsplab's rather than trimesh's because it is stricter and exact: trimesh 5.2
takes a face index 0 as the last vertex and a `1e23` index as a number, loses
the first vertex after a byte order mark, and (keeping the file's order)
leaves negative indices unresolved where faces mix `a/b/c` and `a//c` corners.
Errors name the file, the line and the index or coordinate as written.
"""

from __future__ import annotations

import numpy as np

from .checks import PathLike, checked_vertices, face_of, fan_triangulate, read_bytes

_MAX_OBJ_INDEX = (1 << 31) - 1  # vertex numbers become int32


def _obj_line(line: str) -> str:
    line = line.strip()
    return repr(line if len(line) <= 60 else line[:57] + "...")


def _obj_records(text: str, keyword: str):
    """(line number, line) of every `keyword` record, for error messages."""
    for lineno, line in enumerate(text.splitlines(), start=1):
        words = line.split(None, 1)
        if words and words[0] == keyword:
            yield lineno, line


def _obj_face_indices(words: list[str], n: int) -> list[int]:
    """0-based vertex numbers of a face's corners; n vertices are defined so far."""
    idx = []
    for w in words:
        token = w.split("/", 1)[0]
        try:
            idx.append(int(token))
        except ValueError:
            raise ValueError(f"vertex index {token!r} is not a whole number") from None
    if len(idx) < 3:
        raise ValueError(f"face has {len(idx)} vertices (need at least 3)")
    if min(idx) > 0 and max(idx) <= _MAX_OBJ_INDEX:
        return [i - 1 for i in idx]
    for i in idx:
        if i == 0:
            raise ValueError("vertex index 0 (OBJ indices start at 1)")
        if i < -n:
            raise ValueError(f"vertex index {i} out of range (only {n} vertices come "
                             "before this line)")
        if i > _MAX_OBJ_INDEX:
            raise ValueError(f"vertex index {i} out of range (a mesh has at most "
                             f"{_MAX_OBJ_INDEX} vertices)")
    return [i - 1 if i > 0 else n + i for i in idx]


def read_obj(path: PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Read `v` and `f` records of a Wavefront OBJ; everything else is ignored.

    Face corners may be `a`, `a/b`, `a//c` or `a/b/c`; negative indices count
    back from the latest vertex, as the format specifies. A file without
    faces is refused. Errors name the file, the line and the index or
    coordinate as written.
    """
    name = str(path)
    text = read_bytes(path).decode("utf-8-sig", errors="replace")
    coords: list[list[str]] = []
    counts: list[int] = []
    corners: list[int] = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        words = line.split()
        if not words:
            continue
        try:
            if words[0] == "v":
                if len(words) < 4:
                    raise ValueError("vertex needs 3 coordinates")
                coords.append(words[1:4])
            elif words[0] == "f":
                idx = _obj_face_indices(words[1:], len(coords))
                corners.extend(idx)
                counts.append(len(idx))
        except ValueError as exc:
            raise ValueError(f"{name}: line {lineno} {_obj_line(line)}: {exc}") from None
    try:
        vertices = np.array(coords, dtype=np.float64).reshape(-1, 3)
    except ValueError:
        for lineno, line in _obj_records(text, "v"):
            for w in line.split()[1:4]:
                try:
                    float(w)
                except ValueError:
                    raise ValueError(f"{name}: line {lineno} {_obj_line(line)}: non-numeric "
                                     f"vertex coordinate {w!r}") from None
        raise

    def vertex_line(i: int) -> str:
        lineno, _ = next(r for k, r in enumerate(_obj_records(text, "v")) if k == i)
        return f"line {lineno}: vertex {i + 1}"

    vertices = checked_vertices(vertices, name, vertex_line)
    if not counts:
        if not text.strip():
            raise ValueError(f"{name}: the file is empty: no triangles")
        if not coords:
            raise ValueError(f"{name}: no faces found: not an OBJ file (no 'v' or 'f' lines)")
        raise ValueError(f"{name}: no faces found (no 'f' lines): {len(coords)} vertices "
                         "but no triangles")
    counts_a = np.array(counts, dtype=np.int64)
    flat = np.array(corners, dtype=np.int64)
    beyond = flat >= len(vertices)  # negative indices were checked line by line
    if beyond.any():
        j = int(np.argmax(beyond))
        lineno, line = next(r for k, r in enumerate(_obj_records(text, "f"))
                            if k == face_of(counts_a, j))
        raise ValueError(f"{name}: line {lineno} {_obj_line(line)}: vertex index {flat[j] + 1} "
                         f"out of range (file has {len(vertices)} vertices)")
    return vertices, fan_triangulate(counts_a, flat, name).astype(np.int32).reshape(-1, 3)

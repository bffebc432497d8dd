"""OFF (Object File Format) meshes: bsplab's own strict reader.

bsplab's rather than trimesh's because trimesh 5.2 reads an OFF file cut
short as fewer faces without a word, drops a face of fewer than 3 vertices,
and answers other damage with its internals' errors (a failed reshape, an
index out of range, a missing text-encoding package). Here the header's
counts are checked against the file: a file cut short says how many
vertices and faces the header promised and how many it holds; every error
names the file and the line. Polygons are fan-triangulated in file order,
as the PLY and OBJ readers do.

The format: a keyword line (`OFF`, or with the optional prefixes `ST`, `C`,
`N` of colour, normal and texture columns after x y z, which are ignored),
the counts `vertices faces [edges]` (on the keyword's line or the next),
one `x y z ...` line per vertex, one `n i1 .. in [colour]` line per face
(0-based indices). `#` starts a comment. Binary OFF and the 4D / n-D
variants are refused.
"""

from __future__ import annotations

import re

import numpy as np

from .checks import PathLike, checked_vertices, fan_triangulate, read_bytes

# [ST][C][N]OFF: columns after x y z the reader ignores.
_KEYWORD = re.compile(r"(ST)?C?N?OFF")


class _Incomplete(ValueError):
    """A line with too few numbers: on the last line, a file cut short."""


def _lines(text: str):
    """(line number, words) of every line with content, comments removed."""
    for lineno, line in enumerate(text.splitlines(), start=1):
        words = line.split("#", 1)[0].split()
        if words:
            yield lineno, words


def _whole(word: str, what: str) -> int:
    if not (word.isascii() and word.isdigit()):  # also refuses "3.0", "-1", "1e9", "²"
        raise ValueError(f"{what} must be a whole number >= 0, got {word!r}")
    return int(word)


def _header(lines, name: str) -> tuple[int, int, int]:
    """(vertex count, face count, line number of the counts)."""
    first = next(lines, None)
    if first is None:
        raise ValueError(f"{name}: the file is empty: no triangles")
    lineno, words = first
    keyword = words[0]
    if not _KEYWORD.fullmatch(keyword):
        raise ValueError(f"{name}: line {lineno}: not an OFF file (the first line must be "
                         f"'OFF', got {' '.join(words)[:40]!r})")
    counts = words[1:]
    if counts[:1] == ["BINARY"]:
        raise ValueError(f"{name}: line {lineno}: binary OFF is not supported (only text OFF)")
    if not counts:
        nxt = next(lines, None)
        if nxt is None:
            raise ValueError(f"{name}: the file ends after '{keyword}': no 'vertices faces "
                             "edges' counts line")
        lineno, counts = nxt
    if len(counts) not in (2, 3):
        raise ValueError(f"{name}: line {lineno}: the counts line must be 'vertices faces "
                         f"[edges]', got {' '.join(counts)[:40]!r}")
    try:
        nv, nf = (_whole(w, what) for w, what in zip(counts, ("vertex count", "face count")))
        if len(counts) == 3:
            _whole(counts[2], "edge count")
    except ValueError as e:
        raise ValueError(f"{name}: line {lineno}: {e}") from None
    return nv, nf, lineno


def _cut_short(name: str, nv: int, nf: int, vertices: int, faces: int) -> ValueError:
    return ValueError(f"{name}: truncated: the header promises {nv} vertices and {nf} faces, "
                      f"the file holds {vertices} vertices and {faces} faces")


def read_off(path: PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Read a text OFF file's vertices and faces (polygons fan-triangulated)."""
    name = str(path)
    # A byte that is not UTF-8 (a Latin-1 comment, say) does no harm where
    # it is ignored, and is named as written where it is not.
    lines = list(_lines(read_bytes(path).decode("utf-8-sig", errors="replace")))
    rest = iter(lines)
    nv, nf, counts_line = _header(rest, name)
    coords, vertex_lines = [], []
    counts, corners = [], []
    for lineno, words in rest:
        try:
            if len(coords) < nv:
                if len(words) < 3:
                    raise _Incomplete(f"vertex {len(coords)} needs 3 coordinates, got "
                                     f"{' '.join(words)!r}")
                coords.append(words[:3])
                vertex_lines.append(lineno)
            elif len(counts) < nf:
                corners.extend(_face(words, len(counts), nv))
                counts.append(int(words[0]))
            else:
                raise ValueError(f"more data after the {nv} vertices and {nf} faces the "
                                 f"header (line {counts_line}) promises")
        except ValueError as e:
            if isinstance(e, _Incomplete) and lineno == lines[-1][0]:  # the last line cut off
                raise ValueError(f"{_cut_short(name, nv, nf, len(coords), len(counts))}; its "
                                 f"last line {lineno} is incomplete: {e}") from None
            raise ValueError(f"{name}: line {lineno}: {e}") from None
    if len(coords) < nv or len(counts) < nf:
        raise _cut_short(name, nv, nf, len(coords), len(counts))
    try:
        vertices = np.array(coords, dtype=np.float64).reshape(-1, 3)
    except ValueError:
        i, w = next((i, w) for i, c in enumerate(coords) for w in c if not _is_number(w))
        raise ValueError(f"{name}: line {vertex_lines[i]}: vertex {i} has a non-numeric "
                         f"coordinate {w!r}") from None
    vertices = checked_vertices(vertices, name,
                                lambda i: f"line {vertex_lines[i]}: vertex {i}")
    return vertices, fan_triangulate(np.array(counts, dtype=np.int64),
                                     np.array(corners, dtype=np.int64),
                                     name).astype(np.int32).reshape(-1, 3)


def _face(words: list[str], face: int, nv: int) -> list[int]:
    """The vertex indices of face number `face`, a line `n i1 .. in [colour ...]`."""
    n = _whole(words[0], f"face {face}'s vertex count")
    if n < 3:
        raise ValueError(f"face {face} has {n} vertices (need at least 3)")
    if len(words) < n + 1:
        raise _Incomplete(f"face {face} says {n} vertices but lists {len(words) - 1}")
    idx = [_whole(w, f"face {face}'s vertex index") for w in words[1:n + 1]]
    bad = next((i for i in idx if i >= nv), None)
    if bad is not None:
        raise ValueError(f"face {face}: vertex index {bad} out of range (file has {nv} "
                         "vertices)")
    return idx


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True

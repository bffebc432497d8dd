"""STL meshes (ASCII and binary): bsplab's own strict reader.

bsplab's rather than trimesh's because trimesh 5.2 reads an ASCII STL cut
short as a mesh without faces, answers a damaged binary one with its
internals' errors, and needs a text-encoding package the set-up does not
install to look at a file that is not UTF-8. Here a binary STL's facet
count is checked against the file's size and an ASCII STL's structure line
by line, so a file cut short says so. Every facet is its own three vertices,
in file order (STL shares none).

Which kind a file is: a binary STL is an 80-byte header, a facet count and
50 bytes per facet, so its size says it is one (even when the header starts
with `solid`, as many exporters write); anything else must be ASCII,
starting with `solid`.
"""

from __future__ import annotations

import numpy as np

from .checks import PathLike, checked_vertices, read_bytes

_HEADER = 80    # bytes before a binary STL's facet count
_COUNT = 4      # the facet count: uint32, little-endian
_RECORD = np.dtype([("normal", "<f4", (3,)), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])


def read_stl(path: PathLike) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of an ASCII or binary STL: three vertices per facet."""
    name = str(path)
    data = read_bytes(path)
    if not data:
        raise ValueError(f"{name}: the file is empty: no triangles")
    promised = _binary_count(data)
    if promised is not None and len(data) == _HEADER + _COUNT + _RECORD.itemsize * promised:
        records = np.frombuffer(data, _RECORD, promised, _HEADER + _COUNT)
        vertices, lines = records["corners"].reshape(-1, 3), None
    elif data.lstrip()[:5].lower() == b"solid":
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError as e:
            raise ValueError(f"{name}: not a readable STL file: it starts with 'solid' like an "
                             f"ASCII STL, but byte {e.start} is {data[e.start:e.start + 1]!r}"
                             f"{_as_binary(data, promised)}") from None
        try:
            vertices, lines = _ascii(text, name)
        except ValueError as e:
            if b"\0" not in data:
                raise
            # Text that holds NUL bytes: a binary STL whose header says 'solid'.
            raise ValueError(f"{e}{_as_binary(data, promised)}") from None
    else:
        raise ValueError(f"{name}: not a readable STL file: it does not start with 'solid' "
                         f"(ASCII STL){_as_binary(data, promised)}")

    def where(i: int) -> str:
        return (f"line {lines[i]}: " if lines else "") + f"facet {i // 3} vertex {i % 3}"

    vertices = checked_vertices(vertices, name, where)
    return vertices, np.arange(len(vertices), dtype=np.int32).reshape(-1, 3)


def _binary_count(data: bytes) -> int | None:
    """The facet count a binary STL's header gives (None: too short for one)."""
    if len(data) < _HEADER + _COUNT:
        return None
    return int(np.frombuffer(data, "<u4", 1, _HEADER)[0])


def _as_binary(data: bytes, promised: int | None) -> str:
    """Why the file is no binary STL either, for messages."""
    if promised is None:
        return f", and at {len(data)} bytes it is too short for a binary STL (84 bytes at least)"
    size = _HEADER + _COUNT + _RECORD.itemsize * promised
    return (f"; as a binary STL its header promises {promised} facets ({size} bytes), but "
            f"the file has {len(data)} bytes")


# The ASCII grammar: each state's keyword and the state it leads to.
_NEXT = {
    "top": {"solid": "solid"},
    "solid": {"facet": "facet", "endsolid": "top"},
    "facet": {"outer": "loop"},
    "loop": {"vertex": "loop", "endloop": "endloop"},
    "endloop": {"endfacet": "solid"},
}
_EXPECTED = {"top": "'solid'", "solid": "'facet normal' or 'endsolid'", "facet": "'outer loop'",
             "loop": "'vertex x y z' or 'endloop'", "endloop": "'endfacet'"}


def _ascii(text: str, name: str) -> tuple[np.ndarray, list[int]]:
    """Vertices of an ASCII STL and the line each is on; the structure is
    checked keyword by keyword, so a file cut short says where it ends."""
    state, coords, lines = "top", [], []
    facets, facet_line, in_loop = 0, 0, 0
    text_lines = text.splitlines()
    for lineno, line in enumerate(text_lines, start=1):
        words = line.split()
        if not words:
            continue
        keyword = words[0].lower()
        if keyword not in _NEXT[state]:
            # The last line, cut off inside a facet: the file is cut short.
            cut = (lineno == len(text_lines) and state != "solid"
                   and any(k.startswith(keyword) for k in _NEXT[state]))
            raise ValueError(f"{name}: " + (
                f"truncated: the ASCII STL ends inside facet {facets} (line {facet_line}), "
                f"after {facets} whole facets; its last line {lineno} is cut off: "
                f"{line.strip()[:40]!r}" if cut else
                f"line {lineno}: expected {_EXPECTED[state]}, got {line.strip()[:40]!r}"))
        if keyword == "facet":
            facet_line, in_loop = lineno, 0
        elif keyword == "vertex":
            if len(words) != 4:
                raise ValueError(f"{name}: line {lineno}: a vertex needs 3 coordinates, got "
                                 f"{line.strip()[:40]!r}")
            try:
                coords.append([float(w) for w in words[1:]])
            except ValueError:
                raise ValueError(f"{name}: line {lineno}: non-numeric vertex coordinate in "
                                 f"{line.strip()[:40]!r}") from None
            lines.append(lineno)
            in_loop += 1
        elif keyword == "endloop" and in_loop != 3:
            raise ValueError(f"{name}: line {lineno}: facet {facets} (line {facet_line}) has "
                             f"{in_loop} vertices; an STL facet has 3")
        elif keyword == "endfacet":
            facets += 1
        state = _NEXT[state][keyword]
    if state != "top":
        inside = (f"inside facet {facets} (line {facet_line})" if state != "solid"
                  else "without 'endsolid'")
        raise ValueError(f"{name}: truncated: the ASCII STL ends {inside}, after {facets} "
                         "whole facets")
    return np.array(coords, dtype=np.float64).reshape(-1, 3), lines

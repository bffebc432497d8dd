"""PLY meshes (ASCII, binary little- and big-endian): bsplab's own reader,
and the binary writer.

The reader is bsplab's rather than trimesh's because it is stricter: trimesh
5.2 reads a truncated ASCII PLY as fewer faces and a fractional or too large
list count without a word, and refuses valid files whose face element has
properties beside its index list. Polygons are fan-triangulated in file
order, so triangle numbers are reproducible across tools. Binary PLY whose
faces all have the same size (the common case) is read with one
structured-dtype `np.frombuffer` and no per-element Python loop.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .checks import (PathLike, check_indices, checked_vertices, face_of, fan_triangulate,
                     read_bytes)

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
_PLY_FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
_FACE_LIST_NAMES = ("vertex_indices", "vertex_index")
_PLY_VERSION = "1.0"  # the only version of the format there is


# -- PLY header ------------------------------------------------------------------


@dataclass
class _Property:
    name: str
    dtype: str                   # item type code, e.g. "f4"
    count_dtype: str | None = None  # set for list properties


@dataclass
class _Element:
    name: str
    count: int
    props: list[_Property]


def _parse_header(data: bytes, name: str) -> tuple[str | None, list[_Element], int]:
    """Returns (byte order or None for ASCII, elements, offset of the body)."""
    if not data.startswith(b"ply"):
        raise ValueError(f"{name}: not a PLY file (missing 'ply' magic)")
    end = data.find(b"end_header")
    if end < 0:
        raise ValueError(f"{name}: bad PLY header (no 'end_header')")
    newline = data.find(b"\n", end)
    body = newline + 1 if newline >= 0 else len(data)
    lines = data[:end].decode("ascii", errors="replace").splitlines()[1:]
    order, elements = "missing", []
    for lineno, line in enumerate(lines, start=2):
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        try:
            if words[0] == "format":
                if words[1] not in _PLY_FORMATS:
                    raise ValueError(f"unsupported format {words[1]!r} (expected one of "
                                     f"{', '.join(_PLY_FORMATS)})")
                if words[2:] != [_PLY_VERSION]:
                    raise ValueError(f"unsupported PLY version {' '.join(words[2:])!r} "
                                     f"(only {_PLY_VERSION})")
                order = _PLY_FORMATS[words[1]]
            elif words[0] == "element":
                elements.append(_Element(words[1], _element_count(words[2]), []))
            elif words[0] == "property":
                if not elements:
                    raise ValueError("property before any element")
                if words[1] == "list":
                    prop = _Property(words[4], _PLY_TYPES[words[3]], _PLY_TYPES[words[2]])
                    if prop.count_dtype[0] == "f":
                        raise ValueError(f"a list count must have an integer type, "
                                         f"not {words[2]!r}")
                else:
                    prop = _Property(words[2], _PLY_TYPES[words[1]])
                elements[-1].props.append(prop)
            else:
                raise ValueError(f"unknown keyword {words[0]!r}")
        except (IndexError, KeyError, ValueError) as exc:
            detail = f"unknown type {exc}" if isinstance(exc, KeyError) else str(exc) or "too few words"
            raise ValueError(f"{name}: bad PLY header line {lineno} {line.strip()!r}: {detail}") from None
    if order == "missing":
        raise ValueError(f"{name}: bad PLY header (no 'format' line)")
    return order, elements, body


def _element_count(word: str) -> int:
    if not (word.isascii() and word.isdigit()):  # also refuses '3.7', '-1', 'nan', '²'
        raise ValueError(f"element count must be a whole number >= 0, got {word!r}")
    return int(word)


def _check_list_count(n, available: int, item_size: int, total: int, elem: _Element,
                      record: int, prop: _Property, name: str) -> int:
    """A list's item count as an int, or a ValueError naming the element, the
    record and the count. `available` is how many bytes (binary) or tokens
    (ASCII, item_size 1) are left after the count; `total` is the whole body's."""
    where = f"{elem.name} {record}, list {prop.name!r}"
    if not (np.isfinite(n) and float(n).is_integer() and n >= 0):
        shown = f"{n:g}" if isinstance(n, (float, np.floating)) else str(n)
        raise ValueError(f"{name}: {where}: bad list count {shown} (must be a whole number "
                         ">= 0)")
    n = int(n)
    if n * item_size > total:
        raise ValueError(f"{name}: {where}: list count {n} is larger than the whole file")
    if n * item_size > available:
        raise ValueError(f"{name}: truncated data in element {elem.name!r} "
                         f"({elem.name} {record} of {elem.count} is cut off)")
    return n


# -- PLY body: binary ------------------------------------------------------------

# A parsed element: scalar name -> (n,) array; list name -> (counts (n,), flat items).
_Columns = dict


def _fixed_dtype(elem: _Element, order: str, sizes: list[int]) -> np.dtype:
    """Record dtype assuming list property i always has sizes[i] items."""
    parts, k = [], 0
    for i, p in enumerate(elem.props):
        if p.count_dtype is None:
            parts.append((f"s{i}", order + p.dtype))
        else:
            parts.append((f"c{i}", order + p.count_dtype))
            parts.append((f"l{i}", order + p.dtype, (sizes[k],)))
            k += 1
    return np.dtype(parts)


def _first_list_sizes(buf: bytes, pos: int, elem: _Element, order: str, name: str) -> list[int]:
    """List lengths in the first record, used to guess a fixed record layout."""
    sizes = []
    for p in elem.props:
        if p.count_dtype is None:
            pos += np.dtype(p.dtype).itemsize
            continue
        count_t = np.dtype(order + p.count_dtype)
        if pos + count_t.itemsize > len(buf):
            raise ValueError(f"{name}: truncated data in element {elem.name!r}")
        item = np.dtype(p.dtype).itemsize
        pos += count_t.itemsize
        n = _check_list_count(np.frombuffer(buf, count_t, 1, pos - count_t.itemsize)[0],
                              len(buf) - pos, item, len(buf), elem, 0, p, name)
        sizes.append(n)
        pos += n * item
    return sizes


def _read_binary_element(buf: bytes, pos: int, elem: _Element, order: str,
                         name: str) -> tuple[_Columns, int]:
    lists = [i for i, p in enumerate(elem.props) if p.count_dtype is not None]
    sizes = _first_list_sizes(buf, pos, elem, order, name) if lists and elem.count else [0] * len(lists)
    dtype = _fixed_dtype(elem, order, sizes)
    if pos + dtype.itemsize * elem.count <= len(buf):
        rec = np.frombuffer(buf, dtype, elem.count, pos)
        if all(np.all(rec[f"c{i}"] == n) for i, n in zip(lists, sizes)):
            cols: _Columns = {}
            for i, p in enumerate(elem.props):
                if p.count_dtype is None:
                    cols[p.name] = rec[f"s{i}"]
                else:
                    cols[p.name] = (rec[f"c{i}"].astype(np.int64), rec[f"l{i}"].reshape(-1))
            return cols, pos + dtype.itemsize * elem.count
    if not lists:
        raise ValueError(f"{name}: truncated data in element {elem.name!r} "
                         f"(expected {elem.count} records)")
    return _read_binary_variable(buf, pos, elem, order, name)


def _read_binary_variable(buf: bytes, pos: int, elem: _Element, order: str,
                          name: str) -> tuple[_Columns, int]:
    """Fallback for lists of varying length: walk the records one by one."""
    values: list[list] = [[] for _ in elem.props]
    counts: list[list[int]] = [[] for _ in elem.props]
    types = [(np.dtype(order + p.dtype), np.dtype(order + (p.count_dtype or p.dtype)))
             for p in elem.props]

    def scalar(dtype: np.dtype, at: int):
        if at + dtype.itemsize > len(buf):
            raise ValueError(f"{name}: truncated data in element {elem.name!r} "
                             f"({elem.name} {record} of {elem.count} is cut off)")
        return np.frombuffer(buf, dtype, 1, at)[0]

    for record in range(elem.count):
        for i, p in enumerate(elem.props):
            item_t, count_t = types[i]
            if p.count_dtype is None:
                values[i].append(scalar(item_t, pos))
                pos += item_t.itemsize
                continue
            count = scalar(count_t, pos)
            pos += count_t.itemsize
            n = _check_list_count(count, len(buf) - pos, item_t.itemsize, len(buf), elem,
                                  record, p, name)
            values[i].append(np.frombuffer(buf, item_t, n, pos) if n else
                             np.zeros(0, item_t))
            counts[i].append(n)
            pos += n * item_t.itemsize
    cols: _Columns = {}
    for i, p in enumerate(elem.props):
        if p.count_dtype is None:
            cols[p.name] = np.array(values[i], dtype=types[i][0])
        else:
            flat = np.concatenate(values[i]) if values[i] else np.zeros(0, types[i][0])
            cols[p.name] = (np.array(counts[i], dtype=np.int64), flat)
    return cols, pos


# -- PLY body: ASCII -------------------------------------------------------------


def _read_ascii_element(tokens: np.ndarray, pos: int, elem: _Element,
                        name: str) -> tuple[_Columns, int]:
    """Same result as the binary reader, from a flat array of numeric tokens."""
    lists = [i for i, p in enumerate(elem.props) if p.count_dtype is not None]
    if not lists:  # fixed-width records: one reshape
        width = len(elem.props)
        end = pos + width * elem.count
        if end > tokens.size:
            raise ValueError(f"{name}: truncated data in element {elem.name!r}")
        table = tokens[pos:end].reshape(elem.count, width)
        return {p.name: table[:, i] for i, p in enumerate(elem.props)}, end
    values: list[list] = [[] for _ in elem.props]
    counts: list[list[int]] = [[] for _ in elem.props]
    try:
        for record in range(elem.count):
            for i, p in enumerate(elem.props):
                if p.count_dtype is None:
                    values[i].append(tokens[pos])
                    pos += 1
                    continue
                n = _check_list_count(tokens[pos], tokens.size - pos - 1, 1, tokens.size, elem,
                                      record, p, name)
                values[i].append(tokens[pos + 1:pos + 1 + n])
                counts[i].append(n)
                pos += 1 + n
    except IndexError:
        raise ValueError(f"{name}: truncated data in element {elem.name!r}") from None
    cols: _Columns = {}
    for i, p in enumerate(elem.props):
        if p.count_dtype is None:
            cols[p.name] = np.array(values[i])
        else:
            flat = np.concatenate(values[i]) if values[i] else np.zeros(0)
            cols[p.name] = (np.array(counts[i], dtype=np.int64), flat)
    return cols, pos


def _ascii_tokens(body: bytes, name: str) -> np.ndarray:
    try:
        return np.array(body.split(), dtype=np.float64)
    except ValueError:
        raise ValueError(f"{name}: non-numeric token in ASCII PLY data") from None


def _check_face_indices(counts: np.ndarray, flat: np.ndarray, n_vertices: int,
                        name: str) -> np.ndarray:
    """PLY face lists as int64 after checking every index is a whole number
    naming a vertex; a message names the face (numbered from 0, like the
    file's own indices) and the index as written."""
    flat = np.asarray(flat)
    if np.issubdtype(flat.dtype, np.floating):
        bad = ~np.isfinite(flat) | (flat != np.floor(flat))
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(f"{name}: face {face_of(counts, i)} has a non-integer vertex "
                             f"index {flat[i]:g}")
    bad = (flat < 0) | (flat >= n_vertices)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"{name}: face {face_of(counts, i)}: vertex index {int(flat[i])} "
                         f"out of range (file has {n_vertices} vertices)")
    return flat.astype(np.int64)


def read_ply(path: PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Read a PLY mesh: `(vertices float32 (V,3), faces int32 (F,3))`."""
    name = str(path)
    data = read_bytes(path)
    order, elements, pos = _parse_header(data, name)
    tokens = _ascii_tokens(data[pos:], name) if order is None else None
    if order is None:
        pos = 0
    parsed: dict[str, _Columns] = {}
    for elem in elements:
        if order is None:
            parsed[elem.name], pos = _read_ascii_element(tokens, pos, elem, name)
        else:
            parsed[elem.name], pos = _read_binary_element(data, pos, elem, order, name)
    return _vertices_from(parsed, name), _faces_from(parsed, elements, name)


def _vertices_from(parsed: dict[str, _Columns], name: str) -> np.ndarray:
    vertex = parsed.get("vertex")
    if vertex is None:
        raise ValueError(f"{name}: PLY has no 'vertex' element")
    missing = [c for c in "xyz" if c not in vertex or isinstance(vertex[c], tuple)]
    if missing:
        raise ValueError(f"{name}: vertex element lacks scalar properties {missing}")
    return checked_vertices(np.stack([vertex[c] for c in "xyz"], axis=1), name,
                             lambda i: f"vertex {i}")


def _faces_from(parsed: dict[str, _Columns], elements: list[_Element], name: str) -> np.ndarray:
    n_vertices = len(parsed["vertex"]["x"])
    face = parsed.get("face")
    if face is None:
        return np.zeros((0, 3), dtype=np.int32)
    lists = [k for k, v in face.items() if isinstance(v, tuple)]
    key = next((k for k in _FACE_LIST_NAMES if k in lists), lists[0] if len(lists) == 1 else None)
    if key is None:
        raise ValueError(f"{name}: face element has no 'vertex_indices' list")
    counts, flat = face[key]
    flat = _check_face_indices(counts, flat, n_vertices, name)
    if counts.size and np.all(counts == 3):  # all triangles: no index shuffling needed
        return flat.astype(np.int32).reshape(-1, 3)
    return fan_triangulate(counts, flat, name).astype(np.int32).reshape(-1, 3)


def write_ply(path: PathLike, vertices: np.ndarray, faces: np.ndarray) -> None:
    """Binary little-endian PLY: float x,y,z and `property list uchar int vertex_indices`."""
    v = np.asarray(vertices)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"write_ply: vertices must have shape (V, 3), got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"write_ply: faces must have shape (F, 3), got {f.shape}")
    if not np.issubdtype(f.dtype, np.integer) and f.size:
        raise TypeError(f"write_ply: faces must be integers, got {f.dtype}")
    if not np.issubdtype(v.dtype, np.number):
        raise TypeError(f"write_ply: vertices must be numbers, got {v.dtype}")
    checked_vertices(v, "write_ply", lambda i: f"vertex {i}")  # what read_ply would refuse
    check_indices(f, len(v), "write_ply")
    header = ("ply\nformat binary_little_endian 1.0\n"
              f"element vertex {len(v)}\n"
              "property float x\nproperty float y\nproperty float z\n"
              f"element face {len(f)}\n"
              "property list uchar int vertex_indices\nend_header\n")
    records = np.empty(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    records["n"] = 3
    records["i"] = f
    with open(path, "wb") as out:
        out.write(header.encode("ascii"))
        out.write(np.ascontiguousarray(v, dtype="<f4").tobytes())
        out.write(records.tobytes())

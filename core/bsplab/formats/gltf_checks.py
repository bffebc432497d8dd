"""The structure of a glTF 2.0 file, checked before trimesh reads it.

trimesh answers a damaged GLB with its internals' errors ("chunk was not
expected length!", an AssertionError, a failed reshape, an index out of
range). These checks find the same damage first and say what it is: the
GLB container (header, total length, chunk lengths and types) and, in the
JSON, every reference a mesh's triangles depend on (scene -> node -> mesh ->
accessor -> bufferView -> buffer), each index in range and each byte range
inside what it points into. Messages are the `<what is wrong>` of
"<file>: not a readable GLB file: <what is wrong>".
"""

from __future__ import annotations

import json
import struct

_MAGIC = b"glTF"
_JSON_CHUNK, _BIN_CHUNK = 0x4E4F534A, 0x004E4942
_HEADER = struct.Struct("<4sII")  # magic, version, total length
_CHUNK = struct.Struct("<II")     # length, type
_COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_TYPE_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9,
                    "MAT4": 16}


class GltfError(ValueError):
    """What is wrong with a glTF file's structure."""


def glb_parts(data: bytes) -> tuple[dict, int | None]:
    """(the JSON document, the BIN chunk's length or None) of a GLB file."""
    if len(data) < _HEADER.size:
        raise GltfError(f"{len(data)} bytes is shorter than the 12-byte GLB header")
    magic, version, length = _HEADER.unpack_from(data)
    if magic != _MAGIC:
        raise GltfError(f"no 'glTF' magic at the start (got {magic!r})")
    if version != 2:
        raise GltfError(f"GLB version {version} (only version 2 is read)")
    if length != len(data):
        raise GltfError(f"the header gives a total length of {length} bytes, the file has "
                        f"{len(data)}")
    chunks, pos = [], _HEADER.size
    while pos < len(data):
        if pos + _CHUNK.size > len(data):
            raise GltfError(f"chunk {len(chunks)} at byte {pos}: cut off inside its 8-byte "
                            "header")
        size, kind = _CHUNK.unpack_from(data, pos)
        start = pos + _CHUNK.size
        if start + size > len(data):
            raise GltfError(f"chunk {len(chunks)} at byte {pos} says {size} bytes, only "
                            f"{len(data) - start} follow")
        chunks.append((kind, data[start:start + size]))
        pos = start + size
    if not chunks or chunks[0][0] != _JSON_CHUNK:
        raise GltfError("the first chunk is not the JSON chunk")
    binary = next((len(body) for kind, body in chunks[1:] if kind == _BIN_CHUNK), None)
    return parse_json(chunks[0][1]), binary


def parse_json(text: bytes) -> dict:
    """The glTF JSON document; UTF-8 only, as the format says (and as
    trimesh decodes it: another encoding would send it looking for a
    package the set-up does not install)."""
    try:
        doc = json.loads(text.decode("utf-8"))
    except UnicodeDecodeError as e:
        raise GltfError(f"the JSON is not UTF-8 text (byte {e.start})") from None
    except json.JSONDecodeError as e:
        raise GltfError(f"the JSON is not valid: {e}") from None
    if not isinstance(doc, dict):
        raise GltfError("the JSON is not an object")
    return doc


def check_references(doc: dict, binary: int | None) -> None:
    """Every reference from the scenes down to the buffers in range.
    `binary`: the GLB's BIN chunk length (a buffer without a uri is it)."""
    table = {key: _objects(doc, key) for key in
             ("scenes", "nodes", "meshes", "accessors", "bufferViews", "buffers")}

    def index(owner: str, key: str, value, target: str) -> dict:
        if not _is_int(value) or not 0 <= value < len(table[target]):
            raise GltfError(f"{owner}: {key} {value!r} does not name one of the "
                            f"{len(table[target])} {target}")
        return table[target][value]

    if "scene" in doc:
        index("the document", "scene", doc["scene"], "scenes")
    for i, scene in enumerate(table["scenes"]):
        for n in _list(scene, "nodes", f"scene {i}"):
            index(f"scene {i}", "node", n, "nodes")
    for i, node in enumerate(table["nodes"]):
        for c in _list(node, "children", f"node {i}"):
            index(f"node {i}", "child", c, "nodes")
        if "mesh" in node:
            index(f"node {i}", "mesh", node["mesh"], "meshes")
    for i, mesh in enumerate(table["meshes"]):
        for j, prim in enumerate(_list(mesh, "primitives", f"mesh {i}")):
            where = f"mesh {i} primitive {j}"
            if not isinstance(prim, dict) or not isinstance(prim.get("attributes"), dict):
                raise GltfError(f"{where}: no 'attributes' object")
            if "POSITION" in prim["attributes"]:
                index(where, "POSITION accessor", prim["attributes"]["POSITION"], "accessors")
            if "indices" in prim:
                index(where, "indices accessor", prim["indices"], "accessors")
    for i, buffer in enumerate(table["buffers"]):
        length = buffer.get("byteLength")
        if not _is_int(length) or length < 0:
            raise GltfError(f"buffer {i}: byteLength {length!r} is not a whole number >= 0")
        if "uri" not in buffer and i == 0 and (binary or 0) < length:
            raise GltfError(f"buffer 0 needs {length} bytes of the BIN chunk, which has "
                            f"{binary or 0}")
    for i, view in enumerate(table["bufferViews"]):
        buffer = index(f"bufferView {i}", "buffer", view.get("buffer"), "buffers")
        _fits(f"bufferView {i}", view.get("byteOffset", 0), view.get("byteLength"),
              f"buffer {view['buffer']}", buffer["byteLength"])
    for i, acc in enumerate(table["accessors"]):
        _check_accessor(i, acc, table, index)


def _check_accessor(i: int, acc: dict, table: dict, index) -> None:
    where = f"accessor {i}"
    size = _COMPONENT_BYTES.get(acc.get("componentType"))
    parts = _TYPE_COMPONENTS.get(acc.get("type"))
    if size is None or parts is None:
        raise GltfError(f"{where}: componentType {acc.get('componentType')!r} / type "
                        f"{acc.get('type')!r} is not a glTF accessor type")
    count = acc.get("count")
    if not _is_int(count) or count < 1:
        raise GltfError(f"{where}: count {count!r} is not a whole number >= 1")
    if "bufferView" not in acc:
        return  # all zeros, by the format
    view = index(where, "bufferView", acc["bufferView"], "bufferViews")
    stride = view.get("byteStride", size * parts)
    _fits(where, acc.get("byteOffset", 0), stride * (count - 1) + size * parts,
          f"bufferView {acc['bufferView']}", view["byteLength"])


def _fits(where: str, offset, length, target: str, available: int) -> None:
    if not (_is_int(offset) and _is_int(length)) or offset < 0 or length < 0:
        raise GltfError(f"{where}: byteOffset {offset!r} / byteLength {length!r} are not "
                        "whole numbers >= 0")
    if offset + length > available:
        raise GltfError(f"{where} needs bytes {offset}..{offset + length} of {target}, which "
                        f"has {available}")


def _objects(doc: dict, key: str) -> list[dict]:
    items = _list(doc, key, "the document")
    bad = next((i for i, v in enumerate(items) if not isinstance(v, dict)), None)
    if bad is not None:
        raise GltfError(f"{key}[{bad}] is not an object")
    return items


def _list(owner: dict, key: str, where: str) -> list:
    value = owner.get(key, [])
    if not isinstance(value, list):
        raise GltfError(f"{where}: '{key}' is not a list")
    return value


def _is_int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)

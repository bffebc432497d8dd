"""Bad inputs a new user meets, each with the one clear message it gets
(issue 27): mesh files, API calls, the command line, experiment specs.

Every case is a row of CASES: what is tried, and the exception type (or the
command's exit code) and the exact message it must give, `{d}` standing for
the case's folder. `core/tools/bad_input_messages.py` prints the table of
what each case prints now, from these same rows."""

from __future__ import annotations

import json
import os
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

import bsplab
from bsplab import io, scenes

FORMATS = "(.ply, .obj, .glb, .gltf, .stl, .off)"


# -- files to read -------------------------------------------------------------------


def grid_mesh(nu: int = 6, nv: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """A flat nu x nv grid of vertices, two triangles per cell (6 x 5: 40 faces)."""
    u, v = np.meshgrid(np.arange(nu, dtype=float), np.arange(nv, dtype=float))
    vertices = np.stack([u.ravel(), v.ravel(), np.zeros(u.size)], axis=1)
    faces = []
    for j in range(nv - 1):
        for i in range(nu - 1):
            a = j * nu + i
            faces += [[a, a + 1, a + nu + 1], [a, a + nu + 1, a + nu]]
    return vertices, np.array(faces)


def off_text(newline: str = "\n") -> str:
    v, f = grid_mesh()
    lines = ["OFF", f"{len(v)} {len(f)} 0"] + [" ".join(f"{x:.3f}" for x in p) for p in v]
    lines += ["3 " + " ".join(map(str, t)) for t in f]
    return newline.join(lines) + newline


def ascii_stl() -> str:
    v, f = grid_mesh()
    out = ["solid grid"]
    for t in f:
        out += ["  facet normal 0 0 1", "    outer loop"]
        out += [f"      vertex {p[0]:.3f} {p[1]:.3f} {p[2]:.3f}" for p in v[t]]
        out += ["    endloop", "  endfacet"]
    return "\n".join(out + ["endsolid grid"]) + "\n"


def binary_stl(header: bytes = b"binary grid") -> bytes:
    v, f = grid_mesh()
    rec = np.zeros(len(f), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["v"] = v[f]
    return header.ljust(80, b" ") + struct.pack("<I", len(f)) + rec.tobytes()


def glb(doc_changes: Callable[[dict], None] | None = None, binary: bytes | None = None,
        version: int = 2) -> bytes:
    """A GLB of one triangle (positions and uint32 indices in the BIN chunk);
    `doc_changes` edits its JSON, `binary` replaces the BIN chunk."""
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "<f4").tobytes()
    indices = np.array([0, 1, 2], "<u4").tobytes()
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
                      {"bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR"}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                        {"buffer": 0, "byteOffset": 36, "byteLength": 12}],
        "buffers": [{"byteLength": 48}],
    }
    if doc_changes:
        doc_changes(doc)
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    body = positions + indices if binary is None else binary
    chunks = struct.pack("<II", len(js), 0x4E4F534A) + js
    chunks += struct.pack("<II", len(body), 0x004E4942) + body
    return struct.pack("<4sII", b"glTF", version, 12 + len(chunks)) + chunks


def cut(data, fraction: float):
    return data[:int(len(data) * fraction)]


PLY_HEAD = ("ply\nformat {fmt}\nelement vertex 3\nproperty float x\nproperty float y\n"
            "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
            "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")


def set_in(path: str, value) -> Callable[[dict], None]:
    """A doc_changes that sets doc[a][i][b]... = value for path 'a.i.b'."""
    def change(doc: dict) -> None:
        keys = [int(k) if k.isdigit() else k for k in path.split(".")]
        target = doc
        for k in keys[:-1]:
            target = target[k]
        target[keys[-1]] = value
    return change


def fifo(d: Path, name: str) -> Path:
    p = d / name
    os.mkfifo(p)
    return p


def link_to_zero(d: Path, name: str) -> Path:
    p = d / name
    p.symlink_to("/dev/zero")
    return p


def write(d: Path, name: str, content) -> Path:
    p = d / name
    (p.write_bytes if isinstance(content, bytes) else p.write_text)(content)
    return p


# -- the cases -----------------------------------------------------------------------


@dataclass
class Case:
    id: str
    what: str                     # the input, as the closing note lists it
    run: Callable[[Path], object]  # tries it in folder d (raises, or returns an exit code)
    outcome: str                  # exception type name, or "exit 2"
    message: str                  # the exact message ({d}: the folder)


def mesh_case(id, what, name, content, exc, message):
    """load_mesh of a file written from `content` (bytes, text, or a
    function of the folder that makes the file and returns its path)."""
    def run(d: Path):
        path = content(d, name) if callable(content) else write(d, name, content)
        return io.load_mesh(path)
    return Case(id, what, run, exc, message)


ROOM = scenes.generate("room")
TRI = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], np.float32)
V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
F = np.array([[0, 1, 2]])
O, D = np.zeros((2, 3)), np.ones((2, 3))


def _tree():
    return bsplab.build(ROOM)


def api_case(id, what, call, exc, message):
    return Case(id, what, lambda d: call(), exc, message)


FIFO = object()  # a cli_case file made as a named pipe


def cli_case(id, argv, message, files: dict | None = None):
    """`python -m bsplab ARGV`, in-process, after writing `files` into the
    folder (FIFO: a named pipe): exit code 2 and the one-line `message` on
    stderr."""
    def run(d: Path):
        from bsplab.__main__ import main
        for name, content in (files or {}).items():
            fifo(d, name) if content is FIFO else write(d, name, content)
        try:
            return main([a.replace("{d}", str(d)) for a in argv])
        except SystemExit as e:  # argparse
            return e.code
    return Case(id, "python -m bsplab " + " ".join(argv), run, "exit 2", message)


def spec_case(id, toml: str, message: str):
    """An experiment spec (TOML) through the command line."""
    case = cli_case(id, ["experiment", "{d}/spec.toml", "--out", "{d}/out/run"],
                    "error: {d}/spec.toml: " + message, {"spec.toml": toml})
    changed = [line for line in toml.splitlines() if line not in SPEC_BASE.splitlines()]
    text = "; ".join(changed)
    case.what = "spec: " + (text if len(text) <= 60 else text[:57] + "...")
    return case


SPEC_BASE = 'scenes = ["room"]\nmethods = ["kd"]\nworkloads = ["primary"]\nwidth = 8\nheight = 8\n'

CASES = [
    # -- mesh files ------------------------------------------------------------------
    mesh_case("off_cut_90", "OFF of 40 faces cut at 90 % of its length", "cut.off",
              cut(off_text(), 0.9), "ValueError",
              "{d}/cut.off: truncated: the header promises 30 vertices and 40 faces, the file "
              "holds 30 vertices and 31 faces; its last line 64 is incomplete: face 31 says 3 "
              "vertices but lists 1"),
    mesh_case("off_cut_50", "OFF cut at 50 %, inside the vertices", "half.off",
              cut(off_text(), 0.5), "ValueError",
              "{d}/half.off: truncated: the header promises 30 vertices and 40 faces, the file "
              "holds 26 vertices and 0 faces"),
    mesh_case("off_two_vertex_face", "OFF face with 2 vertices", "two.off",
              "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n2 0 1\n", "ValueError",
              "{d}/two.off: line 7: face 1 has 2 vertices (need at least 3)"),
    mesh_case("off_fractional_count", "OFF face count written '3.0'", "frac.off",
              "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3.0 0 1 2\n", "ValueError",
              "{d}/frac.off: line 6: face 0's vertex count must be a whole number >= 0, "
              "got '3.0'"),
    mesh_case("off_unicode_digit", "OFF face count written '³' (a digit, but not 0-9)",
              "sup.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n\u00b3 0 1 2\n", "ValueError",
              "{d}/sup.off: line 6: face 0's vertex count must be a whole number >= 0, "
              "got '\u00b3'"),
    mesh_case("off_huge_count", "OFF header promising 10^9 vertices", "huge.off",
              "OFF\n1000000000 1 0\n0 0 0\n1 0 0\n", "ValueError",
              "{d}/huge.off: truncated: the header promises 1000000000 vertices and 1 faces, "
              "the file holds 2 vertices and 0 faces"),
    mesh_case("off_short_face", "OFF face line listing fewer indices than it says",
              "short.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n3 0 1 2\n", "ValueError",
              "{d}/short.off: line 6: face 0 says 3 vertices but lists 2"),
    mesh_case("off_not_utf8", "OFF with non-UTF-8 bytes in its data", "latin.off",
              b"OFF\n3 1 0\n0 0 \xe9\n1 0 0\n0 1 0\n3 0 1 2\n", "ValueError",
              "{d}/latin.off: line 3: vertex 0 has a non-numeric coordinate '\ufffd'"),
    mesh_case("off_index_beyond", "OFF face naming a vertex of a file without vertices",
              "novert.off", "OFF\n0 1 0\n3 0 1 2\n", "ValueError",
              "{d}/novert.off: line 3: face 0: vertex index 0 out of range (file has 0 "
              "vertices)"),
    mesh_case("off_no_keyword", "OFF without its 'OFF' line", "bare.off",
              "3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "ValueError",
              "{d}/bare.off: line 1: not an OFF file (the first line must be 'OFF', got "
              "'3 1 0')"),
    mesh_case("ply_version", "PLY saying format ascii 9.9", "v.ply",
              PLY_HEAD.format(fmt="ascii 9.9"), "ValueError",
              "{d}/v.ply: bad PLY header line 2 'format ascii 9.9': unsupported PLY version "
              "'9.9' (only 1.0)"),
    mesh_case("ply_no_version", "PLY saying format binary_little_endian (no version)",
              "nv.ply", PLY_HEAD.format(fmt="binary_little_endian"), "ValueError",
              "{d}/nv.ply: bad PLY header line 2 'format binary_little_endian': unsupported "
              "PLY version '' (only 1.0)"),
    mesh_case("stl_ascii_cut_50", "ASCII STL cut at 50 %", "half.stl", cut(ascii_stl(), 0.5),
              "ValueError",
              "{d}/half.stl: truncated: the ASCII STL ends without 'endsolid', after 20 whole "
              "facets"),
    mesh_case("stl_ascii_cut_10", "ASCII STL cut at 10 %", "tenth.stl", cut(ascii_stl(), 0.1),
              "ValueError",
              "{d}/tenth.stl: truncated: the ASCII STL ends inside facet 3 (line 23), after 3 "
              "whole facets"),
    mesh_case("stl_ascii_no_endsolid", "ASCII STL without its endsolid line", "open.stl",
              ascii_stl().replace("endsolid grid\n", ""), "ValueError",
              "{d}/open.stl: truncated: the ASCII STL ends without 'endsolid', after 40 whole "
              "facets"),
    mesh_case("stl_binary_cut", "binary STL cut at 90 %", "cut.stl", cut(binary_stl(), 0.9),
              "ValueError",
              "{d}/cut.stl: not a readable STL file: it does not start with 'solid' (ASCII "
              "STL); as a binary STL its header promises 40 facets (2084 bytes), but the file "
              "has 1875 bytes"),
    mesh_case("stl_binary_solid_cut", "binary STL whose header says 'solid', cut at 90 %",
              "solidcut.stl", cut(binary_stl(b"solid grid"), 0.9), "ValueError",
              "{d}/solidcut.stl: not a readable STL file: it starts with 'solid' like an ASCII "
              "STL, but byte 110 is b'\\x80'; as a binary STL its header promises 40 facets "
              "(2084 bytes), but the file has 1875 bytes"),
    mesh_case("stl_noise", "STL of 60 random bytes", "noise.stl",
              np.random.default_rng(3).bytes(60), "ValueError",
              "{d}/noise.stl: not a readable STL file: it does not start with 'solid' (ASCII "
              "STL), and at 60 bytes it is too short for a binary STL (84 bytes at least)"),
    mesh_case("glb_chunk_length", "GLB whose JSON chunk length is too large", "chunk.glb",
              lambda d, n: write(d, n, glb()[:12] + struct.pack("<I", 10**6) + glb()[16:]),
              "ValueError",
              "{d}/chunk.glb: not a readable GLB file: chunk 0 at byte 12 says 1000000 bytes, "
              "only 536 follow"),
    mesh_case("glb_cut", "GLB cut at 90 %", "cut.glb", cut(glb(), 0.9), "ValueError",
              "{d}/cut.glb: not a readable GLB file: the header gives a total length of 556 "
              "bytes, the file has 500"),
    mesh_case("glb_version", "GLB of version 1", "v1.glb", glb(version=1), "ValueError",
              "{d}/v1.glb: not a readable GLB file: GLB version 1 (only version 2 is read)"),
    mesh_case("glb_huge_count", "GLB accessor of 10^9 vertices over 36 bytes", "count.glb",
              glb(set_in("accessors.0.count", 10**9)), "ValueError",
              "{d}/count.glb: not a readable GLB file: accessor 0 needs bytes 0..12000000000 "
              "of bufferView 0, which has 36"),
    mesh_case("glb_bad_accessor", "GLB mesh naming accessor 7 of 2", "acc.glb",
              glb(set_in("meshes.0.primitives.0.attributes.POSITION", 7)), "ValueError",
              "{d}/acc.glb: not a readable GLB file: mesh 0 primitive 0: POSITION accessor 7 "
              "does not name one of the 2 accessors"),
    mesh_case("glb_no_bin", "GLB whose buffer needs a BIN chunk it lacks", "nobin.glb",
              glb(binary=b""), "ValueError",
              "{d}/nobin.glb: not a readable GLB file: buffer 0 needs 48 bytes of the BIN "
              "chunk, which has 0"),
    mesh_case("glb_bad_json", "GLB whose JSON chunk is not JSON", "json.glb",
              lambda d, n: write(d, n, glb().replace(b'{"asset"', b'{"asset"'[:-1] + b"!")),
              "ValueError",
              "{d}/json.glb: not a readable GLB file: the JSON is not valid: Expecting ':' "
              "delimiter: line 1 column 13 (char 12)"),
    mesh_case("gltf_utf16", "glTF JSON in UTF-16", "utf16.gltf",
              '{"asset": {"version": "2.0"}}'.encode("utf-16"), "ValueError",
              "{d}/utf16.gltf: not a readable GLTF file: the JSON is not UTF-8 text (byte 0)"),
    mesh_case("gltf_view_range", "glTF bufferView beyond its buffer", "view.gltf",
              json.dumps({"buffers": [{"byteLength": 8, "uri": "x.bin"}],
                          "bufferViews": [{"buffer": 0, "byteOffset": 4, "byteLength": 8}]}),
              "ValueError",
              "{d}/view.gltf: not a readable GLTF file: bufferView 0 needs bytes 4..12 of "
              "buffer 0, which has 8"),
    mesh_case("empty_path", "load_mesh('')", "", lambda d, n: "", "ValueError",
              f"an empty path is not a mesh file {FORMATS}"),
    mesh_case("fifo_ply", "a FIFO named .ply", "pipe.ply", fifo, "ValueError",
              f"{{d}}/pipe.ply: not a regular file (a named pipe); expected a mesh file "
              f"{FORMATS}"),
    mesh_case("fifo_obj", "a FIFO named .obj", "pipe.obj", fifo, "ValueError",
              f"{{d}}/pipe.obj: not a regular file (a named pipe); expected a mesh file "
              f"{FORMATS}"),
    mesh_case("dev_zero_ply", "a .ply linked to /dev/zero", "zero.ply", link_to_zero,
              "ValueError",
              f"{{d}}/zero.ply: not a regular file (a character device); expected a mesh file "
              f"{FORMATS}"),
    # -- the library -------------------------------------------------------------------
    api_case("progress_argument", "bsplab.Progress(5)", lambda: bsplab.Progress(5),
             "TypeError", "bsplab.Progress() takes no arguments, got (5); a new Progress "
                          "starts at value 0, not cancelled"),
    api_case("progress_class", "build(..., progress=bsplab.Progress) (the class)",
             lambda: bsplab.build(TRI, progress=bsplab.Progress), "TypeError",
             "progress must be a bsplab.Progress or None, got the class bsplab.Progress "
             "itself; pass an instance: progress=bsplab.Progress()"),
    api_case("progress_class_intersect", "tree.intersect(..., progress=bsplab.Progress)",
             lambda: _tree().intersect(O, D, progress=bsplab.Progress), "TypeError",
             "progress must be a bsplab.Progress or None, got the class bsplab.Progress "
             "itself; pass an instance: progress=bsplab.Progress()"),
    api_case("build_list_pair", "build([V, F]) (a list, not a tuple)",
             lambda: bsplab.build([V, F]), "TypeError",
             "a mesh of (vertices, indices) must be a tuple, got a list of two arrays: "
             "build((vertices, indices))"),
    api_case("build_ragged_list", "build([V, F2]) (a list of arrays of other shapes)",
             lambda: bsplab.build([V, np.array([[0, 1, 2], [0, 2, 1]])]), "TypeError",
             "a mesh of (vertices, indices) must be a tuple, got a list of two arrays: "
             "build((vertices, indices))"),
    api_case("vertex_beyond_float32", "a finite float64 vertex of 1e39",
             lambda: bsplab.build((np.array([[0, 0, 0], [1e39, 0, 0], [0, 1, 0]]), F)),
             "ValueError", "vertices has 1 entries out of float32 range (max 3.4e38) (first "
                           "at index 1: 1e+39)"),
    api_case("triangle_beyond_float32", "a finite float64 triangle corner of -1e39",
             lambda: bsplab.build(np.where(TRI == 1, -1e39, TRI.astype(float))), "ValueError",
             "triangles has 1 entries out of float32 range (max 3.4e38) (first at index 0: "
             "-1e+39)"),
    api_case("origin_beyond_float32", "a ray origin of 1e39",
             lambda: _tree().intersect([[1e39, 0, 0]], [[1, 0, 0]]), "ValueError",
             "origins has 1 entries out of float32 range (max 3.4e38) (first at index 0: "
             "1e+39)"),
    api_case("tmin_nones", "tmin=[None, None]", lambda: _tree().intersect(O, D, tmin=[None] * 2),
             "TypeError", "tmin must be a real number, an array of real numbers or None, got a "
                          "list holding None (None stands only for the whole tmin)"),
    api_case("tmin_string", "tmin='0.5'", lambda: _tree().intersect(O, D, tmin="0.5"),
             "TypeError", "tmin must be a real number, an array of real numbers or None, got "
                          "str '0.5'"),
    api_case("tmin_complex", "tmin=1+2j", lambda: _tree().intersect(O, D, tmin=1 + 2j),
             "TypeError", "tmin must be a real number, an array of real numbers or None, got "
                          "complex (1+2j)"),
    api_case("tmax_strings", "tmax=['1', '2']", lambda: _tree().intersect(O, D, tmax=["1", "2"]),
             "TypeError", "tmax must be a real number, an array of real numbers or None, got "
                          "a list of strings"),
    api_case("tmin_beyond_float32", "tmin=1e39", lambda: _tree().intersect(O, D, tmin=1e39),
             "ValueError", "tmin out of float32 range (max 3.4e38): 1e+39 at index 0 (inf "
                           "means no limit)"),
    api_case("tmin_above_tmax", "tmin=5, tmax=1", lambda: _tree().intersect(O, D, tmin=5, tmax=1),
             "ValueError", "tmin must be <= tmax; tmin 5 > tmax 1"),
    api_case("tmin_above_tmax_per_ray", "tmin=[0, 3], tmax=[1, 2]",
             lambda: _tree().intersect(O, D, tmin=[0, 3], tmax=[1, 2]), "ValueError",
             "tmin must be <= tmax; ray 1: tmin 3 > tmax 2"),
    api_case("trace_path_tmin_above_tmax", "trace_path(..., tmin=5, tmax=1)",
             lambda: _tree().trace_path(O[0], D[0], tmin=5, tmax=1), "ValueError",
             "tmin must be <= tmax; tmin 5 > tmax 1"),
    # -- the command line --------------------------------------------------------------
    cli_case("agree_rays_0", ["agree", "--rays", "0"],
             "error: argument --rays: must be >= 1, got 0 (see python -m bsplab agree --help)"),
    cli_case("agree_rays_negative", ["agree", "--rays", "-5"],
             "error: argument --rays: must be >= 1, got -5 (see python -m bsplab agree "
             "--help)"),
    cli_case("agree_k_0", ["agree", "--k", "0"],
             "error: argument --k: must be >= 1, got 0 (see python -m bsplab agree --help)"),
    cli_case("agree_k_negative", ["agree", "--k", "-3"],
             "error: argument --k: must be >= 1, got -3 (see python -m bsplab agree --help)"),
    cli_case("agree_k_below_min", ["agree", "--methods", "bsp_wn+kd", "--k", "2"],
             "error: --k 2 is out of range for bsp_wn+kd: it takes K in 3..64"),
    cli_case("agree_k_above_max", ["agree", "--k", "99"],
             "error: --k 99 is out of range for rbsp: it takes K in 1..64"),
    cli_case("agree_k_without_k", ["agree", "--methods", "kd", "--k", "8"],
             "error: --k 8: kd takes no K (the methods that take K: rbsp, rbsp+kd, "
             "bsp_random, bsp_random+, bsp_random+kd, bsp_wn, bsp_wn+, bsp_wn+kd, bsp_cn, "
             "bsp_cn+, bsp_cn+kd)"),
    cli_case("agree_unknown_method", ["agree", "--methods", "octree"],
             "error: unknown method 'octree'; known methods: kd, rbsp, rbsp+kd, bsp_random, "
             "bsp_random+, bsp_random+kd, bsp_wn, bsp_wn+, bsp_wn+kd, bsp_cn, bsp_cn+, "
             "bsp_cn+kd, bsp_ize, bsp_ize+kd, bvh"),
    cli_case("verdict_missing_results",
             ["verdict", "--results", "/nonexistent.csv", "--skip-trace", "--out", "{d}/x.md"],
             "error: --results /nonexistent.csv: no such results file (run `python -m bsplab "
             "results` first, or name one with --results)"),
    cli_case("verdict_missing_record",
             ["verdict", "--results", "{d}/r.csv", "--skip-trace", "--out", "{d}/x.md"],
             "error: --skip-trace: no traced record {d}/data/x.json to reuse; run without "
             "--skip-trace", {"r.csv": "scene\n"}),
    cli_case("bench_build_unknown_scene", ["bench-build", "--scenes", "nope"],
             "error: no scene 'nope': not a generated scene (room, spheres, fan, cube, grids, "
             "tilted), a file, or a mesh in the shared scenes folder (not found)"),
    cli_case("demo_fifo_scene", ["demo", "--scene", "{d}/pipe.ply", "--out", "{d}/x.png"],
             f"error: {{d}}/pipe.ply: not a regular file (a named pipe); expected a mesh file "
             f"{FORMATS}", {"pipe.ply": FIFO}),
    cli_case("experiment_fifo_spec", ["experiment", "{d}/pipe.toml"],
             "error: spec file {d}/pipe.toml is not a regular file", {"pipe.toml": FIFO}),
    cli_case("experiment_fifo_scene", ["experiment", "{d}/spec.toml"],
             "error: {d}/spec.toml: scene file {d}/pipe.ply is not a regular file",
             {"pipe.ply": FIFO, "spec.toml": 'scenes = ["pipe.ply"]\n'}),
    cli_case("report_fifo_results", ["report", "{d}/pipe.csv", "--out", "{d}/r.md"],
             "error: {d}/pipe.csv: not a regular file, not a results file",
             {"pipe.csv": FIFO}),
    cli_case("demo_empty_scene", ["demo", "--scene", "", "--out", "{d}/x.png"],
             f"error: an empty path is not a mesh file {FORMATS}"),
    # -- experiment specs --------------------------------------------------------------
    spec_case("spec_nested_500", "scenes = " + "[" * 500 + "]" * 500 + "\n",
              "nested too deeply: its tables or lists lie inside each other beyond what the "
              "reader can follow (a spec needs at most 8 levels)"),
    spec_case("spec_nested_20", SPEC_BASE + "options = " + "{a = " * 20 + "1" + "}" * 20 + "\n",
              "nested too deeply: options.a.a.a.a.a.a.a lies 9 tables or lists deep; a spec "
              "needs at most 8"),
    spec_case("spec_scenes_string", SPEC_BASE.replace('["room"]', '"fan"'),
              "scenes must be a list of names, got a string 'fan' (write scenes = [\"fan\"])"),
    spec_case("spec_methods_string", SPEC_BASE.replace('["kd"]', '"kd"'),
              "methods must be a list of names, got a string 'kd' (write methods = [\"kd\"])"),
    spec_case("spec_method_ks_without_k", SPEC_BASE + 'method_ks = { kd = [4] }\n',
              "method_ks: kd takes no K; the spec's methods that take K: none"),
    spec_case("spec_method_ks_not_in_methods", SPEC_BASE + 'method_ks = { "bsp_wn+kd" = [4] }\n',
              "method_ks: bsp_wn+kd is not among the spec's methods (kd); it would be ignored"),
    spec_case("spec_method_variants_not_in_methods",
              SPEC_BASE + 'method_variants = { rbsp = [{}] }\n',
              "method_variants: rbsp is not among the spec's methods (kd); it would be ignored"),
    spec_case("spec_executor_bogus", SPEC_BASE + 'executor = "bogus"\n',
              "executor must be one of process, dask, inline, got 'bogus'"),
    spec_case("spec_scheduler_bogus", SPEC_BASE + 'executor = "dask"\nscheduler = "bogus"\n',
              "scheduler must be a Dask scheduler address such as tcp://host:8786 (protocol "
              "tcp, tls, ws or wss; port 1..65535), got 'bogus'"),
    spec_case("spec_scheduler_without_dask", SPEC_BASE + 'scheduler = "tcp://127.0.0.1:8786"\n',
              "scheduler 'tcp://127.0.0.1:8786' is only for executor = \"dask\" (executor is "
              "'process'); remove it or set executor = \"dask\""),
    spec_case("spec_unknown_key", SPEC_BASE + 'colour = "red"\n',
              "unknown spec key(s) colour; known keys: name, scenes, methods, ks, method_ks, "
              "seeds, repetitions, workloads, width, height, ao_samples, ao_distance, options, "
              "build_threads, executor, workers, scheduler, variants, method_variants, "
              "random_rays, cull, hits_only, instances"),
]

# The one case that reaches the network stack: a scheduler address nobody
# answers (refused at once; the wait is bounded by CONNECT_SECONDS).
UNREACHABLE = cli_case("spec_scheduler_unreachable",
                       ["experiment", "{d}/spec.toml", "--out", "{d}/run"],
                       "error: dask scheduler tcp://127.0.0.1:9: cannot connect within 1 s "
                       "(Timed out trying to connect to tcp://127.0.0.1:9 after 1 s); is a "
                       "scheduler running there?",
                       {"spec.toml": SPEC_BASE + 'executor = "dask"\n'
                                                 'scheduler = "tcp://127.0.0.1:9"\n'})


def outcome(case: Case, d: Path, capsys=None) -> tuple[str, str]:
    """(exception type name or "exit N", message) of trying `case` in folder d."""
    if case.outcome.startswith("exit"):
        code = case.run(d)
        err = capsys.readouterr().err if capsys is not None else ""
        return f"exit {code}", err
    try:
        case.run(d)
    except Exception as e:  # noqa: BLE001 - the type is what the case checks
        return type(e).__name__, str(e)
    return "no error", ""


@pytest.fixture
def no_shared_scenes(monkeypatch):
    """As on a machine without the team's meshes: the messages do not name them."""
    from bsplab import workloads
    monkeypatch.setattr(workloads, "shared_scenes_dir", lambda: None)


def check(case: Case, d: Path, capsys) -> None:
    kind, message = outcome(case, d, capsys)
    expected = case.message.replace("{d}", str(d))
    if case.outcome.startswith("exit"):
        assert kind == case.outcome, (kind, message)
        assert message == expected + "\n", message
    else:
        assert (kind, message) == (case.outcome, expected)


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input_gives_its_message(case, tmp_path, capsys, no_shared_scenes):
    check(case, tmp_path, capsys)


def test_a_fifo_named_blend_is_refused_before_blender_runs(tmp_path):
    with pytest.raises(ValueError, match=f"^{tmp_path}/pipe.blend: not a regular file "
                                         r"\(a named pipe\); expected a .blend file$"):
        io.load_blend(fifo(tmp_path, "pipe.blend"), blender="/nonexistent/blender")


def test_an_unreachable_scheduler_is_said_within_the_timeout(tmp_path, capsys, monkeypatch):
    pytest.importorskip("distributed")
    from bsplab.lab import executors
    monkeypatch.setattr(executors, "CONNECT_SECONDS", 1)
    check(UNREACHABLE, tmp_path, capsys)


# -- what must keep loading ------------------------------------------------------------


def _same_triangles(got: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> None:
    np.testing.assert_array_equal(got, vertices[faces].astype(np.float32))


@pytest.mark.parametrize("name, content", [
    ("lf.off", off_text()),
    ("crlf.off", off_text("\r\n")),
    ("no_newline.off", off_text().rstrip("\n")),
    ("comments.off", "# a grid\n" + off_text().replace("\n3 ", "  # vertices end\n3 ", 1)),
    ("counts_on_keyword_line.off", off_text().replace("OFF\n", "OFF ", 1)),
])
def test_valid_off_files_load(tmp_path, name, content):
    v, f = grid_mesh()
    _same_triangles(io.load_mesh(write(tmp_path, name, content)), v, f)


def test_off_polygons_and_colours_fan_in_file_order(tmp_path):
    text = ("COFF\n5 2 0\n0 0 0 255 0 0 255\n1 0 0 0 0 0 255\n1 1 0 0 0 0 255\n"
            "0 1 0 0 0 0 255\n0.5 2 0 0 0 0 255\n4 0 1 2 3 255 0 0\n3 3 2 4\n")
    v, f = io.read_off(write(tmp_path, "quad.off", text))
    np.testing.assert_array_equal(f, [[0, 1, 2], [0, 2, 3], [3, 2, 4]])
    assert v.shape == (5, 3) and v.dtype == np.float32


@pytest.mark.parametrize("name, content", [
    ("ascii.stl", ascii_stl()),
    ("crlf.stl", ascii_stl().replace("\n", "\r\n")),
    ("no_newline.stl", ascii_stl().rstrip("\n")),
    ("upper.stl", ascii_stl().upper()),
    ("two_solids.stl", ascii_stl() + ascii_stl()),
    ("binary.stl", binary_stl()),
    ("binary_solid_header.stl", binary_stl(b"solid exported by a tool that says so")),
])
def test_valid_stl_files_load(tmp_path, name, content):
    v, f = grid_mesh()
    if name == "two_solids.stl":
        f = np.concatenate([f, f])
    _same_triangles(io.load_mesh(write(tmp_path, name, content)), v, f)


def test_a_valid_glb_loads(tmp_path):
    pytest.importorskip("trimesh")
    tris = io.load_mesh(write(tmp_path, "one.glb", glb()))
    np.testing.assert_array_equal(tris, TRI)


def test_a_symlink_to_a_mesh_file_is_read(tmp_path):
    target = write(tmp_path, "grid.off", off_text())
    (tmp_path / "link.off").symlink_to(target)
    np.testing.assert_array_equal(io.load_mesh(tmp_path / "link.off"), io.load_mesh(target))


def test_progress_is_still_the_cores_type():
    p = bsplab.Progress()
    assert isinstance(p, bsplab._core.Progress) and p.value == 0.0 and not p.cancelled
    bsplab.build(TRI, progress=p)
    assert p.value == pytest.approx(1.0)


def test_tmin_equal_to_tmax_and_infinite_ends_are_accepted():
    tree = _tree()
    o = np.tile([[1.0, 1.0, 1.0]], (2, 1))
    d = np.array([[1, 0, 0], [0, 1, 0]], float)
    hit = tree.intersect(o, d)
    assert (hit["prim"] >= 0).all()
    same = tree.intersect(o, d, tmin=hit["t"], tmax=hit["t"])  # a segment of one point
    assert same["prim"].shape == (2,)
    none = tree.intersect(o, d, tmin=np.inf, tmax=np.inf)
    assert (none["prim"] < 0).all()


def test_shipped_specs_with_per_method_tables_take_a_methods_override():
    """results.toml's method_ks names methods a `methods` override leaves out:
    the override narrows them instead of being refused."""
    from bsplab.lab import load_spec
    from bsplab.lab.verdict import SPECS
    spec = load_spec(SPECS / "results.toml", scenes=["room"], methods=["kd", "rbsp+kd"])
    assert spec.method_ks == {"rbsp+kd": [13]}

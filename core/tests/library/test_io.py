"""Mesh readers and writer: formats, property types, triangulation, errors."""

import re
from pathlib import Path

import numpy as np
import pytest

from bsplab import io
from bsplab.formats import ply

REPO = Path(__file__).resolve().parents[3]
SHARED = REPO.parent / "shared" / "scenes"


def _header(fmt, vertex_props, face_props, nv, nf, extra=""):
    lines = ["ply", f"format {fmt} 1.0", "comment test file", extra.rstrip("\n")]
    lines += [f"element vertex {nv}"] + [f"property {p}" for p in vertex_props]
    lines += [f"element face {nf}"] + [f"property {p}" for p in face_props]
    return ("\n".join(l for l in lines if l) + "\nend_header\n").encode()


# A unit square split as a quad plus a triangle on top: exercises fan triangulation.
VERTS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 2, 0]], dtype=np.float64)
POLYS = [[0, 1, 2, 3], [3, 2, 4]]
TRIS = np.array([[0, 1, 2], [0, 2, 3], [3, 2, 4]])


def _binary_ply(order="<", polys=POLYS):
    """Vertex: double xyz + uchar + float; face: uchar, list uint8 uint16, int."""
    vdt = np.dtype([("x", order + "f8"), ("y", order + "f8"), ("z", order + "f8"),
                    ("red", "u1"), ("nx", order + "f4")])
    vrec = np.zeros(len(VERTS), vdt)
    for i, c in enumerate("xyz"):
        vrec[c] = VERTS[:, i]
    vrec["red"], vrec["nx"] = 7, 0.25
    body = vrec.tobytes()
    for poly in polys:
        body += np.array([9], "u1").tobytes() + np.array([len(poly)], "u1").tobytes()
        body += np.array(poly, order + "u2").tobytes() + np.array([-1], order + "i4").tobytes()
    fmt = "binary_little_endian" if order == "<" else "binary_big_endian"
    head = _header(fmt, ["double x", "double y", "double z", "uchar red", "float nx"],
                   ["uchar intensity", "list uint8 uint16 vertex_indices", "int flags"],
                   len(VERTS), len(polys), extra="element camera 1\nproperty float fov")
    # A "camera" element precedes vertex in the header, so its bytes come first.
    camera = np.array([40.0], order + "f4").tobytes()
    return head + camera + body


@pytest.mark.parametrize("order", ["<", ">"])
def test_binary_ply_mixed_types_and_polygons(tmp_path, order):
    path = tmp_path / "mixed.ply"
    path.write_bytes(_binary_ply(order))
    v, f = io.read_ply(path)
    assert v.dtype == np.float32 and f.dtype == np.int32
    np.testing.assert_array_equal(v, VERTS.astype(np.float32))
    np.testing.assert_array_equal(f, TRIS)


def test_binary_ply_all_quads_uses_fixed_layout(tmp_path, monkeypatch):
    path = tmp_path / "quads.ply"
    path.write_bytes(_binary_ply(polys=[[0, 1, 2, 3], [1, 2, 4, 3]]))
    monkeypatch.setattr(ply, "_read_binary_variable", _fail)
    _, f = io.read_ply(path)
    np.testing.assert_array_equal(f, [[0, 1, 2], [0, 2, 3], [1, 2, 4], [1, 4, 3]])


def _fail(*args, **kwargs):
    raise AssertionError("slow per-record path used for a fixed-size layout")


def test_ascii_ply_with_crlf_and_extra_properties(tmp_path):
    head = _header("ascii", ["float x", "float y", "float z", "uchar red"],
                   ["list uchar int vertex_indices"], 5, 2).replace(b"\n", b"\r\n")
    body = "".join(f"{x} {y} {z} 200\r\n" for x, y, z in VERTS)
    body += "4 0 1 2 3\r\n3 3 2 4\r\n"
    path = tmp_path / "a.ply"
    path.write_bytes(head + body.encode())
    v, f = io.read_ply(path)
    np.testing.assert_array_equal(v, VERTS.astype(np.float32))
    np.testing.assert_array_equal(f, TRIS)
    np.testing.assert_array_equal(io.load_mesh(path), VERTS.astype(np.float32)[TRIS])


def test_write_ply_round_trip_and_exact_layout(tmp_path):
    rng = np.random.default_rng(3)
    v = rng.normal(size=(50, 3)).astype(np.float32)
    f = rng.integers(0, 50, (80, 3)).astype(np.int32)
    path = tmp_path / "w.ply"
    io.write_ply(path, v, f)
    data = path.read_bytes()
    header = data[:data.index(b"end_header\n") + len(b"end_header\n")]
    assert b"format binary_little_endian 1.0" in header
    assert b"property list uchar int vertex_indices" in header
    assert len(data) == len(header) + 12 * 50 + 13 * 80
    v2, f2 = io.read_ply(path)
    np.testing.assert_array_equal(v2, v)
    np.testing.assert_array_equal(f2, f)


def test_write_ply_rejects_bad_input(tmp_path):
    with pytest.raises(ValueError):
        io.write_ply(tmp_path / "x.ply", np.zeros((3, 2)), np.zeros((1, 3), int))
    with pytest.raises(ValueError, match="out of range"):
        io.write_ply(tmp_path / "x.ply", np.zeros((3, 3)), [[0, 1, 3]])


def test_obj_forms_negative_indices_and_polygons(tmp_path):
    text = """# comment
o thing
v 0 0 0
v 1 0 0
v 1 1 0 1.0
vt 0 0
vn 0 0 1
v 0 1 0
f 1/1/1 2/1/1 3/1/1 4/1/1
v 0.5 2 0
f -2//1 -3//1 -1//1
usemtl x
l 1 2
"""
    path = tmp_path / "m.obj"
    path.write_text(text)
    v, f = io.read_obj(path)
    np.testing.assert_array_equal(v, VERTS.astype(np.float32))
    np.testing.assert_array_equal(f, [[0, 1, 2], [0, 2, 3], [3, 2, 4]])
    assert io.load_mesh(path).shape == (3, 3, 3)


OBJ3 = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"


@pytest.mark.parametrize("content, message", [
    (OBJ3 + "f 1 2 4\n", r"line 4 'f 1 2 4': vertex index 4 out of range \(file has 3 "
                        r"vertices\)"),
    (OBJ3 + "f 0 1 2\n", "index 0"),
    ("v 0 0 0\nv 1 0 0\nf 1 2\n", "need at least 3"),
    ("v 0 0 zero\n", "line 1 'v 0 0 zero': non-numeric vertex coordinate 'zero'"),
    ("v 0 0 0\nf a b c\n", "line 2 'f a b c': vertex index 'a' is not a whole number"),
    # The index as written and its line, not a 0-based or resolved number.
    (OBJ3 + "f -1 -2 -5\n", "line 4 'f -1 -2 -5': vertex index -5 out of range "
                           r"\(only 3 vertices come before this line\)"),
    (OBJ3 + "f 1 2 9\n", "line 4 'f 1 2 9': vertex index 9 out of range"),
    (OBJ3 + "f 1 2 3\nf 1 2 9/1/1\n", "line 5 'f 1 2 9/1/1': vertex index 9 out of range"),
    (OBJ3 + "f 1 2 100000000000000000000000\n",
     "line 4 .*: vertex index 100000000000000000000000 out of range"),
    (OBJ3 + "f 1 2 1e23\n", "line 4 'f 1 2 1e23': vertex index '1e23' is not a whole number"),
    ("", "the file is empty: no triangles"),
    (OBJ3, r"no faces found \(no 'f' lines\): 3 vertices but no triangles"),
    ("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n",
     r"line 2: vertex 2 has a NaN or infinite coordinate \(nan, 0, 0\)"),
    ("v 0 0 0\nv 1 0 0\nv 0 -inf 0\nf 1 2 3\n", "line 3: vertex 3 has a NaN or infinite"),
    ("v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n", "line 2: vertex 2 has a coordinate beyond "
                                                 "the float32 range"),
])
def test_obj_errors_name_file_and_problem(tmp_path, content, message):
    path = tmp_path / "bad.obj"
    path.write_text(content)
    with pytest.raises(ValueError, match=message) as err:
        io.load_mesh(path)
    assert str(err.value).startswith(str(path) + ": ")


def test_random_bytes_are_not_an_obj(tmp_path):
    path = tmp_path / "noise.obj"
    path.write_bytes(np.random.default_rng(1).bytes(4000))
    with pytest.raises(ValueError, match="no faces found: not an OBJ file") as err:
        io.load_mesh(path)
    assert str(path) in str(err.value)


def test_obj_with_byte_order_mark(tmp_path):
    path = tmp_path / "bom.obj"
    path.write_bytes(b"\xef\xbb\xbf" + (OBJ3 + "f 1 2 3\n").encode())
    v, f = io.read_obj(path)
    assert len(v) == 3 and f.tolist() == [[0, 1, 2]]  # the first vertex is not lost


def test_a_directory_is_not_a_mesh(tmp_path):
    for name in ("scene.ply", "scene.obj", "folder"):
        (tmp_path / name).mkdir()
        for read in (io.load_mesh, io.read_mesh, io.read_ply, io.read_obj):
            with pytest.raises(ValueError, match="is a directory, not a mesh file") as err:
                read(tmp_path / name)
            assert str(tmp_path / name) in str(err.value)


def _good_ply(tmp_path):
    path = tmp_path / "good.ply"
    io.write_ply(path, VERTS, TRIS)
    return path.read_bytes()


def test_ply_errors_name_file_and_problem(tmp_path):
    good = _good_ply(tmp_path)
    cases = {
        "magic.ply": (b"plx" + good[3:], "not a PLY"),
        "noend.ply": (good.replace(b"end_header", b"end_headr"), "end_header"),
        "count.ply": (good.replace(b"element vertex 5", b"element vertex five"), "header line"),
        "type.ply": (good.replace(b"property float y", b"property flaot y"), "flaot"),
        "format.ply": (good.replace(b"binary_little_endian", b"binary_middle_endian"), "format"),
        "trunc.ply": (good[:-7], "truncated"),
        "range.ply": (good[:-4] + np.array([5], "<i4").tobytes(), "out of range"),
        "noxyz.ply": (good.replace(b"property float z", b"property float w"), "z"),
    }
    for name, (blob, message) in cases.items():
        (tmp_path / name).write_bytes(blob)
        with pytest.raises(ValueError, match=message) as err:
            io.read_ply(tmp_path / name)
        assert name in str(err.value), name


V3 = b"0 0 0\n1 0 0\n0 1 0\n"
XYZ = ["float x", "float y", "float z"]


@pytest.mark.parametrize("count, message", [
    (b"nan", "bad list count nan"), (b"inf", "bad list count inf"),
    (b"3.7", "bad list count 3.7"), (b"-3", "bad list count -3"),
    (b"1e10", "list count 10000000000 is larger than the whole file"),
])
def test_ascii_ply_bad_list_counts(tmp_path, count, message):
    path = tmp_path / "count.ply"
    path.write_bytes(_header("ascii", XYZ, ["list uchar int vertex_indices"], 3, 1)
                     + V3 + count + b" 0 1 2\n")
    with pytest.raises(ValueError, match=message) as err:
        io.load_mesh(path)
    assert str(err.value).startswith(f"{path}: face 0, list 'vertex_indices': ")


@pytest.mark.parametrize("count_type, count, message", [
    ("char", np.array([-3], "i1"), r"bad list count -3 \(must be a whole number >= 0\)"),
    ("uint", np.array([4_000_000_000], "<u4"), "list count 4000000000 is larger than the "
                                              "whole file"),
])
def test_binary_ply_bad_list_counts(tmp_path, count_type, count, message):
    path = tmp_path / "count.ply"
    verts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "<f4").tobytes()
    face = np.array([0, 1, 2], "<i4").tobytes()
    for faces in (1, 2):  # the first record (fixed layout) and a later one (record walk)
        first = np.array([3], count.dtype).tobytes() + face if faces == 2 else b""
        path.write_bytes(_header("binary_little_endian", XYZ,
                                 [f"list {count_type} int vertex_indices"], 3, faces)
                         + verts + first + count.tobytes() + face)
        with pytest.raises(ValueError, match=message) as err:
            io.load_mesh(path)
        assert str(err.value).startswith(f"{path}: face {faces - 1}, list 'vertex_indices'")


@pytest.mark.parametrize("header, message", [
    ({"nf": "3.7"}, "element count must be a whole number >= 0, got '3.7'"),
    ({"nf": "nan"}, "element count must be a whole number >= 0, got 'nan'"),
    ({"nf": "-1"}, "element count must be a whole number >= 0, got '-1'"),
    ({"face": "list float int vertex_indices"}, "a list count must have an integer type, "
                                                "not 'float'"),
])
def test_ply_header_counts(tmp_path, header, message):
    path = tmp_path / "head.ply"
    path.write_bytes(_header("ascii", XYZ, [header.get("face", "list uchar int vertex_indices")],
                             3, header.get("nf", 1)) + V3 + b"3 0 1 2\n")
    with pytest.raises(ValueError, match=re.escape(message)) as err:
        io.load_mesh(path)
    assert str(path) in str(err.value) and "header line" in str(err.value)


def test_ply_refuses_nan_vertices_and_indices_at_load(tmp_path):
    path = tmp_path / "nan.ply"
    path.write_bytes(_header("ascii", XYZ, ["list uchar int vertex_indices"], 3, 1)
                     + b"0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n")
    with pytest.raises(ValueError, match=re.escape(
            f"{path}: vertex 1 has a NaN or infinite coordinate (nan, 0, 0)")):
        io.load_mesh(path)
    verts = np.array([[0, 0, 0], [1, 0, 0], [0, np.inf, 0]], "<f4")
    with pytest.raises(ValueError, match="write_ply: vertex 2 has a NaN or infinite"):
        io.write_ply(path, verts, [[0, 1, 2]])  # the writer refuses what the reader would
    path.write_bytes(_header("binary_little_endian", XYZ, ["list uchar int vertex_indices"], 3,
                             1) + verts.tobytes() + b"\x03" + np.array([0, 1, 2], "<i4").tobytes())
    with pytest.raises(ValueError, match="vertex 2 has a NaN or infinite coordinate"):
        io.load_mesh(path)
    path.write_bytes(_header("ascii", XYZ, ["list uchar int vertex_indices"], 3, 2)
                     + V3 + b"3 0 1 2\n3 0 1 inf\n")
    with pytest.raises(ValueError, match="face 1 has a non-integer vertex index inf"):
        io.load_mesh(path)
    path.write_bytes(_header("ascii", XYZ, ["list uchar int vertex_indices"], 3, 2)
                     + V3 + b"3 0 1 2\n4 0 1 2 7\n")
    with pytest.raises(ValueError, match=r"face 1: vertex index 7 out of range \(file has 3"):
        io.load_mesh(path)


def test_ply_without_faces_has_no_triangles(tmp_path):
    path = tmp_path / "points.ply"
    path.write_bytes(_header("ascii", XYZ, ["list uchar int vertex_indices"], 3, 0) + V3)
    assert io.read_ply(path)[1].shape == (0, 3)  # a point cloud reads...
    with pytest.raises(ValueError, match="the mesh has no faces: no triangles") as err:
        io.load_mesh(path)  # ...but is no scene
    assert str(path) in str(err.value)


def test_ascii_ply_truncated(tmp_path):
    head = _header("ascii", ["float x", "float y", "float z"], ["list uchar int vertex_indices"], 3, 1)
    path = tmp_path / "t.ply"
    path.write_bytes(head + b"0 0 0\n1 0 0\n0 1 0\n3 0 1\n")
    with pytest.raises(ValueError, match="truncated"):
        io.read_ply(path)


def test_missing_file_and_unknown_extension(tmp_path):
    for name in ("nope.ply", "nope.obj", "nope.glb", "nope.stl"):
        with pytest.raises(FileNotFoundError, match="no such file"):
            io.load_mesh(tmp_path / name)
    (tmp_path / "mesh.xyz").write_text("0 0 0")
    with pytest.raises(ValueError, match=r"unsupported mesh format '\.xyz' \(expected one of "
                                         r"\.ply, \.obj, \.glb, \.gltf, \.stl, \.off\)"):
        io.load_mesh(tmp_path / "mesh.xyz")


# -- formats read through trimesh ---------------------------------------------------

@pytest.fixture
def trimesh():
    """trimesh, which writes the test files (and reads them inside bsplab.io)."""
    return pytest.importorskip("trimesh")


def _two_node_scene(trimesh):
    """A glTF scene: one quad mesh placed twice (moved and turned), a triangle once."""
    quad = trimesh.Trimesh(VERTS[:4], [[0, 1, 2], [0, 2, 3]], process=False)
    tri = trimesh.Trimesh(VERTS[[0, 1, 4]], [[0, 1, 2]], process=False)
    moved = trimesh.transformations.translation_matrix([10.0, 0.0, 0.0])
    turned = trimesh.transformations.rotation_matrix(np.pi / 2, [0, 0, 1])
    scene = trimesh.Scene()
    scene.add_geometry(quad, node_name="a", geom_name="quad", transform=moved)
    scene.add_geometry(quad, node_name="b", geom_name="quad", transform=turned)
    scene.add_geometry(tri, node_name="c", geom_name="tri")
    expected = np.concatenate([VERTS[:4][[[0, 1, 2], [0, 2, 3]]] + [10.0, 0.0, 0.0],
                               VERTS[:4][[[0, 1, 2], [0, 2, 3]]] @ turned[:3, :3].T,
                               VERTS[[0, 1, 4]][None]])
    return scene, expected


def _sorted_triangles(tris):
    """Triangles as a set (rows sorted), for comparing scenes whose node order
    the file format does not fix."""
    t = np.round(np.asarray(tris, np.float64).reshape(-1, 9), 5)
    return t[np.lexsort(t.T[::-1])]


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_gltf_scene_is_flattened_to_world_space(tmp_path, suffix, trimesh):
    scene, expected = _two_node_scene(trimesh)
    path = tmp_path / f"scene{suffix}"
    scene.export(path)
    tris = io.load_mesh(path)
    assert tris.dtype == np.float32 and tris.shape == (5, 3, 3)
    np.testing.assert_allclose(_sorted_triangles(tris), _sorted_triangles(expected), atol=1e-5)
    v, f = io.read_mesh(path)
    assert v.dtype == np.float32 and f.dtype == np.int32 and f.shape == (5, 3)
    np.testing.assert_array_equal(v[f], tris)


def test_stl_and_off_round_trip(tmp_path, trimesh):
    mesh = trimesh.Trimesh(VERTS, TRIS, process=False)
    for suffix in (".stl", ".off"):
        path = tmp_path / f"mesh{suffix}"
        mesh.export(path)
        np.testing.assert_allclose(_sorted_triangles(io.load_mesh(path)),
                                   _sorted_triangles(VERTS[TRIS]), atol=1e-6)


def test_trimesh_formats_are_checked_like_ply(tmp_path, trimesh):
    bad = VERTS.copy()
    bad[2, 1] = np.nan
    trimesh.Trimesh(bad, TRIS, process=False).export(tmp_path / "nan.glb")
    with pytest.raises(ValueError, match=r"nan.glb: vertex \d+ has a NaN or infinite"):
        io.load_mesh(tmp_path / "nan.glb")
    (tmp_path / "empty.stl").write_text("solid x\nendsolid x\n")
    with pytest.raises(ValueError, match="empty.stl: the mesh has no faces: no triangles"):
        io.load_mesh(tmp_path / "empty.stl")
    (tmp_path / "noise.glb").write_bytes(b"glTF" + np.random.default_rng(1).bytes(200))
    with pytest.raises(ValueError, match="noise.glb: not a readable GLB file") as err:
        io.load_mesh(tmp_path / "noise.glb")
    assert str(err.value).startswith(str(tmp_path / "noise.glb"))
    (tmp_path / "dir.glb").mkdir()
    with pytest.raises(ValueError, match="is a directory, not a mesh file"):
        io.load_mesh(tmp_path / "dir.glb")


def test_ply_and_glb_of_one_mesh_give_the_same_triangles(tmp_path, trimesh):
    """The same scene through bsplab's PLY reader and trimesh's GLB reader."""
    from bsplab import scenes
    v, f = scenes.generate_mesh("room")
    io.write_ply(tmp_path / "room.ply", v, f)
    trimesh.Trimesh(v, f, process=False).export(tmp_path / "room.glb")
    np.testing.assert_array_equal(io.load_mesh(tmp_path / "room.glb"),
                                  io.load_mesh(tmp_path / "room.ply"))


def test_fan_triangulate_mixed_sizes():
    tris = io.fan_triangulate(np.array([5, 3]), np.array([10, 11, 12, 13, 14, 20, 21, 22]))
    np.testing.assert_array_equal(tris, [[10, 11, 12], [10, 12, 13], [10, 13, 14], [20, 21, 22]])


# -- the shared benchmark scenes ---------------------------------------------------


def _shared_rows():
    """(file, triangles, vertices) from the table in ../shared/scenes/SOURCES.md."""
    sources = SHARED / "SOURCES.md"
    if not sources.is_file():
        return []
    pattern = re.compile(r"^\|\s*([\w.-]+\.ply)\s*\|\s*([\d,]+)\s*\|\s*([\d,]+)\s*\|", re.M)
    return [(m[1], int(m[2].replace(",", "")), int(m[3].replace(",", "")))
            for m in pattern.finditer(sources.read_text())]


@pytest.mark.parametrize("row", _shared_rows() or [None])
def test_shared_scene_counts(row):
    if row is None:
        pytest.skip(f"{SHARED} (with SOURCES.md) is absent")
    name, triangles, vertices = row
    v, f = io.read_ply(SHARED / name)
    assert (len(f), len(v)) == (triangles, vertices)
    assert np.all(np.isfinite(v))
    tris = io.load_mesh(SHARED / name)
    assert tris.shape == (triangles, 3, 3) and tris.dtype == np.float32

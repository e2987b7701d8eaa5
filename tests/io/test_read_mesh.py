"""Tests of facecap.io.read_mesh: order-keeping OBJ/PLY/glTF reading."""

from __future__ import annotations

import time
from pathlib import Path

import igl
import numpy as np
import pytest
import trimesh

from facecap.errors import FacecapWarning, FileFormatError, MeshError
from facecap.io.read_mesh import read_mesh

ICT_OBJ = Path("/work/shared/data/ict_face/generic_neutral_mesh.obj")

# A 3 x 2 patch: a quad, a pentagon, two triangles; a UV seam at vertex 1 (two UVs);
# every corner form (v, v/vt, v//vn, v/vt/vn), negative indices, comments and
# statements that must be ignored, an indented line, CRLF endings on some lines.
SMALL_OBJ = """\
# a comment line
mtllib nothing.mtl
o patch
v 0 0 0
v 1 0 0
v 2 0 0   # an inline comment
v 0 1 0
v 1 1 0 1.0
v 2 1 0\r
v 1 2 0.25
vt 0 0
vt 0.5 0
vt 0.5 1
vt 0 1
vt 0.75 0
vn 0 0 1
g left
usemtl skin
s 1
f 1/1/1 2/2/1 5/3/1 4/4/1
g right
s off
f -6/-1 3/2 6/3 7/3 5/3\r
  f 2/5 3/2 5/3
f 4/4/1 5/3/1 -1/1/1
"""
# hand-written truth (0-based)
SMALL_V = np.array(
    [[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 1, 0], [2, 1, 0], [1, 2, 0.25]], dtype=float
)
SMALL_SIZES = np.array([4, 5, 3, 3])
SMALL_POLY = np.array([0, 1, 4, 3, 1, 2, 5, 6, 4, 1, 2, 4, 3, 4, 6])
SMALL_UV_IDX = np.array([0, 1, 2, 3, 4, 1, 2, 2, 2, 4, 1, 2, 3, 2, 0])
SMALL_FACES = np.array(
    [[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 6], [1, 6, 4], [1, 2, 4], [3, 4, 6]]
)


def write(path: Path, text: str) -> Path:
    path.write_bytes(text.encode())
    return path


def test_small_obj_matches_hand_written_truth(tmp_path: Path) -> None:
    mesh = read_mesh(write(tmp_path / "small.obj", SMALL_OBJ))
    np.testing.assert_array_equal(mesh.vertices, SMALL_V)
    np.testing.assert_array_equal(mesh.polygon_sizes, SMALL_SIZES)
    np.testing.assert_array_equal(mesh.polygon_indices, SMALL_POLY)
    np.testing.assert_array_equal(mesh.faces, SMALL_FACES)
    np.testing.assert_array_equal(mesh.uv_indices, SMALL_UV_IDX)
    np.testing.assert_array_equal(mesh.uvs, [[0, 0], [0.5, 0], [0.5, 1], [0, 1], [0.75, 0]])
    assert mesh.vertices.dtype == np.float64 and mesh.faces.dtype == np.int64
    assert mesh.source_unit == "mm" and mesh.source_path == str(tmp_path / "small.obj")


def test_small_obj_matches_libigl(tmp_path: Path) -> None:
    path = write(tmp_path / "small.obj", SMALL_OBJ.replace("  f 2/5", "f 2/5"))
    V, F = igl.read_triangle_mesh(str(path))
    mesh = read_mesh(path)
    np.testing.assert_array_equal(mesh.vertices, V)  # same order and count, bit for bit
    np.testing.assert_array_equal(mesh.faces, F)  # same fan triangulation


def test_unit_converts_to_mm_and_is_recorded(tmp_path: Path) -> None:
    path = write(tmp_path / "small.obj", SMALL_OBJ)
    for unit, factor in [("mm", 1.0), ("cm", 10.0), ("m", 1000.0), ("inches", 25.4)]:
        mesh = read_mesh(path, unit=unit)
        np.testing.assert_allclose(mesh.vertices, SMALL_V * factor, rtol=1e-15)
        assert mesh.source_unit == {"inches": "in"}.get(unit, unit)


def test_triangle_only_obj_has_no_polygons(tmp_path: Path) -> None:
    mesh = read_mesh(write(tmp_path / "t.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n"))
    assert mesh.polygon_sizes is None and mesh.polygon_indices is None
    assert mesh.uvs is None and mesh.uv_indices is None
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2], [1, 3, 2]])


def test_byte_order_mark_does_not_hide_the_first_vertex(tmp_path: Path) -> None:
    path = tmp_path / "bom.obj"
    path.write_bytes(b"\xef\xbb\xbfv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    np.testing.assert_array_equal(read_mesh(path).vertices, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])


def test_line_continuation(tmp_path: Path) -> None:
    mesh = read_mesh(write(tmp_path / "c.obj", "v 0 0 0\nv 1 \\\n 0 0\nv 0 1 0\nf 1 \\\n2 3\n"))
    np.testing.assert_array_equal(mesh.vertices, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2]])


def _slow_obj_reference(text: str) -> tuple[np.ndarray, list[list[int]], list[list[int]]]:
    """An obvious line-by-line OBJ reader (v, f with v/vt forms, negative indices)."""
    V: list[list[float]] = []
    n_vt = 0
    polys: list[list[int]] = []
    uv_polys: list[list[int]] = []
    for line in text.splitlines():
        words = line.split("#")[0].split()
        if not words:
            continue
        if words[0] == "v":
            V.append([float(w) for w in words[1:4]])
        elif words[0] == "vt":
            n_vt += 1
        elif words[0] == "f":
            vs, ts = [], []
            for corner in words[1:]:
                parts = corner.split("/")
                v = int(parts[0])
                vs.append(v - 1 if v > 0 else len(V) + v)
                t = int(parts[1])
                ts.append(t - 1 if t > 0 else n_vt + t)
            polys.append(vs)
            uv_polys.append(ts)
    return np.array(V), polys, uv_polys


def test_random_obj_matches_slow_reference(tmp_path: Path) -> None:
    rng = np.random.default_rng(7)
    lines = []
    n_v = n_vt = 0
    for _ in range(400):
        kind = rng.choice(["v", "vt", "f", "g"], p=[0.4, 0.2, 0.35, 0.05])
        if kind == "v":
            lines.append("v " + " ".join(repr(float(x)) for x in rng.normal(size=3) * 100))
            n_v += 1
        elif kind == "vt":
            lines.append("vt %r %r" % tuple(rng.random(2).tolist()))
            n_vt += 1
        elif kind == "f" and n_v >= 3 and n_vt >= 1:
            size = int(rng.integers(3, 7))
            corners = []
            for _ in range(size):
                v = int(rng.integers(0, n_v))
                t = int(rng.integers(0, n_vt))
                v_tok = str(v + 1) if rng.random() < 0.5 else str(v - n_v)
                t_tok = str(t + 1) if rng.random() < 0.5 else str(t - n_vt)
                form = rng.integers(0, 2)
                corners.append(f"{v_tok}/{t_tok}" if form == 0 else f"{v_tok}/{t_tok}/1")
            lines.append("f " + " ".join(corners))
        elif kind == "g":
            lines.append("g group%d" % rng.integers(0, 9))
    text = "vn 0 0 1\n" + "\n".join(lines) + "\n"
    V_ref, polys, uv_polys = _slow_obj_reference(text)
    mesh = read_mesh(write(tmp_path / "random.obj", text))
    np.testing.assert_array_equal(mesh.vertices, V_ref)
    np.testing.assert_array_equal(mesh.polygon_sizes, [len(p) for p in polys])
    np.testing.assert_array_equal(mesh.polygon_indices, np.concatenate(polys))
    np.testing.assert_array_equal(mesh.uv_indices, np.concatenate(uv_polys))
    fan = [[p[0], p[j], p[j + 1]] for p in polys for j in range(1, len(p) - 1)]
    np.testing.assert_array_equal(mesh.faces, fan)


# ----------------------------------------------------------------------------- errors


def test_face_index_out_of_range_names_face_and_line(tmp_path: Path) -> None:
    path = write(tmp_path / "bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99\n")
    with pytest.raises(MeshError) as info:
        read_mesh(path)
    message = str(info.value)
    assert info.value.path == str(path)
    assert "line 4" in message and "face 1" in message and "99" in message and "3 vertices" in message


@pytest.mark.parametrize(
    "text, words",
    [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", ["line 4", "start at 1"]),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 1 2\n", ["line 4", "-4"]),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n", ["line 5", "texture coordinate 2"]),
    ],
)
def test_bad_indices_are_refused(tmp_path: Path, text: str, words: list[str]) -> None:
    with pytest.raises(MeshError) as info:
        read_mesh(write(tmp_path / "bad.obj", text))
    assert all(w in str(info.value) for w in words), str(info.value)


@pytest.mark.parametrize(
    "text, words",
    [
        ("v 0 0 0\nv 1 0 abc\nv 0 1 0\nf 1 2 3\n", ["line 2", "'abc'"]),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3.5\n", ["line 4", "'3.5'"]),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2/ 3\n", ["line 4", "'2/'"]),
        ("v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", ["line 2", "3 numbers"]),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", ["line 4", "3 corners"]),
        ("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n", ["vertex 3", "NaN"]),
    ],
)
def test_unparsable_text_is_refused(tmp_path: Path, text: str, words: list[str]) -> None:
    with pytest.raises(FileFormatError) as info:
        read_mesh(write(tmp_path / "bad.obj", text))
    assert all(w in str(info.value) for w in words), str(info.value)


def test_file_level_errors(tmp_path: Path) -> None:
    with pytest.raises(FileFormatError, match="no such file") as info:
        read_mesh(tmp_path / "missing.obj")
    assert info.value.path == str(tmp_path / "missing.obj")
    with pytest.raises(FileFormatError, match="unknown mesh file type"):
        read_mesh(write(tmp_path / "mesh.stl", "solid x\n"))
    with pytest.raises(FileFormatError, match="empty"):
        read_mesh(write(tmp_path / "empty.obj", ""))
    with pytest.raises(MeshError, match="no faces"):
        read_mesh(write(tmp_path / "points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n"))
    with pytest.raises(MeshError, match="no vertices"):
        read_mesh(write(tmp_path / "blank.obj", "# only a comment\n"))


def test_partial_uvs_are_dropped_with_a_warning(tmp_path: Path) -> None:
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf 2 4 3\n"
    with pytest.warns(FacecapWarning, match="2 of 6 face corners|3 of 6 face corners"):
        mesh = read_mesh(write(tmp_path / "partial.obj", text))
    assert mesh.uvs is None and mesh.uv_indices is None
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2], [1, 3, 2]])


# ----------------------------------------------------------------------------- vertex colours

COLOR_OBJ = """\
v 0 0 0 1 0 0
v 1 0 0 0 0.5 0
v 0 1 0   0 0 0.25  # blue
v 1 1 0 0.125 0.375 1.0
f 1 2 3
f 2 4 3
"""


def test_obj_vertex_colours_from_hand_written_text(tmp_path: Path) -> None:
    mesh = read_mesh(write(tmp_path / "colour.obj", COLOR_OBJ))
    np.testing.assert_array_equal(mesh.vertices, [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    np.testing.assert_array_equal(
        mesh.vertex_colors, np.array([[1, 0, 0], [0, 0.5, 0], [0, 0, 0.25], [0.125, 0.375, 1]],
                                     dtype=np.float32),
    )
    assert mesh.vertex_colors.dtype == np.float32


def test_obj_8bit_vertex_colours_are_divided_by_255(tmp_path: Path) -> None:
    text = "v 0 0 0 255 0 0\nv 1 0 0 0 51 0\nv 0 1 0 0 0 1\nf 1 2 3\n"
    mesh = read_mesh(write(tmp_path / "c8.obj", text))
    np.testing.assert_allclose(mesh.vertex_colors, [[1, 0, 0], [0, 0.2, 0], [0, 0, 1 / 255]], atol=1e-7)


def test_obj_without_colours_has_none(tmp_path: Path) -> None:
    mesh = read_mesh(write(tmp_path / "small.obj", SMALL_OBJ))
    assert mesh.vertex_colors is None


def test_obj_with_colours_on_some_vertices_drops_them_with_a_warning(tmp_path: Path) -> None:
    text = "v 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0 0 0 1\nf 1 2 3\n"
    with pytest.warns(FacecapWarning, match="only 2 of 3 vertices have colours"):
        mesh = read_mesh(write(tmp_path / "mixed.obj", text))
    assert mesh.vertex_colors is None
    np.testing.assert_array_equal(mesh.vertices, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])


def test_obj_colours_out_of_range_are_refused(tmp_path: Path) -> None:
    with pytest.raises(FileFormatError, match="vertex colours"):
        read_mesh(write(tmp_path / "bad.obj", "v 0 0 0 -1 0 0\nv 1 0 0 0 0 0\nv 0 1 0 0 0 0\nf 1 2 3\n"))


def _colour_ply(fmt: str, kind: str) -> tuple[bytes, np.ndarray]:
    """A hand-written 4-vertex PLY with ``kind`` ('uchar', 'float', 'double') colours and alpha."""
    rgb8 = np.array([[255, 0, 0], [0, 128, 0], [0, 0, 7], [10, 20, 30]])
    head = ["ply", f"format {fmt} 1.0", "element vertex 4", "property float x", "property float y",
            "property float z", f"property {kind} red", f"property {kind} green", f"property {kind} blue",
            "property uchar alpha", "element face 2", "property list uchar int vertex_indices",
            "end_header"]
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=float)
    values = rgb8 if kind == "uchar" else rgb8 / 255.0
    dt = {"uchar": "u1", "float": "f4", "double": "f8"}[kind]
    if fmt == "ascii":
        rows = [" ".join([*(repr(float(x)) for x in V[i]), *(str(c) if kind == "uchar" else repr(float(c))
                                                           for c in values[i]), "255"])
                for i in range(4)]
        body = ("\n".join(rows) + "\n3 0 1 2\n3 1 3 2\n").encode()
    else:
        e = "<" if fmt == "binary_little_endian" else ">"
        rec = np.zeros(4, dtype=[("x", e + "f4"), ("y", e + "f4"), ("z", e + "f4"), ("r", e + dt),
                                 ("g", e + dt), ("b", e + dt), ("a", "u1")])
        for j, k in enumerate("xyz"):
            rec[k] = V[:, j]
        for j, k in enumerate("rgb"):
            rec[k] = values[:, j]
        rec["a"] = 255
        faces = np.array([(3, 0, 1, 2), (3, 1, 3, 2)],
                         dtype=[("n", "u1"), ("a", e + "i4"), ("b", e + "i4"), ("c", e + "i4")])
        body = rec.tobytes() + faces.tobytes()
    return ("\n".join(head) + "\n").encode() + body, rgb8 / 255.0


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian", "binary_big_endian"])
@pytest.mark.parametrize("kind", ["uchar", "float", "double"])
def test_ply_vertex_colours_from_hand_written_file(tmp_path: Path, fmt: str, kind: str) -> None:
    data, truth = _colour_ply(fmt, kind)
    path = tmp_path / "colour.ply"
    path.write_bytes(data)
    mesh = read_mesh(path)
    np.testing.assert_allclose(mesh.vertex_colors, truth, atol=1e-7)
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2], [1, 3, 2]])


def test_ply_vertex_colours_agree_with_trimesh(tmp_path: Path) -> None:
    data, truth = _colour_ply("binary_little_endian", "uchar")
    path = tmp_path / "colour.ply"
    path.write_bytes(data)
    ours = read_mesh(path).vertex_colors
    theirs = np.asarray(trimesh.load(path, process=False).visual.vertex_colors)[:, :3] / 255.0
    np.testing.assert_allclose(ours, theirs, atol=1e-7)


def test_glb_vertex_colours_come_from_color_0(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    rgb8 = rng.integers(0, 256, size=(4, 3), dtype=np.uint8)
    tm = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], [[0, 1, 2], [1, 3, 2]],
                         process=False)
    tm.visual.vertex_colors = np.c_[rgb8, np.full(4, 255, np.uint8)]
    tm.export(tmp_path / "c.glb")
    np.testing.assert_allclose(read_mesh(tmp_path / "c.glb").vertex_colors, rgb8 / 255.0, atol=1e-7)
    plain = trimesh.Trimesh(tm.vertices, tm.faces, process=False)
    plain.export(tmp_path / "p.glb")
    assert read_mesh(tmp_path / "p.glb").vertex_colors is None


# ----------------------------------------------------------------------------- PLY

PLY_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0.5, 0.25]], dtype=float)
PLY_POLYS = [[0, 1, 2, 3], [1, 4, 2]]


def ply_bytes(fmt: str, polys: list[list[int]], *, texcoord: bool = False, extra: bool = False) -> bytes:
    """A PLY written by hand; ``extra`` adds properties and an element to skip."""
    endian = {"binary_little_endian": "<", "binary_big_endian": ">"}.get(fmt)
    head = ["ply", f"format {fmt} 1.0", "comment made by hand", f"element vertex {len(PLY_V)}",
            "property float x", "property double y", "property float z"]
    if extra:
        head += ["property uchar red", "property list uchar int neighbours"]
    head += [f"element face {len(polys)}", "property list uchar int vertex_indices"]
    if texcoord:
        head.append("property list uchar float texcoord")
    if extra:
        head += ["property int flags", "element edge 1", "property int vertex1", "property int vertex2"]
    head.append("end_header")
    out = ("\n".join(head) + "\n").encode()
    uv = lambda p: [0.125 * (k % 7) for k in range(2 * len(p))]  # noqa: E731
    if endian is None:
        for i, v in enumerate(PLY_V):
            skipped = f" 7 {i % 3} " + " ".join(["1"] * (i % 3)) if extra else ""
            out += (" ".join(map(str, v)) + skipped + "\n").encode()
        for p in polys:
            line = f"{len(p)} " + " ".join(map(str, p))
            if texcoord:
                line += f" {2 * len(p)} " + " ".join(map(str, uv(p)))
            out += (line + (" 5" if extra else "") + "\n").encode()
        if extra:
            out += b"0 1\n"
        return out
    for i, v in enumerate(PLY_V):
        out += np.array([v[0]], endian + "f4").tobytes() + np.array([v[1]], endian + "f8").tobytes()
        out += np.array([v[2]], endian + "f4").tobytes()
        if extra:
            out += bytes([7, i % 3]) + np.ones(i % 3, endian + "i4").tobytes()
    for p in polys:
        out += bytes([len(p)]) + np.array(p, endian + "i4").tobytes()
        if texcoord:
            out += bytes([2 * len(p)]) + np.array(uv(p), endian + "f4").tobytes()
        if extra:
            out += np.array([5], endian + "i4").tobytes()
    if extra:
        out += np.array([0, 1], endian + "i4").tobytes()
    return out


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian", "binary_big_endian"])
@pytest.mark.parametrize("texcoord", [False, True])
@pytest.mark.parametrize("extra", [False, True])
def test_ply_mixed_polygons(tmp_path: Path, fmt: str, texcoord: bool, extra: bool) -> None:
    path = tmp_path / "m.ply"
    path.write_bytes(ply_bytes(fmt, PLY_POLYS, texcoord=texcoord, extra=extra))
    mesh = read_mesh(path, unit="cm")
    np.testing.assert_array_equal(mesh.vertices, PLY_V * 10)
    np.testing.assert_array_equal(mesh.polygon_sizes, [4, 3])
    np.testing.assert_array_equal(mesh.polygon_indices, [0, 1, 2, 3, 1, 4, 2])
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2], [0, 2, 3], [1, 4, 2]])
    if texcoord:
        expected = np.array([0.125 * (k % 7) for p in PLY_POLYS for k in range(2 * len(p))]).reshape(-1, 2)
        np.testing.assert_array_equal(mesh.uvs[mesh.uv_indices], expected)
    else:
        assert mesh.uvs is None


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian"])
def test_ply_triangles_match_trimesh(tmp_path: Path, fmt: str) -> None:
    """Where trimesh can read a PLY (one polygon size), both keep the same vertices and faces."""
    rng = np.random.default_rng(3)
    src = trimesh.Trimesh(rng.normal(size=(50, 3)), rng.integers(0, 50, size=(80, 3)), process=False)
    path = tmp_path / "t.ply"
    path.write_bytes(trimesh.exchange.ply.export_ply(src, encoding="ascii" if fmt == "ascii" else "binary"))
    ref = trimesh.load(path, process=False)
    mesh = read_mesh(path)
    np.testing.assert_array_equal(mesh.vertices, np.asarray(ref.vertices))
    np.testing.assert_array_equal(mesh.faces, np.asarray(ref.faces))
    assert mesh.polygon_sizes is None


def test_ply_vertex_uvs(tmp_path: Path) -> None:
    text = (
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nproperty float s\nproperty float t\nelement face 1\n"
        "property list uchar int vertex_indices\nend_header\n"
        "0 0 0 0.25 0.5\n1 0 0 0.75 0.5\n0 1 0 0.25 1\n3 0 1 2\n"
    )
    mesh = read_mesh(write(tmp_path / "uv.ply", text))
    np.testing.assert_array_equal(mesh.uvs, [[0.25, 0.5], [0.75, 0.5], [0.25, 1]])
    np.testing.assert_array_equal(mesh.uv_indices, [0, 1, 2])


@pytest.mark.parametrize(
    "data, error, words",
    [
        (b"not a ply\n", FileFormatError, "not a PLY"),
        (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
         b"property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n", MeshError, "no faces"),
        (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
         b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
         b"0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", MeshError, "vertex 7"),
        (b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
         b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
         + np.zeros(9, "<f4").tobytes() + b"\x03\x00\x00", FileFormatError, "truncated"),
        (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
         b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
         b"0 zero 0\n3 0 0 0\n", FileFormatError, "'zero'"),
        (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty quaternion x\nend_header\n",
         FileFormatError, "header line 4"),
        (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
         b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
         b"0 0 0\n1 0 0\n0 1 0\n3 0 1.5 2\n", FileFormatError, "integers"),
        (b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
         b"property float z\nelement face 2\nproperty list char int vertex_indices\nend_header\n"
         + np.zeros(9, "<f4").tobytes() + b"\x04" + np.arange(4, dtype="<i4").tobytes()
         + b"\xff" + np.arange(3, dtype="<i4").tobytes(), FileFormatError, "negative length|truncated"),
    ],
)
def test_ply_errors(tmp_path: Path, data: bytes, error: type, words: str) -> None:
    path = tmp_path / "bad.ply"
    path.write_bytes(data)
    with pytest.raises(error, match=words) as info:
        read_mesh(path)
    assert info.value.path == str(path)


# ----------------------------------------------------------------------------- glTF


def test_glb_concatenates_meshes_in_file_order_with_node_transforms(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    box = trimesh.creation.box()
    sphere = trimesh.creation.icosphere(subdivisions=1)
    uv_sphere = rng.random((len(sphere.vertices), 2))
    sphere.visual = trimesh.visual.TextureVisuals(uv=uv_sphere)
    box.visual = trimesh.visual.TextureVisuals(uv=rng.random((len(box.vertices), 2)))
    scene = trimesh.Scene()
    shift = np.array([0.1, 0.2, 0.3])
    scene.add_geometry(box, geom_name="box", node_name="box_node",
                       transform=trimesh.transformations.translation_matrix(shift))
    scene.add_geometry(sphere, geom_name="sphere", node_name="sphere_node")
    path = tmp_path / "scene.glb"
    path.write_bytes(scene.export(file_type="glb"))

    mesh = read_mesh(path)  # glTF is in metres by specification
    assert mesh.source_unit == "m"
    nb = len(box.vertices)
    np.testing.assert_allclose(mesh.vertices[:nb], (box.vertices + shift) * 1000, atol=1e-4)
    np.testing.assert_allclose(mesh.vertices[nb:], sphere.vertices * 1000, atol=1e-4)
    np.testing.assert_array_equal(mesh.faces, np.concatenate([box.faces, sphere.faces + nb]))
    np.testing.assert_allclose(mesh.uvs[nb:], uv_sphere, atol=1e-6)  # float32 in the file
    np.testing.assert_array_equal(mesh.uv_indices, mesh.faces.ravel())
    assert read_mesh(path, unit="mm").source_unit == "mm"


# ----------------------------------------------------------------------------- the ICT face


@pytest.mark.skipif(not ICT_OBJ.exists(), reason="ICT FaceKit neutral not available")
def test_ict_neutral_keeps_file_order_and_counts() -> None:
    start = time.perf_counter()
    mesh = read_mesh(ICT_OBJ, unit="cm")
    elapsed = time.perf_counter() - start
    V_igl, F_igl = igl.read_triangle_mesh(str(ICT_OBJ))
    assert mesh.n_vertices == 26_719 and V_igl.shape == (26_719, 3)
    np.testing.assert_array_equal(read_mesh(ICT_OBJ).vertices, V_igl)
    np.testing.assert_allclose(mesh.vertices, V_igl * 10.0, rtol=1e-15)
    np.testing.assert_array_equal(mesh.faces, F_igl)
    assert mesh.polygon_sizes.size == 26_384
    assert np.count_nonzero(mesh.polygon_sizes == 4) == 25_836
    assert np.count_nonzero(mesh.polygon_sizes == 3) == 548
    assert mesh.uvs.shape == (28_911, 2) and mesh.uv_indices.size == mesh.polygon_indices.size
    assert elapsed < 1.0

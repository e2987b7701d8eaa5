"""Tests of facecap.io.write_mesh: OBJ/PLY writing, round trips, number formatting."""

from __future__ import annotations

from pathlib import Path

import igl
import numpy as np
import pytest
import trimesh

from facecap.errors import FileFormatError, InputError, MeshError
from facecap.io.read_mesh import read_mesh
from facecap.io.write_mesh import _fixed_rows, _join, _number_rows, write_mesh
from facecap.structures import Mesh


def quad_mesh(seed: int = 0, *, uvs: str = "seams") -> Mesh:
    """A 4 x 3 vertex grid of quads with one quad split in two triangles, in mm.

    ``uvs``: 'seams' gives the left column of quads its own UV island (vertices
    on the seam have two UVs), 'vertex' one UV per vertex, 'none' no UVs.
    """
    rng = np.random.default_rng(seed)
    nx, ny = 4, 3
    x, y = np.meshgrid(np.arange(nx, dtype=float), np.arange(ny, dtype=float))
    V = np.stack([x.ravel() * 7.5, y.ravel() * 7.5, rng.normal(size=nx * ny)], axis=1) * 1.3
    idx = np.arange(nx * ny).reshape(ny, nx)
    sizes, corners = [], []
    for j in range(ny - 1):
        for i in range(nx - 1):
            q = [idx[j, i], idx[j, i + 1], idx[j + 1, i + 1], idx[j + 1, i]]
            if (i, j) == (2, 1):
                sizes += [3, 3]
                corners += [q[0], q[1], q[2], q[0], q[2], q[3]]
            else:
                sizes.append(4)
                corners += q
    sizes_a, corners_a = np.array(sizes), np.array(corners)
    starts = np.cumsum(sizes_a) - sizes_a
    faces = np.array(
        [[corners_a[s], corners_a[s + k], corners_a[s + k + 1]] for s, n in zip(starts, sizes_a)
         for k in range(1, n - 1)]
    )
    uv = uv_idx = None
    if uvs != "none":
        base = rng.random((nx * ny, 2))
        if uvs == "vertex":
            uv, uv_idx = base, corners_a.copy()
        else:  # the left quad column uses a second copy of its UVs
            uv = np.concatenate([base, base[:, ::-1] * 0.5])
            left = np.repeat(np.arange(sizes_a.size) % (nx - 1) == 0, sizes_a)
            uv_idx = np.where(left, corners_a + nx * ny, corners_a)
    return Mesh(V, faces, sizes_a, corners_a, uv, uv_idx, source_unit="mm")


def assert_same_topology(a: Mesh, b: Mesh) -> None:
    np.testing.assert_array_equal(a.faces, b.faces)
    np.testing.assert_array_equal(a.polygon_sizes, b.polygon_sizes)
    np.testing.assert_array_equal(a.polygon_indices, b.polygon_indices)


@pytest.mark.parametrize("uvs", ["seams", "vertex", "none"])
def test_obj_round_trip(tmp_path: Path, uvs: str) -> None:
    mesh = quad_mesh(uvs=uvs)
    path = write_mesh(mesh, tmp_path / "m.obj")
    assert path == tmp_path / "m.obj"
    back = read_mesh(path)
    # default decimals: 6 in mm, so the rounding error is at most 0.5e-6 mm
    assert np.abs(back.vertices - mesh.vertices).max() <= 0.5e-6 + 1e-12
    assert_same_topology(back, mesh)
    if uvs == "none":
        assert back.uvs is None
    else:
        np.testing.assert_allclose(back.uvs[back.uv_indices], mesh.uvs[mesh.uv_indices], rtol=0, atol=5e-10)
        np.testing.assert_array_equal(back.uv_indices, mesh.uv_indices)  # UV list kept as is


@pytest.mark.parametrize("uvs", ["seams", "vertex", "none"])
def test_ply_round_trip_is_exact(tmp_path: Path, uvs: str) -> None:
    mesh = quad_mesh(uvs=uvs)
    back = read_mesh(write_mesh(mesh, tmp_path / "m.ply"))
    np.testing.assert_array_equal(back.vertices, mesh.vertices)  # float64 in the file
    assert_same_topology(back, mesh)
    if uvs == "none":
        assert back.uvs is None
    else:  # float32 in the file
        np.testing.assert_allclose(back.uvs[back.uv_indices], mesh.uvs[mesh.uv_indices], rtol=0, atol=6e-8)
    header = (tmp_path / "m.ply").read_bytes().split(b"end_header")[0]
    assert b"binary_little_endian" in header
    assert (b"property float s" in header) == (uvs == "vertex")
    assert (b"texcoord" in header) == (uvs == "seams")


@pytest.mark.parametrize("suffix", [".obj", ".ply"])
def test_writes_in_the_source_unit(tmp_path: Path, suffix: str) -> None:
    mesh = read_mesh(write_mesh(quad_mesh(), tmp_path / f"mm{suffix}"))
    cm_mesh = Mesh(mesh.vertices, mesh.faces, mesh.polygon_sizes, mesh.polygon_indices,
                   mesh.uvs, mesh.uv_indices, source_unit="cm")
    path = write_mesh(cm_mesh, tmp_path / f"cm{suffix}")
    raw = read_mesh(path)  # read as if in mm: numbers are the cm values
    np.testing.assert_allclose(raw.vertices, mesh.vertices / 10.0, rtol=0, atol=0.5e-7 + 1e-15)
    back = read_mesh(path, unit="cm")
    np.testing.assert_allclose(back.vertices, mesh.vertices, rtol=0, atol=0.5e-6 + 1e-12)
    # an explicit unit overrides the mesh's
    in_m = read_mesh(write_mesh(cm_mesh, tmp_path / f"m{suffix}", unit="m"))
    np.testing.assert_allclose(in_m.vertices, mesh.vertices / 1000.0, rtol=0, atol=0.5e-9 + 1e-15)


def test_animation_frame_replaces_positions(tmp_path: Path) -> None:
    mesh = quad_mesh()
    frame = mesh.vertices + np.random.default_rng(1).normal(size=mesh.vertices.shape)
    for suffix in (".obj", ".ply"):
        back = read_mesh(write_mesh(mesh, tmp_path / f"f{suffix}", vertices=frame))
        np.testing.assert_allclose(back.vertices, frame, rtol=0, atol=0.5e-6 + 1e-12)
        assert_same_topology(back, mesh)
    with pytest.raises(InputError, match="vertices"):
        write_mesh(mesh, tmp_path / "bad.obj", vertices=frame[:-1])
    with pytest.raises(InputError, match="vertices"):
        write_mesh(mesh, tmp_path / "bad.obj", vertices=np.full_like(frame, np.nan))


def test_obj_text_is_what_libigl_reads(tmp_path: Path) -> None:
    mesh = quad_mesh()
    path = write_mesh(mesh, tmp_path / "m.obj", decimals=9)
    V, F = igl.read_triangle_mesh(str(path))
    assert np.abs(V - mesh.vertices).max() <= 0.5e-9 + 1e-13
    np.testing.assert_array_equal(F, mesh.faces)


def test_triangle_ply_is_what_trimesh_reads(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    mesh = Mesh(rng.normal(size=(30, 3)) * 50, rng.integers(0, 30, size=(40, 3)))
    path = write_mesh(mesh, tmp_path / "t.ply")
    ref = trimesh.load(path, process=False)
    np.testing.assert_array_equal(np.asarray(ref.vertices), mesh.vertices)
    np.testing.assert_array_equal(np.asarray(ref.faces), mesh.faces)


def test_obj_lines_for_a_known_triangle(tmp_path: Path) -> None:
    mesh = Mesh(np.array([[10.0, -2.5, 0.0], [0.125, 1e-7, -3.0], [-0.0, 1234.5, 7.0]]),
                np.array([[0, 1, 2]]), uvs=np.array([[0.5, 0.25], [1.0, 0.0], [0.0, 1.0]]),
                uv_indices=np.array([2, 0, 1]))
    lines = write_mesh(mesh, tmp_path / "t.obj").read_text().splitlines()
    assert lines[1:] == [
        "v 10 -2.5 0", "v 0.125 0 -3", "v 0 1234.5 7",
        "vt 0.5 0.25", "vt 1 0", "vt 0 1",
        "f 1/3 2/1 3/2",
    ]


def test_number_text_matches_python_formatting() -> None:
    """Vectorised fixed-point text against Python's correctly rounded '%.{d}f'."""
    rng = np.random.default_rng(11)
    ints = np.concatenate([rng.integers(-10**12, 10**12, 2000), [0, -1, 1, 9, 10, 99, 100, -10**15]])
    assert _join(_number_rows(ints, 0), np.full((1, ints.size), 10, np.uint8)).split() == [
        str(int(i)).encode() for i in ints
    ]
    for decimals in (0, 1, 3, 6, 9):
        # values with at most `decimals` digits after the point: no rounding ties to argue about
        x = rng.integers(-10**9, 10**9, 3000) / 10.0**decimals
        x[:4] = [0.0, -0.0, 10.0**-decimals, -(10.0**-decimals)]
        text = _join(_fixed_rows(x, decimals), np.full((1, x.size), 10, np.uint8)).split()
        expected = []
        for v in x:
            s = "%.*f" % (decimals, v)
            s = s.rstrip("0").rstrip(".") if "." in s else s
            expected.append(("0" if s in ("-0", "") else s).encode())
        assert text == expected
        # and any value comes back within half a unit of the last decimal
        y = rng.normal(size=3000) * 10.0 ** rng.integers(-3, 5, 3000)
        back = np.array(_join(_fixed_rows(y, decimals), np.full((1, y.size), 10, np.uint8)).split(), float)
        assert np.all(np.abs(back - y) <= 0.5 * 10.0**-decimals * (1 + 1e-9) + np.abs(y) * 1e-15)


def test_no_temporary_file_is_left_behind(tmp_path: Path) -> None:
    mesh = quad_mesh()
    write_mesh(mesh, tmp_path / "a.obj")
    write_mesh(mesh, tmp_path / "a.obj")  # replaces
    write_mesh(mesh, tmp_path / "b.ply")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.obj", "b.ply"]


def test_errors(tmp_path: Path) -> None:
    mesh = quad_mesh()
    with pytest.raises(FileFormatError, match="'.stl'"):
        write_mesh(mesh, tmp_path / "m.stl")
    with pytest.raises(FileFormatError, match="does not exist"):
        write_mesh(mesh, tmp_path / "no" / "such" / "m.obj")
    with pytest.raises(InputError, match="mesh"):
        write_mesh(mesh.vertices, tmp_path / "m.obj")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="decimals"):
        write_mesh(mesh, tmp_path / "m.obj", decimals=20)
    with pytest.raises(InputError, match="unit"):
        write_mesh(mesh, tmp_path / "m.obj", unit="furlong")
    bad_uv = Mesh(mesh.vertices, mesh.faces, mesh.polygon_sizes, mesh.polygon_indices,
                  mesh.uvs, mesh.uv_indices + 1000)
    with pytest.raises(InputError, match="uv_indices"):
        write_mesh(bad_uv, tmp_path / "m.ply")
    assert not any(tmp_path.iterdir())


# ----------------------------------------------------------------------------- vertex colours


def _coloured_mesh() -> Mesh:
    rng = np.random.default_rng(11)
    V = rng.normal(size=(60, 3)) * 30.0
    F = np.stack([np.arange(58), np.arange(1, 59), np.arange(2, 60)], axis=1)
    return Mesh(V, F, vertex_colors=rng.random((60, 3)))


def test_obj_colour_round_trip(tmp_path: Path) -> None:
    mesh = _coloured_mesh()
    back = read_mesh(write_mesh(mesh, tmp_path / "c.obj"))
    np.testing.assert_allclose(back.vertex_colors, mesh.vertex_colors, atol=1e-6, rtol=0)
    np.testing.assert_allclose(back.vertices, mesh.vertices, atol=1e-6, rtol=0)
    first = (tmp_path / "c.obj").read_text().splitlines()[1].split()
    assert first[0] == "v" and len(first) == 7


def test_ply_colour_round_trip_is_within_one_8bit_step(tmp_path: Path) -> None:
    mesh = _coloured_mesh()
    back = read_mesh(write_mesh(mesh, tmp_path / "c.ply"))
    np.testing.assert_allclose(back.vertex_colors, mesh.vertex_colors, atol=0.5 / 255 + 1e-7, rtol=0)
    np.testing.assert_array_equal(back.vertices, mesh.vertices)


def test_ply_colours_are_what_trimesh_reads(tmp_path: Path) -> None:
    mesh = _coloured_mesh()
    path = write_mesh(mesh, tmp_path / "c.ply")
    theirs = np.asarray(trimesh.load(path, process=False).visual.vertex_colors)[:, :3] / 255.0
    np.testing.assert_allclose(theirs, mesh.vertex_colors, atol=0.5 / 255 + 1e-7, rtol=0)


def test_colours_survive_with_vertices_and_validation() -> None:
    mesh = _coloured_mesh()
    moved = mesh.with_vertices(mesh.vertices + 1.0)
    np.testing.assert_array_equal(moved.vertex_colors, mesh.vertex_colors)
    assert Mesh(mesh.vertices, mesh.faces).vertex_colors is None
    for bad in (np.ones((59, 3)), np.full((60, 3), 2.0), np.full((60, 3), np.nan)):
        with pytest.raises(MeshError, match="vertex_colors"):
            Mesh(mesh.vertices, mesh.faces, vertex_colors=bad)

"""Alembic export, read back with Alembic's own reader (alembic3d's IArchive)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from alembic3d import Abc, AbcGeom

from facecap.errors import InputError
from facecap.io import write_alembic
from facecap.structures import Mesh

RATE = 24.0


def _polygon_mesh(*, uvs: str = "face-varying") -> Mesh:
    """A flat sheet of a quad, a triangle and a pentagon, all counter-clockwise seen from +z (mm).

    Face-varying UVs with a seam: the pentagon's corners use UVs of their own,
    so UV indices differ from vertex indices.
    """
    V = np.array([[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0], [20, 0, 0],
                  [20, 10, 0], [25, 15, 0], [15, 20, 0]], float)
    polygons = [[0, 1, 2, 3], [1, 4, 2], [4, 5, 6, 7, 2]]
    sizes = [len(p) for p in polygons]
    corners = [i for p in polygons for i in p]
    faces = [[p[0], p[k], p[k + 1]] for p in polygons for k in range(1, len(p) - 1)]
    if uvs == "none":
        return Mesh(V, faces, polygon_sizes=sizes, polygon_indices=corners)
    if uvs == "per-vertex":
        return Mesh(V, faces, polygon_sizes=sizes, polygon_indices=corners, uvs=V[:, :2] / 25.0)
    uv = np.concatenate([V[:, :2] / 25.0, V[[4, 5, 6, 7, 2], :2] / 25.0 + 0.5])
    uv_indices = [0, 1, 2, 3, 1, 4, 2, 8, 9, 10, 11, 12]
    return Mesh(V, faces, polygon_sizes=sizes, polygon_indices=corners, uvs=uv, uv_indices=uv_indices)


def _take(mesh: Mesh, n_frames: int = 6) -> np.ndarray:
    rng = np.random.default_rng(0)
    return (mesh.vertices[None] + rng.normal(size=(n_frames, mesh.n_vertices, 3))).astype(np.float32)


def _reverse_each_polygon(values: np.ndarray, sizes: list[int]) -> np.ndarray:
    """Blender's abc_reader_mesh.cc rule, one polygon at a time: corner k of n comes from file corner n-1-k."""
    out, start = [], 0
    for n in sizes:
        out.extend(values[start:start + n][::-1])
        start += n
    return np.array(out)


def _open_mesh(path: Path) -> tuple[object, object]:
    archive = Abc.IArchive(str(path))
    head = archive.getTop().getChild("Head")
    assert AbcGeom.IXform.matches(head.getHeader())
    assert AbcGeom.IXform(head, Abc.WrapExistingFlag.kWrapExisting).getSchema().isConstantIdentity()
    face = head.getChild("Face")
    assert AbcGeom.IPolyMesh.matches(face.getHeader())
    return archive, AbcGeom.IPolyMesh(face, Abc.WrapExistingFlag.kWrapExisting).getSchema()


def test_topology_uvs_positions_and_time_sampling_read_back(tmp_path: Path) -> None:
    mesh = _polygon_mesh()
    frames = _take(mesh)
    sizes = mesh.polygon_sizes.tolist()
    out = write_alembic(tmp_path / "take.abc", mesh, [(0, frames[:4]), (4, frames[4:])], n_frames=6, rate=RATE,
                        unit_scale=0.001)
    assert out == tmp_path / "take.abc"
    assert [p.name for p in tmp_path.iterdir()] == ["take.abc"]
    archive, schema = _open_mesh(out)

    sample = schema.getValue(Abc.ISampleSelector(0.0))
    assert np.asarray(sample.getFaceCounts()).tolist() == sizes
    file_corners = np.asarray(sample.getFaceIndices())
    np.testing.assert_array_equal(_reverse_each_polygon(file_corners, sizes), mesh.polygon_indices)
    # Alembic's winding: seen from +z (the polygons' normal) the file lists each polygon clockwise.
    start = 0
    for n in sizes:
        x, y = mesh.vertices[file_corners[start:start + n], :2].T
        assert 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0  # shoelace: clockwise
        start += n

    uv = schema.getUVsParam()
    assert uv.valid() and uv.isIndexed() and uv.getScope() == AbcGeom.GeometryScope.kFacevaryingScope
    uv_sample = uv.getIndexedValue(Abc.ISampleSelector(0.0))
    np.testing.assert_array_equal(np.asarray(uv_sample.getVals()), mesh.uvs.astype(np.float32))
    np.testing.assert_array_equal(_reverse_each_polygon(np.asarray(uv_sample.getIndices()), sizes), mesh.uv_indices)

    assert schema.getNumSamples() == 6
    sampling = schema.getTimeSampling()
    assert sampling.getTimeSamplingType().isUniform()
    assert sampling.getTimeSamplingType().getTimePerCycle() == pytest.approx(1 / RATE, rel=1e-12)
    assert [sampling.getSampleTime(k) for k in range(6)] == pytest.approx(np.arange(6) / RATE, rel=1e-12)
    assert Abc.GetArchiveStartAndEndTime(archive) == pytest.approx((0.0, 5 / RATE), rel=1e-12)
    for k in (0, 2, 3, 5):  # a sample selector given a number selects by time in seconds
        points = np.asarray(schema.getValue(Abc.ISampleSelector(k / RATE)).getPositions())
        np.testing.assert_allclose(points, frames[k] * 0.001, rtol=1e-6, atol=0)
        topology = np.asarray(schema.getValue(Abc.ISampleSelector(k / RATE)).getFaceIndices())
        np.testing.assert_array_equal(topology, file_corners)  # every sample has the same topology


def test_per_vertex_uvs_are_indexed_by_vertex(tmp_path: Path) -> None:
    mesh = _polygon_mesh(uvs="per-vertex")
    write_alembic(tmp_path / "take.abc", mesh, [(0, _take(mesh, 2))], n_frames=2, rate=RATE)
    _, schema = _open_mesh(tmp_path / "take.abc")
    uv = schema.getUVsParam().getIndexedValue(Abc.ISampleSelector(0.0))
    indices = _reverse_each_polygon(np.asarray(uv.getIndices()), mesh.polygon_sizes.tolist())
    np.testing.assert_array_equal(np.asarray(uv.getVals())[indices], mesh.uvs[mesh.polygon_indices].astype(np.float32))


def test_a_mesh_without_uvs_writes_none_and_triangles_without_polygons(tmp_path: Path) -> None:
    mesh = _polygon_mesh(uvs="none")
    triangles = Mesh(mesh.vertices, mesh.faces)
    frames = _take(mesh, 3)
    write_alembic(tmp_path / "take.abc", triangles, iter([(0, frames[:1]), (1, frames[1:])]), n_frames=3,
                  rate=RATE, progress=True)
    _, schema = _open_mesh(tmp_path / "take.abc")
    assert not schema.getUVsParam().valid()
    sample = schema.getValue(Abc.ISampleSelector(2 / RATE))
    assert np.asarray(sample.getFaceCounts()).tolist() == [3] * triangles.n_faces
    np.testing.assert_array_equal(
        _reverse_each_polygon(np.asarray(sample.getFaceIndices()), [3] * triangles.n_faces), triangles.faces.ravel()
    )
    np.testing.assert_array_equal(np.asarray(sample.getPositions()), frames[2])  # unit_scale 1: as given


def test_a_streamed_write_reads_back_like_one_block(tmp_path: Path) -> None:
    mesh = _polygon_mesh()
    frames = _take(mesh, 12)
    write_alembic(tmp_path / "one.abc", mesh, [(0, frames)], n_frames=12, rate=RATE)
    write_alembic(tmp_path / "many.abc", mesh, [(k, frames[k:k + 1]) for k in range(12)], n_frames=12, rate=RATE)
    (_a, one), (_b, many) = _open_mesh(tmp_path / "one.abc"), _open_mesh(tmp_path / "many.abc")
    for k in range(12):
        selector = Abc.ISampleSelector(k / RATE)
        np.testing.assert_array_equal(np.asarray(many.getValue(selector).getPositions()), frames[k])
        np.testing.assert_array_equal(np.asarray(one.getValue(selector).getPositions()), frames[k])


@pytest.mark.parametrize("case", ["nan at frame 3", "short stream", "out of order", "wrong vertex count"])
def test_a_bad_stream_raises_and_leaves_nothing(case: str, tmp_path: Path) -> None:
    mesh = _polygon_mesh()
    frames = _take(mesh)
    nan = frames.copy()
    nan[3, 2, 0] = np.nan
    blocks = {
        "nan at frame 3": [(0, nan[:2]), (2, nan[2:])],
        "short stream": [(0, frames[:5])],
        "out of order": [(0, frames[:2]), (4, frames[4:])],
        "wrong vertex count": [(0, frames[:, 1:])],
    }[case]
    with pytest.raises(InputError):
        write_alembic(tmp_path / "take.abc", mesh, blocks, n_frames=6, rate=RATE)
    assert list(tmp_path.iterdir()) == []


def test_bad_arguments_are_named_and_write_nothing(tmp_path: Path) -> None:
    mesh = _polygon_mesh()
    block = [(0, _take(mesh, 1))]
    with pytest.raises(InputError, match=r"\.abc file name"):
        write_alembic(tmp_path / "take.usdc", mesh, block, n_frames=1, rate=RATE)
    with pytest.raises(InputError, match="Mesh"):
        write_alembic(tmp_path / "take.abc", mesh.vertices, block, n_frames=1, rate=RATE)
    with pytest.raises(InputError, match="rate"):
        write_alembic(tmp_path / "take.abc", mesh, block, n_frames=1, rate=-1.0)
    with pytest.raises(InputError, match="unit_scale"):
        write_alembic(tmp_path / "take.abc", mesh, block, n_frames=1, rate=RATE, unit_scale=0.0)
    with pytest.raises(InputError, match="does not exist"):
        write_alembic(tmp_path / "missing" / "take.abc", mesh, block, n_frames=1, rate=RATE)
    bad_uvs = Mesh(mesh.vertices, mesh.faces, polygon_sizes=mesh.polygon_sizes,
                   polygon_indices=mesh.polygon_indices, uvs=mesh.uvs, uv_indices=mesh.uv_indices[:-1])
    with pytest.raises(InputError, match="uv_indices"):
        write_alembic(tmp_path / "take.abc", bad_uvs, block, n_frames=1, rate=RATE)
    assert list(tmp_path.iterdir()) == []


def test_a_missing_alembic3d_names_the_extra(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "alembic3d", None)  # makes `import alembic3d` raise ImportError
    mesh = _polygon_mesh()
    with pytest.raises(InputError, match=r'pip install "facecap\[alembic\]"'):
        write_alembic(tmp_path / "take.abc", mesh, [(0, _take(mesh, 1))], n_frames=1, rate=RATE)
    assert list(tmp_path.iterdir()) == []


def test_importing_the_writer_does_not_import_alembic3d() -> None:
    code = "import sys, facecap.io, facecap.io.write_alembic; print('alembic3d' in sys.modules, 'imath' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["False", "False"]


def test_head_motion_is_the_head_xform_per_frame(tmp_path: Path) -> None:
    from scipy.spatial.transform import Rotation

    mesh = _polygon_mesh()
    frames = _take(mesh)
    T = frames.shape[0]
    motion = np.tile(np.eye(4), (T, 1, 1))
    motion[:, :3, :3] = Rotation.from_rotvec(np.outer(np.linspace(0, 0.3, T), [0.2, 1.0, 0.1])).as_matrix()
    motion[:, :3, 3] = np.outer(np.arange(T), [1.0, -2.0, 3.0])
    path = write_alembic(tmp_path / "moving.abc", mesh, [(0, frames)], n_frames=T, rate=24.0, head_motion=motion,
                         unit_scale=0.001)
    archive = Abc.IArchive(str(path))
    head = AbcGeom.IXform(archive.getTop().getChild("Head"), Abc.WrapExistingFlag.kWrapExisting).getSchema()
    assert head.getNumSamples() == T
    for k in (0, T // 2, T - 1):
        sample = head.getValue(Abc.ISampleSelector(k / 24.0))
        row_major = np.array([[sample.getMatrix()[i][j] for j in range(4)] for i in range(4)])
        expected = motion[k].copy()
        expected[:3, 3] *= 0.001  # the unit scale applies to the translation as to the points
        np.testing.assert_allclose(row_major.T, expected, atol=1e-12)
    with pytest.raises(InputError, match="head_motion"):
        write_alembic(tmp_path / "bad.abc", mesh, [(0, frames)], n_frames=T, rate=24.0, head_motion=motion[:2])
    assert not (tmp_path / "bad.abc").exists()

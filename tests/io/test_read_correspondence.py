"""Tests for facecap.io.read_correspondence: JSON marker maps, snapping, and matching to a take."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from facecap.errors import CorrespondenceError, FacecapWarning, FileFormatError, InputError
from facecap.io.read_correspondence import CorrespondenceMatch, match_correspondence, read_correspondence
from facecap.structures import Correspondence, Mesh


def _bumpy_grid(seed=0, n=6, unit="mm"):
    """A small non-flat open surface: an n x n grid (mm) with random heights."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.arange(n, dtype=float) * 10.0, np.arange(n, dtype=float) * 10.0)
    V = np.column_stack([x.ravel(), y.ravel(), rng.uniform(-4.0, 4.0, n * n)])
    F = []
    for i in range(n - 1):
        for j in range(n - 1):
            a, b, c, d = i * n + j, i * n + j + 1, (i + 1) * n + j, (i + 1) * n + j + 1
            F += [[a, b, d], [a, d, c]]
    return Mesh(V, np.array(F), source_unit=unit)


def _closest_on_segment(p, a, b):
    ab = b - a
    t = np.clip(np.dot(p - a, ab) / np.dot(ab, ab), 0.0, 1.0)
    return a + t * ab


def _closest_on_triangle(p, a, b, c):
    """Obvious reference: the projection if it falls inside, else the best edge point."""
    n = np.cross(b - a, c - a)
    q = p - np.dot(p - a, n) / np.dot(n, n) * n
    # inside test by signed areas
    signs = [np.dot(np.cross(v1 - v0, q - v0), n) for v0, v1 in ((a, b), (b, c), (c, a))]
    if min(signs) >= 0:
        return q
    candidates = [_closest_on_segment(p, u, v) for u, v in ((a, b), (b, c), (c, a))]
    return min(candidates, key=lambda x: np.sum((x - p) ** 2))


def _brute_force_closest(p, V, F):
    best = None
    for f in F:
        q = _closest_on_triangle(p, *V[f])
        d = np.linalg.norm(q - p)
        if best is None or d < best[0]:
            best = (d, q)
    return best


def _write(tmp_path, doc, name="map.json"):
    path = tmp_path / name
    path.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    return path


def test_points_snap_to_the_brute_force_closest_surface_point(tmp_path):
    mesh = _bumpy_grid()
    rng = np.random.default_rng(1)
    queries = np.column_stack([rng.uniform(-5, 55, 25), rng.uniform(-5, 55, 25), rng.uniform(-15, 15, 25)])
    path = _write(tmp_path, {f"p{k}": q.tolist() for k, q in enumerate(queries)})
    corr = read_correspondence(path, mesh)
    assert corr.labels == tuple(f"p{k}" for k in range(25))
    snapped = corr.points(mesh.vertices)
    for k, q in enumerate(queries):
        d_ref, c_ref = _brute_force_closest(q, mesh.vertices, mesh.faces)
        assert corr.snap_distances[k] == pytest.approx(d_ref, abs=1e-9)
        np.testing.assert_allclose(snapped[k], c_ref, atol=1e-7)
    # stored as a triangle and its barycentric weights
    np.testing.assert_array_equal(corr.vertex_indices, mesh.faces[corr.triangles])
    assert (corr.weights >= 0).all()
    np.testing.assert_allclose(corr.weights.sum(axis=1), 1.0, atol=1e-12)


def test_vertex_entries_and_the_ways_to_evaluate_the_map(tmp_path):
    mesh = _bumpy_grid()
    path = _write(tmp_path, {"Chin": 7, "Nose": 0, "Brow": [12.0, 13.0, 40.0]})
    corr = read_correspondence(path, mesh)
    np.testing.assert_array_equal(corr.vertex_indices[:2], [[7, 7, 7], [0, 0, 0]])
    np.testing.assert_array_equal(corr.weights[:2], [[1, 0, 0], [1, 0, 0]])
    assert corr.triangles[:2].tolist() == [-1, -1] and corr.snap_distances[:2].tolist() == [0.0, 0.0]
    # follows the surface as it deforms: one pose, a batch of poses, and the sparse matrix agree
    rng = np.random.default_rng(2)
    poses = mesh.vertices[None] + rng.normal(size=(4, mesh.n_vertices, 3))
    batch = corr.points(poses)
    assert batch.shape == (4, 3, 3)
    np.testing.assert_allclose(batch[2], corr.points(poses[2]))
    np.testing.assert_allclose(batch[2, :2], poses[2, [7, 0]])
    W = corr.matrix(mesh.n_vertices)
    assert W.shape == (3, mesh.n_vertices)
    np.testing.assert_allclose(W @ poses[1], corr.points(poses[1]))
    with pytest.raises(InputError, match="vertices"):
        corr.points(poses[0, :5])


def test_points_are_in_the_mesh_source_unit_or_the_stated_units(tmp_path):
    mesh_cm = _bumpy_grid(unit="cm")  # vertices already in mm; its file was in cm
    on_surface_mm = np.array([0.2, 0.3, 0.5]) @ mesh_cm.vertices[mesh_cm.faces[10]]  # inside triangle 10
    corr = read_correspondence(_write(tmp_path, {"a": (on_surface_mm / 10.0).tolist()}), mesh_cm)
    assert corr.snap_distances[0] == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(corr.points(mesh_cm.vertices)[0], on_surface_mm, atol=1e-9)
    wrapped = {"units": "m", "markers": {"a": (on_surface_mm / 1000.0).tolist(), "b": 3}}
    corr = read_correspondence(_write(tmp_path, wrapped, "wrapped.json"), mesh_cm)
    assert corr.labels == ("a", "b")
    np.testing.assert_allclose(corr.points(mesh_cm.vertices)[0], on_surface_mm, atol=1e-9)


def test_degenerate_triangle_gets_finite_weights(tmp_path):
    V = np.array([[0.0, 0, 0], [10, 0, 0], [20, 0, 0], [0, 100, 50], [1, 100, 50], [0, 101, 50]])
    mesh = Mesh(V, np.array([[0, 1, 2], [3, 4, 5]]))  # the first triangle is a line segment
    q = np.array([14.0, 3.0, 4.0])
    corr = read_correspondence(_write(tmp_path, {"a": q.tolist()}), mesh)
    assert np.isfinite(corr.weights).all()
    np.testing.assert_allclose(corr.points(V)[0], [14.0, 0.0, 0.0], atol=1e-9)
    assert corr.snap_distances[0] == pytest.approx(5.0)


@pytest.mark.parametrize(
    "doc, message",
    [
        ({"a": 36}, "vertex index 36 out of range .*36 vertices"),
        ({"a": -1}, "vertex index -1 out of range"),
        ({"a": 3.0}, "'a': expected a non-negative integer vertex index or a point"),
        ({"a": True}, "'a': expected"),
        ({"a": "12"}, "'a': expected"),
        ({"a": [1, 2]}, "'a': expected"),
        ('{"a": [NaN, 1, 2]}', "'a': expected"),
        ({}, "empty"),
        ({"markers": {}}, "empty"),
        ('{"a": 1, "b": 2, "a": 3}', "label 'a' appears more than once"),
        ('{"a": 1,\n "b": }', "malformed JSON at line 2"),
        ([1, 2], "expected a JSON object"),
        ({"units": "parsec", "markers": {"a": 1}}, "units"),
        ({" ": 1}, "label is empty"),
    ],
    ids=[
        "too_big", "negative", "float", "bool", "string", "two_numbers", "nan", "empty", "empty_wrapped",
        "duplicate", "malformed", "list", "units", "blank_label",
    ],
)
def test_bad_maps_raise_correspondence_error_naming_the_file(tmp_path, doc, message):
    path = _write(tmp_path, doc)
    with pytest.raises(CorrespondenceError, match=message) as info:
        read_correspondence(path, _bumpy_grid())
    assert info.value.path == str(path)
    assert "\n" not in str(info.value)


def test_missing_file_and_wrong_mesh_type(tmp_path):
    with pytest.raises(FileFormatError, match="file not found"):
        read_correspondence(tmp_path / "none.json", _bumpy_grid())
    with pytest.raises(InputError, match="Mesh"):
        read_correspondence(_write(tmp_path, {"a": 1}), np.zeros((3, 3)))  # type: ignore[arg-type]


def test_matching_to_a_take(tmp_path):
    mesh = _bumpy_grid()
    path = _write(tmp_path, {"c": 5, "a": 1, "b": [10.0, 10.0, 9.0]})
    take_labels = ("a", "x", "b", "c", "y")
    with pytest.warns(FacecapWarning, match=r"\['x', 'y'\]") as record:
        corr = read_correspondence(path, mesh, labels=take_labels)
    assert record[0].filename == __file__  # points at the caller
    assert corr.labels == ("a", "b", "c")  # take order

    full = read_correspondence(path, mesh)
    with pytest.warns(FacecapWarning, match="not in the marker map, so they do not drive the face") as record:
        match = match_correspondence(full, take_labels)
    assert record[0].filename == __file__
    assert isinstance(match, CorrespondenceMatch)
    assert match.ignored_labels == ("x", "y")
    assert match.take_columns.dtype == np.int64
    # row k of the matched map is take column take_columns[k]
    assert [take_labels[i] for i in match.take_columns] == list(match.correspondence.labels)
    order = [full.labels.index(s) for s in match.correspondence.labels]
    np.testing.assert_array_equal(match.correspondence.vertex_indices, full.vertex_indices[order])
    np.testing.assert_array_equal(match.correspondence.weights, full.weights[order])


def test_matching_without_ignored_markers_is_silent_and_extra_map_markers_raise(tmp_path):
    mesh = _bumpy_grid()
    path = _write(tmp_path, {"a": 1, "b": 2, "ghost": 3, "phantom": 4})
    full = read_correspondence(path, mesh)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        match = match_correspondence(full.select(["b", "a"]), ["a", "b"])
    assert match.take_columns.tolist() == [0, 1] and match.ignored_labels == ()
    with pytest.raises(CorrespondenceError, match=r"take does not have: \['ghost', 'phantom'\]") as info:
        read_correspondence(path, mesh, labels=["a", "b"])
    assert info.value.path == str(path)


def test_correspondence_record_validates_its_shapes():
    with pytest.raises(CorrespondenceError, match="shape"):
        Correspondence(("a", "b"), [[0, 0, 0]], [[1, 0, 0]])
    with pytest.raises(CorrespondenceError, match="duplicate"):
        Correspondence(("a", "a"), [[0, 0, 0]] * 2, [[1, 0, 0]] * 2)

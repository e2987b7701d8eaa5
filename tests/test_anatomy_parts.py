"""Analytic checks of the anatomy's parts, without the mesher: thickness, embedding, quality, jaw cut, muscles, landmarks."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from facecap.anatomy import (
    ANATOMY_LANDMARK_NAMES,
    AnatomyLandmarks,
    MuscleSpec,
    anatomy_landmarks,
    embed_points,
    embedding_matrix,
    facial_muscles,
    is_mandible,
    jaw_joint,
    read_landmarks,
    tet_quality,
    tet_volumes,
    tissue_thickness,
)
from facecap.errors import FileFormatError, InputError
from facecap.synth import load_ict_sample


def _grid_mesh(n: int = 21, size: float = 100.0) -> tuple[np.ndarray, np.ndarray]:
    u = np.linspace(0.0, size, n)
    X, Y = np.meshgrid(u, u, indexing="ij")
    V = np.stack([X.ravel(), Y.ravel(), np.zeros(n * n)], axis=1)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return V, F


def _box_tets(nx: int, ny: int, nz: int, h: float, origin: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """A box of cubes, each split into 6 positively oriented tetrahedra (Kuhn / Freudenthal)."""
    g = np.stack(np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), np.arange(nz + 1), indexing="ij"), -1).reshape(-1, 3)
    X = g * h + np.asarray(origin)
    node = lambda i, j, k: (i * (ny + 1) + j) * (nz + 1) + k
    I, J, K = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    I, J, K = I.ravel(), J.ravel(), K.ravel()
    corners = {(a, b, c): node(I + a, J + b, K + c) for a in (0, 1) for b in (0, 1) for c in (0, 1)}
    tets = []
    for perm in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)):
        path = [(0, 0, 0)]
        for axis in perm:
            step = list(path[-1])
            step[axis] = 1
            path.append(tuple(step))
        tets.append(np.stack([corners[p] for p in path], axis=1))
    T = np.concatenate(tets).astype(np.int64)
    vol = tet_volumes(X, T)
    T[vol < 0] = T[vol < 0][:, [0, 2, 1, 3]]
    return X.astype(np.float64), T


def test_thickness_keeps_landmark_values_and_stays_within_their_range() -> None:
    V, F = _grid_mesh()
    rng = np.random.default_rng(3)
    idx = rng.choice(V.shape[0], size=8, replace=False)
    depths = rng.uniform(4.0, 22.0, size=8)
    t = tissue_thickness(V, F, idx, depths)
    assert np.allclose(t[idx], depths, atol=1e-12)
    # discrete maximum principle on a mesh of right triangles (cotangent weights >= 0)
    assert t.min() >= depths.min() - 1e-9 and t.max() <= depths.max() + 1e-9
    # a constant is harmonic: equal landmark values give that value everywhere
    assert np.allclose(tissue_thickness(V, F, idx, np.full(8, 7.25)), 7.25, atol=1e-9)


def test_thickness_refuses_bad_depths() -> None:
    V, F = _grid_mesh(5)
    with pytest.raises(InputError, match="depths"):
        tissue_thickness(V, F, [0, 3], [5.0, -1.0])
    with pytest.raises(InputError, match="vertices"):
        tissue_thickness(V, F, [0, 0], [5.0, 6.0])


def test_embedding_reproduces_points_and_flags_inside() -> None:
    X, T = _box_tets(4, 3, 2, 10.0, (0.0, 0.0, 0.0))
    rng = np.random.default_rng(7)
    inside_pts = rng.uniform([0.5, 0.5, 0.5], [39.5, 29.5, 19.5], size=(500, 3))
    outside_pts = rng.uniform([0, 0, 20.5], [40, 30, 22], size=(50, 3))  # just above the box
    P = np.concatenate([inside_pts, outside_pts])
    e = embed_points(X, T, P)
    W = embedding_matrix(e, X.shape[0], T)
    assert np.abs(W @ X - P).max() < 1e-9
    assert np.allclose(e.weights.sum(axis=1), 1.0, atol=1e-12)
    assert e.inside[:500].all() and not e.inside[500:].any()
    # a point inside lies in its tetrahedron: the weights are its barycentric coordinates, all in [0, 1]
    assert e.weights[:500].min() >= -1e-9 and e.weights[:500].max() <= 1 + 1e-9


def test_quality_of_a_regular_tetrahedron() -> None:
    a = 10.0
    X = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=np.float64) * a / (2 * np.sqrt(2))
    T = np.array([[0, 1, 2, 3]])
    if tet_volumes(X, T)[0] < 0:
        T = T[:, [0, 2, 1, 3]]
    q = tet_quality(X, T)
    assert q.min_volume_mm3 == pytest.approx(a**3 / (6 * np.sqrt(2)), rel=1e-12)
    assert q.min_dihedral_deg == pytest.approx(np.degrees(np.arccos(1 / 3)), abs=1e-9)
    assert q.max_dihedral_deg == pytest.approx(np.degrees(np.arccos(1 / 3)), abs=1e-9)
    assert q.n_inverted == 0
    assert tet_quality(X, T[:, [0, 2, 1, 3]]).n_inverted == 1


def test_mandible_cut_and_condyles_from_the_ict_landmarks() -> None:
    sample = load_ict_sample()
    lm = anatomy_landmarks(sample.mesh)
    joint = jaw_joint(lm)
    left, right = joint.condyles
    # the ICT face is mirror-symmetric (to its float32 storage): the condyles mirror each other; in front of the ears, behind the eyes
    assert left[0] > 30 and right[0] < -30 and left[0] == pytest.approx(-right[0], abs=1e-3)
    assert lm.point("exocanthion_L")[2] - 30 > left[2] > lm.point("supraglenoid_L")[2] - 10
    # at the height of the orbitale (Frankfort horizontal)
    assert lm.local(left)[1] == pytest.approx(lm.local(lm.point("suborbital_L"))[1], abs=1e-9)
    pts = np.array([lm.point(n) for n in ("pogonion", "menton", "labrale_inferius", "gonion_L",
                                          "labrale_superius", "nasion", "zygomatic_L", "supraorbital_R")])
    assert is_mandible(pts, joint).tolist() == [True] * 4 + [False] * 4


def test_muscle_fraction_volume_and_fibres_of_a_straight_tube() -> None:
    """A flat 'skin' at z = 0 with 10 mm of tissue: a 6 x 4 mm elliptic tube 30 mm long at 5 mm depth."""
    X, T = _box_tets(40, 20, 10, 1.0, (-20.0, -10.0, -10.0))
    sv, sf = _grid_mesh(41, 40.0)
    skin = sv - np.array([20.0, 20.0, 0.0])
    normals = np.tile([0.0, 0.0, 1.0], (skin.shape[0], 1))
    depth = np.full(skin.shape[0], 10.0)
    a, b = np.array([-15.0, 0.0, 0.0]), np.array([15.0, 0.0, 0.0])
    lm = AnatomyLandmarks(("a", "b"), np.array([0, 1]), np.stack([a, b]), np.eye(3), np.zeros(3))
    spec = MuscleSpec("tube", (lambda p: p("a"), lambda p: p("b")), (0.5, 0.5), 6.0, 4.0)
    m = facial_muscles(X, T, lm, skin, normals, depth, specs=(spec,))
    vol = tet_volumes(X, T)
    inside_volume = float((m.fractions[:, 0] * vol).sum())
    exact = np.pi * 3.0 * 2.0 * 30.0
    # 27 uniform samples per 1/6 mm^3 tetrahedron: the boundary layer's sampling error is a few per cent
    assert inside_volume == pytest.approx(exact, rel=0.05)
    used = m.fractions[:, 0] > 0
    assert np.allclose(np.linalg.norm(m.fibres[used, 0], axis=1), 1.0)
    assert np.all(m.fibres[used, 0] @ np.array([1.0, 0.0, 0.0]) > 0.999)
    centroids = X[T].mean(axis=1)
    far = np.linalg.norm(centroids[:, 1:] - np.array([0.0, -5.0]), axis=1) > 4.5
    assert np.all(m.fractions[far, 0] == 0)
    near_axis = np.linalg.norm(centroids[:, 1:] - np.array([0.0, -5.0]), axis=1) < 0.8
    assert np.all(m.fractions[near_axis & (np.abs(centroids[:, 0]) < 14), 0] == 1.0)
    assert np.allclose(m.curves[0, 0], [-15, 0, -5]) and np.allclose(m.curves[0, -1], [15, 0, -5])


def test_landmark_json_round_trip_and_errors(tmp_path: Path) -> None:
    mesh = load_ict_sample().mesh
    lm = anatomy_landmarks(mesh)
    assert lm.names == ANATOMY_LANDMARK_NAMES
    path = tmp_path / "landmarks.json"
    path.write_text(json.dumps(lm.as_dict()))
    again = read_landmarks(path, mesh)
    assert np.array_equal(again.vertices, lm.vertices)
    # points a little off the surface snap to the nearest vertex (0.09 mm off; vertices are >= 0.3 mm apart at the mouth corners)
    moved = {n: (mesh.vertices[v] + 0.05).tolist() for n, v in lm.as_dict().items()}
    path.write_text(json.dumps(moved))
    assert np.array_equal(read_landmarks(path, mesh).vertices, lm.vertices)
    # the 68 iBUG points give the same named landmarks as the built-in ICT ones
    path.write_text(json.dumps({"ibug68": load_ict_sample().landmarks.tolist()}))
    assert np.array_equal(read_landmarks(path, mesh).vertices, lm.vertices)
    bad = dict(lm.as_dict())
    del bad["pogonion"]
    path.write_text(json.dumps(bad))
    with pytest.raises(InputError, match="missing landmarks.*pogonion"):
        read_landmarks(path, mesh)
    far = dict(moved)
    far["menton"] = [0.0, -75.7, 160.0]
    path.write_text(json.dumps(far))
    with pytest.raises(InputError, match="menton"):
        read_landmarks(path, mesh)
    path.write_text("[1, 2")
    with pytest.raises(FileFormatError):
        read_landmarks(path, mesh)
    with pytest.raises(FileFormatError, match="not found"):
        read_landmarks(tmp_path / "none.json", mesh)


def test_a_scan_outside_the_ict_topology_needs_landmarks() -> None:
    V, F = _grid_mesh(6)
    from facecap.structures import Mesh

    with pytest.raises(InputError, match="not in the ICT-FaceKit topology"):
        anatomy_landmarks(Mesh(vertices=V, faces=F))


def test_a_scan_too_small_or_inside_out_is_refused() -> None:
    from facecap.anatomy import soft_tissue_shell
    from facecap.errors import MeshError
    from facecap.structures import Mesh

    full = load_ict_sample().mesh
    lm = anatomy_landmarks(full)
    # only the nose of the face: the landmarks (as points) lie far from it
    nose = np.flatnonzero(np.linalg.norm(full.vertices - lm.point("pronasale"), axis=1) < 20)
    keep = np.isin(full.faces, nose).all(axis=1)
    used, inverse = np.unique(full.faces[keep], return_inverse=True)
    small = Mesh(vertices=full.vertices[used], faces=inverse.reshape(-1, 3))
    with pytest.raises(InputError, match="further than 10 mm"):
        anatomy_landmarks(small, {n: p.tolist() for n, p in zip(lm.names, lm.points)})
    # the whole face with its triangles turned inside out: refused, not a bone outside the face
    flipped = Mesh(vertices=full.vertices, faces=full.faces[:, ::-1])
    with pytest.raises(MeshError, match="face into the head"):
        soft_tissue_shell(flipped, lm)

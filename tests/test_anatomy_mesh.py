"""The soft-tissue volume of the bundled ICT face: bone inside the skin, one valid tetrahedral mesh of it."""

from __future__ import annotations

import os

import igl
import numpy as np
import pytest
import trimesh

from facecap.anatomy import (
    MIN_TISSUE_MM,
    PART_BONE,
    PART_SKIN,
    anatomy_landmarks,
    soft_tissue_shell,
    tet_quality,
    tet_volumes,
    tetrahedralize_shell,
)
from facecap.anatomy.tetrahedralize_shell import ENVELOPE_MM
from facecap.errors import InputError
from facecap.synth import load_ict_sample

TEST_TETS = 2000


@pytest.fixture(scope="module")
def shell():
    mesh = load_ict_sample().mesh
    return soft_tissue_shell(mesh, anatomy_landmarks(mesh))


@pytest.fixture(scope="module")
def tets(shell, tmp_path_factory):
    """The coarse mesh, made from an empty working folder (fTetWild itself writes files into it)."""
    folder = tmp_path_factory.mktemp("cwd")
    previous = os.getcwd()
    os.chdir(folder)
    try:
        mesh = tetrahedralize_shell(shell.V, shell.F, n_tets=TEST_TETS)
    finally:
        os.chdir(previous)
    return mesh, folder


def test_the_mesher_leaves_no_files_behind(tets) -> None:
    _, folder = tets
    assert list(folder.iterdir()) == []


def test_closed_surface_is_watertight_outward_and_keeps_the_scan_vertices(shell) -> None:
    surface = trimesh.Trimesh(shell.V, shell.F, process=False)
    assert surface.is_watertight and surface.is_winding_consistent and surface.volume > 0
    scan = load_ict_sample().mesh.vertices
    s = shell.skin_vertices.size
    assert np.array_equal(shell.V[:s], scan[shell.skin_vertices])
    # every skin triangle is a scan triangle with the scan's orientation
    scan_faces = {tuple(np.roll(f, -np.argmin(f))) for f in load_ict_sample().mesh.faces.tolist()}
    skin = shell.skin_vertices[shell.F[shell.part == PART_SKIN]]
    assert all(tuple(np.roll(f, -np.argmin(f))) in scan_faces for f in skin.tolist())


def test_bone_lies_inside_the_skin_by_the_table_depth_at_landmarks(shell) -> None:
    S = shell.V[: shell.skin_vertices.size]
    bone = trimesh.Trimesh(shell.bone, shell.skin_faces, process=False)
    origins, dirs = S[shell.landmark_rows], -shell.normals[shell.landmark_rows]
    loc, ray, _ = bone.ray.intersects_location(origins, dirs, multiple_hits=False)
    depth = np.full(len(origins), np.nan)
    depth[ray] = np.linalg.norm(loc - origins[ray], axis=1)
    names = np.array(shell.landmark_names)
    # the ray along the smoothed normal finds the bone at the table depth within 0.3 mm where the
    # smooth bone can follow the skin (measured 0.19). Exceptions, by design: the mid-philtrum and the
    # upper lip margin, 6 mm apart, pull against each other through the 6 mm bone smoothing (0.65, 0.52);
    # left out: the rhinion, where the bone leaves the nasal ridge for the membrane under the
    # cartilaginous nose (9 mm found for 3), and the menton (the bone rim under the chin is held at
    # the unsmoothed offset: 9 mm for 7.25)
    tolerance = {"mid_philtrum": 0.8, "labrale_superius": 0.8}
    left_out = {"rhinion", "menton"}
    ok = ~np.isin(names, list(left_out))
    tol = np.array([tolerance.get(n, 0.3) for n in names[ok]])
    assert np.all(np.abs(depth[ok] - shell.landmark_depths[ok]) < tol), dict(zip(names[ok], depth[ok]))
    assert ok.sum() >= 30
    # the bone keeps the minimum tissue from the skin everywhere except next to the nose, whose
    # nostril passages (in the ICT scan) reach deep into the head past the membrane the bone follows
    d2, face, closest = igl.point_mesh_squared_distance(shell.bone, S, shell.skin_faces)
    lm = anatomy_landmarks(load_ict_sample().mesh)
    nose = nose_footprint(S, lm)
    by_nose = nose[shell.skin_faces[face]].any(axis=1)
    nose = nose | by_nose
    assert by_nose.mean() < 0.2
    assert np.sqrt(d2[~by_nose]).min() > MIN_TISSUE_MM - 0.01
    # and the tissue is on its skin side: 0.5 mm from the bone towards the skin lies inside the closed
    # surface (generalised winding number ~1), away from the openings' walls (3 vertex rings) and the nose
    near_wall = _rings_from_boundary(shell.skin_faces, S.shape[0], 3)
    near_nose = _dilate(shell.skin_faces, nose, 3)  # the alae overhang the nostril passages too
    checked = ~near_wall & ~near_nose
    assert checked.mean() > 0.5  # measured 0.6 on the ICT face
    w = igl.winding_number(shell.V, shell.F, shell.bone[checked] + 0.5 * shell.normals[checked])
    assert np.all(w > 0.5)


def _rings_from_boundary(F, n, rings):
    near = np.zeros(n, dtype=bool)
    near[np.concatenate(igl.boundary_loop_all(F))] = True
    return _dilate(F, near, rings)


def _dilate(F, mask, rings):
    import scipy.sparse as sp

    n = mask.size
    near = mask.copy()
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    A = sp.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(n, n)).tocsr()
    A = A + A.T
    for _ in range(rings):
        near = near | ((A @ near.astype(float)) > 0)
    return near


def nose_footprint(S, lm):
    from facecap.anatomy.soft_tissue_shell import _nose_footprint

    return _nose_footprint(S, lm, behind_alae=False) | _nose_footprint(S, lm, behind_alae=True)


def test_tetrahedra_are_positive_and_fill_the_meshed_volume(shell, tets) -> None:
    tets, _ = tets
    X, T = tets.X, tets.T
    assert X.dtype == np.float64 and T.dtype == np.int64 and T.shape[1] == 4
    vol = tet_volumes(X, T)
    assert vol.min() > 0
    q = tet_quality(X, T)
    assert q.n_inverted == 0 and q.min_dihedral_deg > 1.0
    assert 0.5 * TEST_TETS < T.shape[0] < 3 * TEST_TETS
    meshed = trimesh.Trimesh(tets.surface_V, tets.surface_F, process=False)
    assert meshed.is_watertight
    # fTetWild keeps the boundary within its envelope of the surface: the volumes differ by at most
    # area x envelope (a shell of that thickness round the surface)
    assert abs(vol.sum() - meshed.volume) <= meshed.area * ENVELOPE_MM
    # measured: within 0.3 % (the bound above allows 11 %)
    assert abs(vol.sum() - meshed.volume) < 0.01 * meshed.volume
    # the edge-collapse decimation for a coarse mesh shrinks convex parts a little (measured 4.5 %
    # at this setting; none at the default, where the surface is meshed as it is)
    full = trimesh.Trimesh(shell.V, shell.F, process=False).volume
    assert 0.0 <= full - meshed.volume < 0.06 * full
    # every node is used and lies inside the envelope's reach of the surface
    assert np.unique(T).size == X.shape[0]
    lo, hi = shell.V.min(axis=0) - ENVELOPE_MM, shell.V.max(axis=0) + ENVELOPE_MM
    assert np.all((X >= lo) & (X <= hi))


def test_too_few_tets_or_an_open_surface_is_refused(shell) -> None:
    with pytest.raises(InputError, match="n_tets"):
        tetrahedralize_shell(shell.V, shell.F, n_tets=10)
    with pytest.raises(InputError, match="not closed"):
        tetrahedralize_shell(shell.V, shell.F[shell.part != PART_BONE], n_tets=1000)

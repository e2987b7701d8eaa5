"""soft_tissue_shell on the bundled ICT face: bone inside the skin at the table depths, one closed outward surface."""

from __future__ import annotations

import igl
import numpy as np
import pytest
import trimesh

from facecap.anatomy import MIN_TISSUE_MM, PART_SKIN, anatomy_landmarks, soft_tissue_shell
from facecap.errors import MeshError
from facecap.structures import Mesh
from facecap.io.ict_sample import load_ict_sample


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


def test_a_scan_inside_out_is_refused() -> None:
    full = load_ict_sample().mesh
    lm = anatomy_landmarks(full)
    # the whole face with its triangles turned inside out: refused, not a bone outside the face
    flipped = Mesh(vertices=full.vertices, faces=full.faces[:, ::-1])
    with pytest.raises(MeshError, match="face into the head"):
        soft_tissue_shell(flipped, lm)

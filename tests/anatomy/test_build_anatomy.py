"""build_anatomy on the bundled ICT face at a coarse setting: skin embedding, tetrahedra, bone nodes, jaw cut, condyles."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from facecap.anatomy import (
    JAW_GAP_MM,
    anatomy_landmarks,
    build_anatomy,
    in_jaw_gap,
    is_mandible,
    jaw_joint,
    tet_volumes,
)
from facecap.errors import InputError
from facecap.io.ict_sample import load_ict_sample


def test_skin_embedding_reproduces_every_scan_vertex(anatomy) -> None:
    scan = load_ict_sample().mesh.vertices
    assert anatomy.skin_tets.shape == (scan.shape[0],) and anatomy.skin_weights.shape == (scan.shape[0], 4)
    assert np.abs(anatomy.skin_positions() - scan).max() < 1e-9
    assert np.abs(anatomy.skin_matrix() @ anatomy.nodes - scan).max() < 1e-9
    assert np.allclose(anatomy.skin_weights.sum(axis=1), 1.0, atol=1e-12)
    # the skin moves with the mesh: a rigid motion of the nodes moves the skin rigidly
    c, s = np.cos(0.3), np.sin(0.3)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    moved = anatomy.skin_positions(anatomy.nodes @ R.T + [1.0, 2.0, 3.0])
    assert np.abs(moved - (scan @ R.T + [1.0, 2.0, 3.0])).max() < 1e-9
    # the meshed face region is the face in front of the ears, well inside the scan
    assert 0.5 < anatomy.skin_meshed.mean() < 0.9


def test_tetrahedra_are_positively_oriented(anatomy) -> None:
    assert anatomy.nodes.dtype == np.float64 and anatomy.tets.dtype == np.int64
    assert tet_volumes(anatomy.nodes, anatomy.tets).min() > 0
    assert anatomy.provenance["quality"]["n_inverted"] == 0


def test_bone_nodes_are_split_by_the_jaw_cut(anatomy) -> None:
    cran, mand = anatomy.cranium_nodes, anatomy.mandible_nodes
    assert cran.size > 50 and mand.size > 20
    assert np.intersect1d(cran, mand).size == 0 and np.intersect1d(cran, anatomy.rim_nodes).size == 0
    joint = jaw_joint(anatomy_landmarks(load_ict_sample().mesh))
    assert is_mandible(anatomy.nodes[mand], joint).all() and not is_mandible(anatomy.nodes[cran], joint).any()
    # Dirichlet nodes are on the bone surface: close to it, and at least the minimum tissue from the skin
    d_bone, _ = cKDTree(anatomy.bone_vertices).query(anatomy.nodes[np.concatenate([cran, mand])])
    assert np.median(d_bone) < 3.0
    d_skin, _ = cKDTree(anatomy.scan_vertices[anatomy.skin_meshed]).query(anatomy.nodes[cran])
    assert np.median(d_skin) > 3.0
    # the chin's bone is mandible, the forehead's is cranium
    p = dict(zip(anatomy.landmark_names, anatomy.landmark_points))
    _, near_chin = cKDTree(anatomy.nodes[np.concatenate([cran, mand])]).query(p["pogonion"] - [0, 0, 11.25])
    assert near_chin >= cran.size
    _, near_brow = cKDTree(anatomy.nodes[np.concatenate([cran, mand])]).query(p["glabella"] - [0, 0, 5.25])
    assert near_brow < cran.size


def test_the_bone_along_the_jaw_cut_holds_to_neither_jaw(anatomy) -> None:
    # Flesh glued to the cranium on one side of the cut and to the mandible a few mm away on the
    # other was crushed when the jaw moved (inverted elements at the mouth's corners on a 22k model):
    # no bone node within JAW_GAP_MM of the cut, measured here independently of in_jaw_gap
    joint = jaw_joint(anatomy_landmarks(load_ict_sample().mesh))
    bone = np.concatenate([anatomy.cranium_nodes, anatomy.mandible_nodes])
    local = (anatomy.nodes - joint.origin) @ joint.frame.T
    z, y = local[:, 2], local[:, 1]
    # the cut's occlusal segment, stomion backwards to the ramus front: vertical offset from it
    front = (z >= joint.cut_z[1]) & (z <= joint.cut_z[2])
    height = np.abs(y - np.interp(z, joint.cut_z, joint.cut_y))
    slope = np.diff(joint.cut_y[1:]) / np.diff(joint.cut_z[1:])
    across = height / np.sqrt(1.0 + slope[0] ** 2)  # distance to the straight segment
    assert np.all(across[bone][front[bone]] >= JAW_GAP_MM - 1e-9)
    # the band is real: boundary nodes on the bone there exist and are free (not rim, not bone)
    from facecap.anatomy.build_anatomy import boundary_nodes

    surface = boundary_nodes(anatomy.tets)
    in_band = surface[front[surface] & (across[surface] < JAW_GAP_MM)]
    d_bone, _ = cKDTree(anatomy.bone_vertices).query(anatomy.nodes[in_band])
    freed = in_band[d_bone < 1.0]
    assert freed.size >= 5
    assert np.intersect1d(freed, np.concatenate([bone, anatomy.rim_nodes])).size == 0
    assert in_jaw_gap(anatomy.nodes[freed], joint).all() and not in_jaw_gap(anatomy.nodes[bone], joint).any()
    assert anatomy.provenance["jaw_gap_mm"] == JAW_GAP_MM


def test_condyles_are_in_front_of_the_ears(anatomy) -> None:
    left, right = anatomy.condyles
    p = dict(zip(anatomy.landmark_names, anatomy.landmark_points))
    for c, side in ((left, "L"), (right, "R")):
        assert abs(c[0]) < abs(p[f"supraglenoid_{side}"][0])  # medial of the skin
        assert p[f"gonion_{side}"][1] < c[1] < p[f"supraorbital_{side}"][1]


def test_bad_input_is_refused() -> None:
    with pytest.raises(InputError, match="n_tets"):
        build_anatomy(load_ict_sample().mesh, n_tets=5, progress=False)
    with pytest.raises(InputError, match="Mesh"):
        build_anatomy(np.zeros((3, 3)), progress=False)

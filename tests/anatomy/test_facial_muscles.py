"""facial_muscles: an analytic straight tube in a box of tissue, and the 36 muscles of the bundled ICT face's model."""

from __future__ import annotations

import numpy as np
import pytest

from anatomy_meshes import box_tets as _box_tets, grid_mesh as _grid_mesh
from facecap.anatomy import MUSCLE_NAMES, AnatomyLandmarks, MuscleSpec, facial_muscles, tet_volumes


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


def test_muscles_sit_between_their_origin_and_insertion(anatomy) -> None:
    assert anatomy.muscle_names == MUSCLE_NAMES and len(MUSCLE_NAMES) >= 30
    f, fib = anatomy.muscle_fractions, anatomy.muscle_fibres
    assert f.shape == (anatomy.n_tets, anatomy.n_muscles) and fib.shape == (anatomy.n_tets, anatomy.n_muscles, 3)
    assert f.min() >= 0.0 and f.max() <= 1.0
    used = f > 0
    assert np.allclose(np.linalg.norm(fib[used], axis=1), 1.0)
    assert np.all(fib[~used] == 0)
    centroids = anatomy.nodes[anatomy.tets].mean(axis=1)
    from scipy.spatial import cKDTree

    tree = cKDTree(centroids)
    for k, name in enumerate(anatomy.muscle_names):
        curve = anatomy.muscle_curves[k]
        assert used[:, k].sum() > 0, name
        # nonzero near the origin and the insertion (within the tube plus a tetrahedron's reach)
        reach = 0.5 * max(anatomy.muscle_widths_mm[k], anatomy.muscle_thicknesses_mm[k]) + 8.0
        for end in (curve[0], curve[-1]):
            near = tree.query_ball_point(end, reach)
            assert f[near, k].max() > 0, name
        # zero far from the centre curve
        d, _ = cKDTree(curve).query(centroids)
        assert np.all(f[d > reach + 6.0, k] == 0), name
    # straight muscles: the fibres follow the origin-to-insertion direction
    for name in ("zygomaticus_major_L", "zygomaticus_major_R", "frontalis_L", "risorius_R", "depressor_anguli_oris_L"):
        k = anatomy.muscle_names.index(name)
        c = anatomy.muscle_curves[k]
        axis = (c[-1] - c[0]) / np.linalg.norm(c[-1] - c[0])
        weights = f[:, k]
        mean_cos = float((weights * (fib[:, k] @ axis)).sum() / weights.sum())
        assert mean_cos > 0.9, name
    # rings: fibres run round the ring, across the direction to its centre
    k = anatomy.muscle_names.index("orbicularis_oris")
    centre = anatomy.muscle_curves[k].mean(axis=0)
    inside = used[:, k]
    radial = centroids[inside] - centre
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    assert np.median(np.abs(np.einsum("ij,ij->i", radial, fib[inside, k]))) < 0.4

"""Markers placed on the template from the bases' material: a known place recovered through deformed bases."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.io.ict_sample import load_ict_sample
from facecap.registration.marker_places_from_bases import marker_places_from_bases


def test_known_places_come_back_through_deformed_bases_and_one_slid_basis_is_outvoted():
    face = load_ict_sample().mesh
    V, F = face.vertices, face.faces
    rng = np.random.default_rng(0)
    tri = rng.choice(F.shape[0], 40, replace=False)
    w = rng.dirichlet(np.ones(3), 40)
    places = np.einsum("mj,mjc->mc", w, V[F[tri]])
    bases, skins = [], []
    for k in range(5):  # each basis the template under its own smooth deformation
        bump = 2.0 * np.sin(V[:, :1] / (20.0 + 5 * k)) * np.array([0.3, 1.0, 0.2])
        B = V + bump
        bases.append(B)
        skins.append(np.einsum("mj,mjc->mc", w, B[F[tri]]))
    skins = np.stack(skins)
    skins[4] += np.array([0.0, 3.0, 0.0])  # one basis slid 3 mm: the median outvotes it
    landed = np.ones(skins.shape[:2], dtype=bool)
    landed[:, 0] = False  # a marker no scan showed: not placed
    out = marker_places_from_bases(np.stack(bases), F, V, skins, landed)
    assert not out.found[0] and np.all(out.found[1:])
    error = np.linalg.norm(out.points[1:] - places[1:], axis=1)
    assert np.median(error) < 0.05 and error.max() < 0.5, (np.median(error), error.max())
    assert np.allclose(out.weights[1:].sum(axis=1), 1.0)
    moved = out.moved_mm(V, F[tri], w)
    assert np.isnan(moved[0]) and np.allclose(moved[1:], error)


def test_shapes_are_checked():
    face = load_ict_sample().mesh
    with pytest.raises(InputError, match="skin_points"):
        marker_places_from_bases(face.vertices[None], face.faces, face.vertices, np.zeros((2, 3, 3)),
                                 np.ones((2, 3), bool))

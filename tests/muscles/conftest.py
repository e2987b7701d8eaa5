"""The small model (``anatomy`` of tests/conftest.py: the bundled ICT face at ~4k tetrahedra) and a marker layout,
shared by the muscle tests."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pytest

from facecap.anatomy import FaceAnatomy
from facecap.muscles import MuscleModel
from facecap.synth import choose_marker_vertices

N_MARKERS = 120


class Layout(NamedTuple):
    marker_vertices: np.ndarray
    rest_markers: np.ndarray


@pytest.fixture(scope="session")
def model(anatomy: FaceAnatomy) -> MuscleModel:
    return MuscleModel(anatomy)


@pytest.fixture(scope="session")
def layout(anatomy: FaceAnatomy, model: MuscleModel) -> Layout:
    """120 markers, denser where the muscles and the jaw move the skin (as real layouts are round the mouth).

    Each marker sits 1.5 mm above the skin along the vertex normal, so the rest offsets are real.
    """
    model.equilibrium(np.zeros(model.n_muscles), np.eye(3, 4))
    dXa, dXb = model.jacobians()
    rest_skin = model.skin(model.rest_positions)
    deltas = np.stack([model.skin(model.rest_positions + d) - rest_skin for d in np.concatenate([dXa, 0.2 * dXb[:9]])])
    usable = anatomy.skin_meshed & model.skin_follows
    vertices = choose_marker_vertices(anatomy.scan_vertices, anatomy.scan_faces, deltas, N_MARKERS, exclude=~usable)
    V, F = anatomy.scan_vertices, anatomy.scan_faces
    normals = np.zeros_like(V)
    face_normals = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    for corner in range(3):
        np.add.at(normals, F[:, corner], face_normals)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return Layout(vertices, V[vertices] + 1.5 * normals[vertices])

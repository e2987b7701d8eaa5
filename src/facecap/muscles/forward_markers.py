"""The forward model: markers from known controls (what :class:`MuscleSolver` inverts)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..errors import InputError
from ..fem import QuasistaticResult
from ..typing import FloatArray
from .marker_embedding import MarkerEmbedding
from .muscle_controls import MuscleControls
from .muscle_model import MuscleModel, apply_affine

__all__ = ["ForwardMarkers", "forward_markers"]


class ForwardMarkers(NamedTuple):
    """The face under one set of controls.

    Attributes
    ----------
    markers : (M, 3) float64 array, mm
        Model markers in world coordinates (noise added if asked).
    nodes : (N, 3) float64 array, mm
        Equilibrium node positions, world.
    skin : (n_scan, 3) float64 array, mm
        The scan's vertices, world.
    result : QuasistaticResult
        The solve in the cranium's frame (converged, iterations, inverted tetrahedra, ...).
    """

    markers: FloatArray
    nodes: FloatArray
    skin: FloatArray
    result: QuasistaticResult


def forward_markers(model: MuscleModel, embedding: MarkerEmbedding, controls: MuscleControls, *,
                    x0: FloatArray | None = None, noise_mm: float = 0.0,
                    seed: int | None = None) -> ForwardMarkers:
    """Solve the face under ``controls`` and read its markers.

    Parameters
    ----------
    model : MuscleModel
    embedding : MarkerEmbedding
    controls : MuscleControls
    x0 : (N, 3) float64 array, mm, optional
        Initial guess of the nodes in the cranium's frame (default rest).
    noise_mm : float, default 0
        Standard deviation of Gaussian noise added to each marker coordinate.
    seed : int, optional
        Seed of the noise.

    Returns
    -------
    ForwardMarkers

    Notes
    -----
    ``markers = A_c(W X(a, b_m) + offsets)``, ``A_c`` the cranium's affine map and ``X`` the
    equilibrium in the cranium's frame (:meth:`MuscleModel.equilibrium`).
    """
    if not isinstance(controls, MuscleControls) or controls.n_muscles != model.n_muscles:
        raise InputError(f"controls: expected MuscleControls with {model.n_muscles} activations")
    if not (np.isfinite(noise_mm) and noise_mm >= 0):
        raise InputError(f"noise_mm: expected a finite value >= 0, got {noise_mm!r}")
    result = model.equilibrium(controls.activations, controls.mandible, x0=x0)
    x = result.positions
    markers = apply_affine(controls.cranium, embedding.matrix @ x + embedding.offsets)
    if noise_mm > 0:
        markers = markers + np.random.default_rng(seed).normal(0.0, noise_mm, markers.shape)
    return ForwardMarkers(markers, apply_affine(controls.cranium, x),
                          apply_affine(controls.cranium, model.skin(x)), result)

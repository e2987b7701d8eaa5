"""The jaw opening of a blendshape face as a rotation, not a straight line.

ICT's ``jawOpen`` at full weight moves the lower teeth by a rigid rotation of about 25 degrees
(to 0.3 % of their displacement). A linear blendshape reaches it along straight lines, so at
half weight the jaw is the chord of that rotation: shortened by ``1 - cos(12.5 deg)``, 2.4 %,
about 2 mm at the chin. Real jaws do not shrink. A face model with a rigid mandible cannot follow
that, while a surface that interpolates markers can. Here the rotation part of each vertex's
displacement is taken along the arc instead, and the rest stays linear, so that full weight is
exactly ICT's shape again.

For a vertex at rest ``p`` with full-weight displacement ``d``, the jaw's screw motion ``J_w``
(the rotation by ``w theta`` about the fitted axis, plus ``w`` times the slide along it) gives the
rotational displacement ``r(w) = J_w(p) - p``. The vertex's share of it is
``alpha = clip(d . r(1) / |r(1)|^2, 0, 1)`` (0 where ``|r(1)|`` is under 0.5 mm), and its
displacement at weight ``w`` is ``alpha r(w) + w (d - alpha r(1))``: ``d`` at ``w = 1``,
zero at ``w = 0``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import InputError
from ..typing import FloatArray

__all__ = ["ICT_JAW_SCREW", "JawScrew", "JAW_MODES", "fit_jaw_screw", "rotational_jaw_correction"]

JAW_MODES = ("linear", "rotational")
"""``generate_performance(jaw=...)``: the blendshape's straight lines, or the jaw's arc."""

JAW_SHAPE = "jawOpen"
"""The expression whose displacement is taken along the jaw's arc."""

MIN_ROTATIONAL_MM = 0.5
"""Vertices whose full-weight rotational displacement is below this keep the linear blend."""


class JawScrew(NamedTuple):
    """The jaw's full-weight motion as a screw: rotation ``angle_rad`` about ``axis`` through
    ``centre``, then ``slide_mm`` along the axis."""

    axis: FloatArray
    angle_rad: float
    centre: FloatArray
    slide_mm: float

    def apply(self, points: FloatArray, weight: float | FloatArray) -> FloatArray:
        """``J_w(points)``: the motion at ``weight`` (a scalar, or one per leading row of ``points``)."""
        w = np.asarray(weight, dtype=np.float64)
        rot = Rotation.from_rotvec(np.multiply.outer(w, self.axis * self.angle_rad)).as_matrix()
        moved = np.einsum("...ij,...nj->...ni", rot, points - self.centre) + self.centre
        return moved + (w[..., None, None] if w.ndim else w) * self.slide_mm * self.axis


ICT_JAW_SCREW = JawScrew(axis=np.array([1.0, 0.0, 0.0]), angle_rad=float(np.deg2rad(25.334069)),
                         centre=np.array([0.0, -5.473287, 18.191076]), slide_mm=0.0)
"""ICT's ``jawOpen`` at full weight, in the bundled sample's frame (mm): :func:`fit_jaw_screw` of
the 2,204 lower-teeth vertices of the full ICT model (``../shared/data/ict_face``, vertices
17039-21450 that move more than 30 % of the most; 0.08 mm mean residual, 0.23 mm max), the generic
identity. ``python tools/fit_jaw_screw.py`` derives it again."""


def fit_jaw_screw(rest: FloatArray, moved: FloatArray) -> JawScrew:
    """The screw motion that best carries ``rest`` (n, 3) onto ``moved`` (n, 3) (Kabsch, then its axis)."""
    A, B = np.asarray(rest, dtype=np.float64), np.asarray(moved, dtype=np.float64)
    if A.shape != B.shape or A.ndim != 2 or A.shape[1] != 3 or A.shape[0] < 3:
        raise InputError(f"rest and moved: expected matching (n >= 3, 3) arrays, got {A.shape} and {B.shape}")
    a0, b0 = A.mean(axis=0), B.mean(axis=0)
    U, _, Vt = np.linalg.svd((A - a0).T @ (B - b0))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    t = b0 - R @ a0
    rotvec = Rotation.from_matrix(R).as_rotvec()
    angle = float(np.linalg.norm(rotvec))
    if angle < 1e-9:
        raise InputError("the jaw's motion has no rotation")
    axis = rotvec / angle
    slide = float(t @ axis)
    # a point on the axis: (I - R) c = t - slide * axis, solved in the plane normal to the axis
    centre = np.linalg.lstsq(np.eye(3) - R, t - slide * axis, rcond=None)[0]
    centre -= (centre - a0) @ axis * axis  # the axis point nearest the rest centroid
    return JawScrew(axis, angle, centre, slide)


def rotational_jaw_correction(rest: FloatArray, jaw_delta: FloatArray, weights: FloatArray,
                              screw: JawScrew) -> FloatArray:
    """What to add to a linear blend so that the jaw opens along its arc: (T, n, 3) mm.

    Parameters
    ----------
    rest : (n, 3) float array, mm
        The face at rest (the identity's neutral).
    jaw_delta : (n, 3) float array, mm
        The jaw-opening expression's full-weight displacement.
    weights : (T,) float array
        Its weight per frame.
    screw : JawScrew
        The jaw's full-weight motion (:func:`fit_jaw_screw`).

    Returns
    -------
    (T, n, 3) float64 array
        ``alpha (r(w) - w r(1))`` per vertex and frame (the module docstring); zero where the
        weight is 0 or 1.
    """
    P = np.asarray(rest, dtype=np.float64)
    d = np.asarray(jaw_delta, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    r1 = screw.apply(P, 1.0) - P
    size = np.einsum("ij,ij->i", r1, r1)
    alpha = np.where(size >= MIN_ROTATIONAL_MM**2,
                     np.clip(np.einsum("ij,ij->i", d, r1) / np.maximum(size, 1e-12), 0.0, 1.0), 0.0)
    out = np.zeros((w.size,) + P.shape)
    active = np.flatnonzero(w != 0)
    moving = alpha > 0
    if active.size and moving.any():
        arc = screw.apply(P[moving], w[active]) - P[moving]  # (a, m, 3)
        out[np.ix_(active, np.flatnonzero(moving))] = alpha[moving, None] * (arc - w[active, None, None] * r1[moving])
    return out

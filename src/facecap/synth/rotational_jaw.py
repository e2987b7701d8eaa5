"""The jaw opening of a blendshape face as a rotation, not a straight line.

ICT's ``jawOpen`` at full weight moves the lower teeth by a rigid rotation of about 25 degrees
(to 0.3 % of their displacement). A linear blendshape reaches it along straight lines, so at
half weight the jaw is the chord of that rotation: shortened by ``1 - cos(12.7 deg)``, 2.4 %,
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
from ..markers import rigid_fit
from ..typing import FloatArray
from ..validate import as_points

__all__ = ["ICT_JAW_SCREW", "JawScrew", "JAW_MODES", "fit_jaw_screw", "rotational_jaw_correction"]

JAW_MODES = ("linear", "rotational")
"""``generate_performance(jaw=...)``: the blendshape's straight lines, or the jaw's arc."""

JAW_SHAPE = "jawOpen"
"""The expression whose displacement is taken along the jaw's arc."""

MIN_ROTATIONAL_MM = 0.5
"""Vertices whose full-weight rotational displacement is below this keep the linear blend: near the
axis a vertex's share of the rotation is a ratio of two tiny numbers, and its arc differs from the
line by under 0.03 mm anyway."""


class JawScrew(NamedTuple):
    """The jaw's full-weight motion as a screw: a rotation about an axis, then a slide along it.

    Attributes
    ----------
    axis : (3,) float64 array
        Unit direction of the axis (the right-hand rule gives the rotation's sense).
    angle_rad : float
        Rotation at full weight, radians.
    centre : (3,) float64 array, mm
        A point of the axis.
    slide_mm : float
        Translation along the axis at full weight, mm.
    """

    axis: FloatArray
    angle_rad: float
    centre: FloatArray
    slide_mm: float

    def apply(self, points: FloatArray, weight: float | FloatArray) -> FloatArray:
        """``J_w(points)``: ``points`` (n, 3) mm moved by the motion at ``weight``.

        A scalar weight gives (n, 3); a (T,) array of weights (one per frame) gives (T, n, 3):
        the rotation by ``w angle_rad`` about the axis, then ``w slide_mm`` along it.

        Examples
        --------
        >>> import numpy as np
        >>> quarter = JawScrew(np.array([0.0, 0.0, 1.0]), np.pi / 2, np.zeros(3), 1.0)
        >>> quarter.apply(np.array([[1.0, 0.0, 0.0]]), 1.0).round(6).tolist()
        [[0.0, 1.0, 1.0]]
        """
        w = np.asarray(weight, dtype=np.float64)
        rot = Rotation.from_rotvec(np.multiply.outer(w, self.axis * self.angle_rad)).as_matrix()
        moved = np.einsum("...ij,...nj->...ni", rot, points - self.centre) + self.centre
        return moved + (w[..., None, None] if w.ndim else w) * self.slide_mm * self.axis


def _read_only(screw: JawScrew) -> JawScrew:
    for a in (screw.axis, screw.centre):
        a.setflags(write=False)
    return screw


ICT_JAW_SCREW = _read_only(JawScrew(axis=np.array([1.0, 0.0, 0.0]), angle_rad=float(np.deg2rad(25.334069)),
                                    centre=np.array([0.0, -5.473287, 18.191076]), slide_mm=0.0))
"""ICT's ``jawOpen`` at full weight, in the bundled sample's frame (mm): :func:`fit_jaw_screw` of
the 2,204 lower-teeth vertices of the full ICT model (``../shared/data/ict_face``, vertices
17039-21450 that move more than 30 % of the most; 0.08 mm mean residual, 0.23 mm max), the generic
identity. ``python tools/fit_jaw_screw.py`` derives it again. Other identities use it too: their
jaws differ by a few mm, which moves the half-weight correction by about 0.1 mm."""


def fit_jaw_screw(rest: FloatArray, moved: FloatArray) -> JawScrew:
    """The screw motion that best carries ``rest`` onto ``moved``.

    Parameters
    ----------
    rest, moved : (n, 3) float array, mm
        The same points before and after the motion (n >= 3, not collinear).

    Returns
    -------
    JawScrew
        The least-squares rigid motion (:func:`facecap.markers.rigid_fit`) written as a screw: its
        rotation vector gives the axis and angle, its translation's component along the axis the
        slide, and the rest a point of the axis (the one nearest the points' centroid).

    Raises
    ------
    InputError
        Arrays of the wrong shape or not finite, too few or collinear points, or a motion without
        rotation.

    Examples
    --------
    >>> import numpy as np
    >>> quarter = JawScrew(np.array([0.0, 0.0, 1.0]), np.pi / 2, np.array([5.0, 0.0, 0.0]), 2.0)
    >>> P = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> fit = fit_jaw_screw(P, quarter.apply(P, 1.0))
    >>> round(float(np.degrees(fit.angle_rad)), 6), round(fit.slide_mm, 6), (fit.centre.round(6) + 0.0).tolist()
    (90.0, 2.0, [5.0, 0.0, 0.25])
    """
    A = as_points(rest, name="rest")
    B = as_points(moved, name="moved")
    if A.shape != B.shape or A.shape[0] < 3:
        raise InputError(f"rest and moved: expected matching (n >= 3, 3) arrays, got {A.shape} and {B.shape}")
    fit = rigid_fit(A, B)
    R, t = np.asarray(fit.rotation), np.asarray(fit.translation)
    if not np.all(np.isfinite(R)):
        raise InputError("rest: the points are too few or collinear to fix a rotation")
    rotvec = Rotation.from_matrix(R).as_rotvec()
    angle = float(np.linalg.norm(rotvec))
    if angle < 1e-9:
        raise InputError("the motion has no rotation: it is not a jaw opening")
    axis = rotvec / angle
    slide = float(t @ axis)
    # (I - R) c = t - slide * axis has a line of solutions (the axis); lstsq gives the one in the
    # plane through the origin, then it moves along the axis to the point nearest the centroid
    centre = np.linalg.lstsq(np.eye(3) - R, t - slide * axis, rcond=None)[0]
    centre += (A.mean(axis=0) - centre) @ axis * axis
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
    P = as_points(rest, name="rest")
    d = as_points(jaw_delta, name="jaw_delta")
    w = np.asarray(weights, dtype=np.float64)
    if d.shape != P.shape:
        raise InputError(f"jaw_delta: expected shape {P.shape} like rest, got {d.shape}")
    if w.ndim != 1 or not np.all(np.isfinite(w)):
        raise InputError(f"weights: expected a finite (T,) array, got shape {w.shape}")
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

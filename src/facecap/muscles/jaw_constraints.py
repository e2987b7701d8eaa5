"""The temporomandibular joint as constraints psi1-psi6 on the mandible's frame (Sifakis et al. 2005, sec. 8)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from ..errors import InputError
from ..rotations import nearest_rotation
from ..typing import FloatArray

__all__ = ["JawConstraints"]

DEFAULT_TRACK_LENGTH_MM = 15.0
"""How far each condyle may slide forward along its track, mm."""
DEFAULT_MAX_OPENING_DEG = 35.0
"""Largest opening rotation of the mandible about the condylar axis."""
DEFAULT_TRACK_SLOPE_DEG = 30.0
"""Tracks point forward and this much down from the face frame's horizontal (the articular eminence)."""


@dataclass(frozen=True, eq=False)
class JawConstraints:
    """The jaw's joint: two parallel condyle tracks and a bounded opening angle.

    All vectors live in the cranium's frame (the rest, scan coordinates), so they apply to
    the mandible transform ``[M_m | t_m]`` relative to the cranium.

    Attributes
    ----------
    u : (3,) float64 array
        Unit vector from the right to the left condyle (the hinge axis at rest).
    v : (3,) float64 array
        Unit direction of the sliding tracks, back to front, orthogonal to ``u``.
    w : (3,) float64 array
        ``v x u`` (up, roughly).
    midpoint : (3,) float64 array, mm
        ``m``, the rest midpoint of the condyles.
    condyle_distance_mm : float
        ``l``, the distance between the condyles.
    track_length_mm : float
        ``d``: each condyle slides in ``[0, d]`` along ``v``.
    max_opening_rad : float
        The opening angle is in ``[0, max_opening_rad]``; ``s = sin(max_opening_rad)``.

    Notes
    -----
    With ``b = (M_m, t_m)`` (Sifakis et al. 2005, sec. 8):

    - ``psi1 = w^T M_m u = 0`` (the hinge stays parallel to the tracks' plane),
    - ``psi2 = w^T (M_m m + t_m - m) = 0`` (the condyles' midpoint stays on it),
    - ``psi3 = u^T (M_m m + t_m - m) = 0`` (midway between the tracks),
    - ``psi4 = v^T (M_m (m - l/2 u) + t_m - m)`` in ``[0, d]`` (right condyle on its track),
    - ``psi5 = v^T (M_m (m + l/2 u) + t_m - m)`` in ``[0, d]`` (left condyle),
    - ``psi6 = w^T M_m v`` in ``[-s, 0]`` (the opening angle).

    Every ``psi_i`` is affine in ``b``: :meth:`linear_terms` gives ``psi = G b + g0``.
    :meth:`transform` builds a rigid ``b`` that meets psi1-psi3 exactly from an opening
    angle and the two slides; :meth:`pose` reads them back.

    Examples
    --------
    >>> jaw = JawConstraints(np.array([1.0, 0, 0]), np.array([0.0, 0, 1]), np.array([0.0, 40, -60]), 100.0)
    >>> b = jaw.transform(0.3, 2.0, 1.0)
    >>> bool(np.allclose(jaw.pose(b), [0.3, 2.0, 1.0])), float(np.abs(jaw.values(b)[:3]).max()) < 1e-12
    (True, True)
    """

    u: FloatArray
    v: FloatArray
    midpoint: FloatArray
    condyle_distance_mm: float
    track_length_mm: float = DEFAULT_TRACK_LENGTH_MM
    max_opening_rad: float = float(np.radians(DEFAULT_MAX_OPENING_DEG))

    def __post_init__(self) -> None:
        u = np.asarray(self.u, dtype=np.float64).reshape(3)
        v = np.asarray(self.v, dtype=np.float64).reshape(3)
        m = np.asarray(self.midpoint, dtype=np.float64).reshape(3)
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(v)) and np.all(np.isfinite(m))):
            raise InputError("jaw constraints: u, v and midpoint must be finite")
        u = u / np.linalg.norm(u)
        v = v - (v @ u) * u
        if np.linalg.norm(v) < 1e-9:
            raise InputError("jaw constraints: the track direction v is parallel to the condylar axis u")
        v = v / np.linalg.norm(v)
        for name, value, hi in (("condyle_distance_mm", self.condyle_distance_mm, np.inf),
                                ("track_length_mm", self.track_length_mm, np.inf),
                                ("max_opening_rad", self.max_opening_rad, np.pi / 2)):
            if not (np.isfinite(value) and 0 < value < hi):
                raise InputError(f"jaw constraints: {name} must be positive (and below {hi}), got {value!r}")
        object.__setattr__(self, "u", u)
        object.__setattr__(self, "v", v)
        object.__setattr__(self, "midpoint", m)

    @property
    def w(self) -> FloatArray:
        """``v x u``."""
        return np.cross(self.v, self.u)

    @classmethod
    def from_anatomy(cls, anatomy: Any, *, track_length_mm: float = DEFAULT_TRACK_LENGTH_MM,
                     max_opening_deg: float = DEFAULT_MAX_OPENING_DEG,
                     track_slope_deg: float = DEFAULT_TRACK_SLOPE_DEG) -> JawConstraints:
        """The joint of a :class:`~facecap.anatomy.FaceAnatomy`: its condyles and face frame.

        Parameters
        ----------
        anatomy : FaceAnatomy
        track_length_mm : float, default 15
            Forward travel of each condyle.
        max_opening_deg : float, default 35
        track_slope_deg : float, default 30
            The tracks run forward and this many degrees down (the articular eminence).
        """
        from ..anatomy import face_frame

        left, right = np.asarray(anatomy.condyles, dtype=np.float64)
        frame = face_frame(dict(zip(anatomy.landmark_names, anatomy.landmark_points)))
        u = left - right
        slope = np.radians(float(track_slope_deg))
        v = np.cos(slope) * frame[2] - np.sin(slope) * frame[1]
        return cls(u, v, 0.5 * (left + right), float(np.linalg.norm(u)), float(track_length_mm),
                   float(np.radians(max_opening_deg)))

    @cached_property
    def affine_terms(self) -> tuple[FloatArray, FloatArray]:
        """:meth:`linear_terms`, computed once."""
        return self.linear_terms()

    def linear_terms(self) -> tuple[FloatArray, FloatArray]:
        """``G (6, 12)`` and ``g0 (6,)`` with ``psi = G [vec(M_m), t_m] + g0`` (``vec`` row-major)."""
        u, v, w, m, half = self.u, self.v, self.w, self.midpoint, 0.5 * self.condyle_distance_mm
        G = np.zeros((6, 12))
        g0 = np.zeros(6)
        rows = [(w, u, None), (w, m, w), (u, m, u), (v, m - half * u, v), (v, m + half * u, v), (w, v, None)]
        for i, (left, right, translation) in enumerate(rows):
            G[i, :9] = np.outer(left, right).ravel()
            if translation is not None:
                G[i, 9:] = translation
                g0[i] = -translation @ m
        return G, g0

    def values(self, mandible: Any) -> FloatArray:
        """``psi1 .. psi6`` of a mandible transform ``(3, 4)`` (mm for psi2-psi5)."""
        b = np.asarray(mandible, dtype=np.float64)
        G, g0 = self.affine_terms
        return G @ np.concatenate([b[:, :3].ravel(), b[:, 3]]) + g0

    def violations(self, mandible: Any) -> FloatArray:
        """How far each of psi1-psi6 is outside its allowed set, (6,) (0 where met)."""
        p = self.values(mandible)
        d, s = self.track_length_mm, np.sin(self.max_opening_rad)
        out = np.abs(p)
        for i, (lo, hi) in ((3, (0.0, d)), (4, (0.0, d)), (5, (-s, 0.0))):
            out[i] = max(lo - p[i], p[i] - hi, 0.0)
        return out

    def transform(self, opening_rad: float, slide_left_mm: float = 0.0, slide_right_mm: float = 0.0) -> FloatArray:
        """The rigid mandible transform ``(3, 4)`` of an opening angle and two condyle slides.

        The mandible turns by ``opening_rad`` about the condylar axis (chin down for a positive
        angle), then about ``w`` by ``asin((slide_right - slide_left) / l)``, and its condyle
        midpoint moves by the mean slide along ``v``: psi1-psi3 hold exactly, psi4 and psi5 are
        the two slides and psi6 is ``-sin(opening_rad)``. Limits are not checked here
        (:meth:`violations` does).
        """
        u, v, w, m = self.u, self.v, self.w, self.midpoint
        yaw_sine = (float(slide_right_mm) - float(slide_left_mm)) / self.condyle_distance_mm
        if abs(yaw_sine) >= 1.0:
            raise InputError("jaw: the two slides differ by more than the condyle distance")
        R = _rotation(w, np.arcsin(yaw_sine)) @ _rotation(u, float(opening_rad))
        t = m + 0.5 * (float(slide_left_mm) + float(slide_right_mm)) * v - R @ m
        return np.hstack([R, t[:, None]])

    def pose(self, mandible: Any) -> FloatArray:
        """``(opening_rad, slide_left_mm, slide_right_mm)`` of a mandible transform (inverse of :meth:`transform`)."""
        b = np.asarray(mandible, dtype=np.float64)
        R = nearest_rotation(b[:, :3])
        p = self.values(b)
        # the opening is the angle of R v in the (v, -w) plane after the yaw is taken out
        Rv = R @ self.v
        opening = float(np.arctan2(-(self.w @ Rv), np.hypot(self.v @ Rv, self.u @ Rv)))
        return np.array([opening, p[4], p[3]])


def _rotation(axis: FloatArray, angle: float) -> FloatArray:
    """Rotation by ``angle`` about the unit ``axis`` (right hand)."""
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * (K @ K)

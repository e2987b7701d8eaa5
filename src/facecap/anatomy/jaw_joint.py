"""The jaw: temporomandibular joint (condyle) positions and the cut between cranium and mandible.

Both come from the skin landmarks in the face frame (x left, y up, z forward):

- each condyle lies at the height of the Frankfort horizontal (the orbitale,
  taken at the suborbital landmark), at the face contour just in front of the
  ear at that height, 18 mm medial of the skin (8.5 mm of tissue over the
  supraglenoid region plus half a condyle's width);
- the mandible is what lies below a cut in the sagittal (z, y) plane: the
  occlusal plane from the stomion (mouth slit), rising 8.5 degrees backwards
  to the front of the ramus (10 mm in front of the gonion), then straight up
  the ramus to 5 mm below the condyle (the condylar neck), and level behind it;
- the bone within 6 mm of that cut is neither: the crowns of the teeth and the gap
  between them, over which the lips and cheeks lie unattached, and the sigmoid
  notch and joint between the ramus and the skull.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..typing import FloatArray
from .anatomy_landmarks import AnatomyLandmarks

__all__ = ["JawJoint", "jaw_joint", "is_mandible", "in_jaw_gap", "JAW_GAP_MM"]

CONDYLE_DEPTH_MM = 18.0
"""Condyle centre medial of the skin contour in front of the ear."""
OCCLUSAL_TILT_DEG = 8.5
"""Rise of the occlusal plane backwards from the stomion, relative to the face frame's horizontal."""
RAMUS_FRONT_AHEAD_OF_GONION_MM = 10.0
CONDYLAR_NECK_MM = 5.0
JAW_GAP_MM = 6.0
"""Half-width of the band along the cranium-mandible cut whose bone nodes hold to neither bone.

The model's bone is one membrane under the skin, cut in two, so without the band the flesh was
glued to the cranium just on one side of the cut and to the mandible just on the other, a few
millimetres apart. Opening the jaw or sliding a condyle then crushed the tetrahedra between the
two: on a 22k-tetrahedron model of the ICT face one to three inverted, with no muscle active,
at the corners of the mouth (11.5-25 degrees of opening, a 6-12 mm condyle slide) and beside
the condylar neck (a 10-12 mm slide). In a real face nothing there is bound to both: the lips
and cheeks lie over the teeth's crowns (8-10 mm high) and the gap between the dental arches,
attached higher and lower at the vestibule's fold, and between the ramus and the skull are the
sigmoid notch and the joint, bridged by muscle. With a 6 mm band (12 mm of freed bone across
the cut) none of those poses inverts an element.
"""


class JawJoint(NamedTuple):
    """The jaw's joint and the cranium-mandible cut.

    Attributes
    ----------
    condyles : (2, 3) float64 array, mm
        Left and right condyle centres (the temporomandibular joints), scan coordinates.
    cut_z, cut_y : (3,) float64 arrays, mm
        Face-frame polyline of the cut: points below ``y = interp(z, cut_z, cut_y)``
        (level beyond the ends) belong to the mandible. ``cut_z`` increases.
    frame : (3, 3) float64 array
        Face frame rows (left, up, forward).
    origin : (3,) float64 array, mm
        Face frame origin.
    """

    condyles: FloatArray
    cut_z: FloatArray
    cut_y: FloatArray
    frame: FloatArray
    origin: FloatArray


def jaw_joint(landmarks: AnatomyLandmarks) -> JawJoint:
    """Place the condyles and the mandible cut from the skin landmarks.

    Parameters
    ----------
    landmarks : AnatomyLandmarks

    Returns
    -------
    JawJoint
    """
    lm = landmarks
    p = lambda name: lm.local(lm.point(name))
    condyles_local = []
    for side, sign in (("L", 1.0), ("R", -1.0)):
        y = p(f"suborbital_{side}")[1]
        # the skin contour at that height: between the supraglenoid and gonion landmarks
        top, low = p(f"supraglenoid_{side}"), p(f"gonion_{side}")
        t = np.clip((top[1] - y) / max(top[1] - low[1], 1e-9), 0.0, 1.0)
        skin = (1 - t) * top + t * low
        condyles_local.append(np.array([skin[0] - sign * CONDYLE_DEPTH_MM, y, skin[2]]))
    C = np.array(condyles_local)
    stomion = p("stomion")
    z_condyle, y_condyle = C[:, 2].mean(), C[:, 1].mean()
    z_ramus = 0.5 * (p("gonion_L")[2] + p("gonion_R")[2]) + RAMUS_FRONT_AHEAD_OF_GONION_MM
    y_ramus = stomion[1] + np.tan(np.radians(OCCLUSAL_TILT_DEG)) * (stomion[2] - z_ramus)
    cut_z = np.array([z_condyle, z_ramus, stomion[2]])
    cut_y = np.array([y_condyle - CONDYLAR_NECK_MM, y_ramus, stomion[1]])
    return JawJoint(C @ lm.frame + lm.origin, cut_z, cut_y, lm.frame.copy(), lm.origin.copy())


def is_mandible(points: Any, joint: JawJoint) -> np.ndarray:
    """Which points lie below the cranium-mandible cut.

    Parameters
    ----------
    points : (k, 3) float array, mm
        Scan coordinates.
    joint : JawJoint

    Returns
    -------
    (k,) bool array
    """
    L = _face_local(points, joint)
    return L[:, 1] < np.interp(L[:, 2], joint.cut_z, joint.cut_y)


def in_jaw_gap(points: Any, joint: JawJoint, half_width_mm: float = JAW_GAP_MM) -> np.ndarray:
    """Which points lie within ``half_width_mm`` of the cranium-mandible cut (in the sagittal plane).

    The cut's level continuations before the condyles and beyond the stomion count as part of
    it; see :data:`JAW_GAP_MM` for why the bone there is left free.

    Parameters
    ----------
    points : (k, 3) float array, mm
        Scan coordinates.
    joint : JawJoint
    half_width_mm : float, default :data:`JAW_GAP_MM`

    Returns
    -------
    (k,) bool array
    """
    q = _face_local(points, joint)[:, [2, 1]]  # (z, y)
    far = 1e4  # the level continuations, as long segments
    corners = np.column_stack([np.r_[joint.cut_z[0] - far, joint.cut_z, joint.cut_z[-1] + far],
                               np.r_[joint.cut_y[0], joint.cut_y, joint.cut_y[-1]]])
    distance = np.full(q.shape[0], np.inf)
    for a, b in zip(corners[:-1], corners[1:]):
        ab = b - a
        t = np.clip((q - a) @ ab / float(ab @ ab), 0.0, 1.0)
        distance = np.minimum(distance, np.linalg.norm(q - (a + t[:, None] * ab), axis=1))
    return distance < half_width_mm


def _face_local(points: Any, joint: JawJoint) -> FloatArray:
    """Scan coordinates ``(k, 3)`` in the face frame of ``joint`` (x left, y up, z forward)."""
    return (np.asarray(points, dtype=np.float64) - joint.origin) @ joint.frame.T

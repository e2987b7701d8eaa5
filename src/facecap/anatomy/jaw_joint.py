"""The jaw: temporomandibular joint (condyle) positions and the cut between cranium and mandible.

Both come from the skin landmarks in the face frame (x left, y up, z forward):

- each condyle lies at the height of the Frankfort horizontal (the orbitale,
  taken at the suborbital landmark), at the face contour just in front of the
  ear at that height, 18 mm medial of the skin (8.5 mm of tissue over the
  supraglenoid region plus half a condyle's width);
- the mandible is what lies below a cut in the sagittal (z, y) plane: the
  occlusal plane from the stomion (mouth slit), rising 8.5 degrees backwards
  to the front of the ramus (10 mm in front of the gonion), then straight up
  the ramus to 5 mm below the condyle (the condylar neck), and level behind it.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..typing import FloatArray
from .anatomy_landmarks import AnatomyLandmarks

__all__ = ["JawJoint", "jaw_joint", "is_mandible"]

CONDYLE_DEPTH_MM = 18.0
"""Condyle centre medial of the skin contour in front of the ear."""
OCCLUSAL_TILT_DEG = 8.5
"""Rise of the occlusal plane backwards from the stomion, relative to the face frame's horizontal."""
RAMUS_FRONT_AHEAD_OF_GONION_MM = 10.0
CONDYLAR_NECK_MM = 5.0


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
    L = (np.asarray(points, dtype=np.float64) - joint.origin) @ joint.frame.T
    return L[:, 1] < np.interp(L[:, 2], joint.cut_z, joint.cut_y)

"""``correspondence.npz``: how a result's face maps back into the capture's frame, where cameras are calibrated.

Written beside the vertices by every command whose face comes from the markers (``facecap animate``,
``facecap blend``) and read by the stages that work in the capture's frame (the wrinkle layer's cameras).
A face point ``x`` of frame ``t`` is at ``M_t c^-1(x)`` in the mocap frame: ``c^-1`` is the triharmonic
warp from ``face_points`` to ``mocap_points`` (exact at those points, exact for any affine map), ``M_t``
the frame's ``mocap_from_stabilized`` (the identity when the take was not stabilised).
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from ..errors import FileFormatError
from ._atomic import atomic_path

__all__ = ["write_mocap_correspondence", "read_mocap_correspondence"]


def write_mocap_correspondence(path: str | os.PathLike[str], mocap_points: Any, face_points: Any, labels: Any, *,
                               mocap_from_stabilized: Any = None) -> None:
    """Write ``correspondence.npz`` (mm).

    Parameters
    ----------
    path : path-like
    mocap_points : (K, 3) float array, mm
        Points in the (stabilised) mocap frame: the rest markers.
    face_points : (K, 3) float array, mm
        Where the face holds them (the result's frame, in mm): the map ``c`` of Bickel et al. 4.1 carries
        ``mocap_points`` there.
    labels : sequence of str
        One per point.
    mocap_from_stabilized : (T, 4, 4) float array, optional
        Per frame, the rigid motion carrying the stabilised markers back to where the capture saw them.

    Raises
    ------
    ValueError
        On shapes that do not agree or non-finite points (a bug of the caller, not a user's file).
    """
    mocap = np.asarray(mocap_points, dtype=np.float64)
    face = np.asarray(face_points, dtype=np.float64)
    names = np.asarray(list(labels), dtype=str)
    if mocap.ndim != 2 or mocap.shape[1] != 3 or face.shape != mocap.shape or names.shape != (mocap.shape[0],):
        raise ValueError(f"correspondence: mocap {mocap.shape}, face {face.shape}, labels {names.shape} do not agree")
    if not (np.isfinite(mocap).all() and np.isfinite(face).all()):
        raise ValueError("correspondence: points must be finite")
    arrays: dict[str, np.ndarray] = {"mocap_points": mocap, "face_points": face, "labels": names,
                                     "units": np.asarray("mm")}
    if mocap_from_stabilized is not None:
        motion = np.asarray(mocap_from_stabilized, dtype=np.float64)
        if motion.ndim != 3 or motion.shape[1:] != (4, 4):
            raise ValueError(f"mocap_from_stabilized: expected (T, 4, 4), got {motion.shape}")
        arrays["mocap_from_stabilized"] = motion
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:  # a file object: np.savez would append .npz to a temporary name
            np.savez(f, **arrays)


def read_mocap_correspondence(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """Read ``correspondence.npz``: ``mocap_points``, ``face_points``, ``labels`` and, if stabilised,
    ``mocap_from_stabilized``.

    Raises
    ------
    FileFormatError
        Naming the file: not an npz archive, a missing array, shapes that do not agree, non-finite points.
    """
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError) as exc:
        raise FileFormatError(f"not a readable correspondence archive ({exc})", path=str(path)) from exc
    missing = [k for k in ("mocap_points", "face_points") if k not in arrays]
    if missing:
        raise FileFormatError(f"correspondence lacks {', '.join(missing)}", path=str(path))
    mocap, face = arrays["mocap_points"], arrays["face_points"]
    if mocap.ndim != 2 or mocap.shape[1:] != (3,) or face.shape != mocap.shape or mocap.shape[0] < 4:
        raise FileFormatError(f"correspondence: mocap_points {mocap.shape} and face_points {face.shape} must be the "
                              "same (K, 3), K >= 4", path=str(path))
    if not (np.isfinite(mocap).all() and np.isfinite(face).all()):
        raise FileFormatError("correspondence: points must be finite", path=str(path))
    motion = arrays.get("mocap_from_stabilized")
    if motion is not None and (motion.ndim != 3 or motion.shape[1:] != (4, 4) or not np.isfinite(motion).all()):
        raise FileFormatError(f"correspondence: mocap_from_stabilized must be finite (T, 4, 4), got {motion.shape}",
                              path=str(path))
    return arrays

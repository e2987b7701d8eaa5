"""``correspondence.npz``: how a result's face maps back into the capture's frame, where cameras are calibrated.

Written beside the vertices by every command whose face comes from the markers (``facecap animate``,
``facecap blend``) and read by the stages that work in the capture's frame (the wrinkle layer's cameras).
A face point ``x`` of frame ``t`` is at ``M_t c^-1(x)`` in the mocap frame: ``c^-1`` is the triharmonic
warp from ``face_points`` to ``mocap_points`` (exact at those points, exact for any affine map), ``M_t``
the frame's ``mocap_from_stabilized`` (the identity when the take was not stabilised).
"""

from __future__ import annotations

import os
import zipfile
from typing import Any

import numpy as np

from ..errors import FileFormatError
from .atomic_write import atomic_path

__all__ = ["write_mocap_correspondence", "read_mocap_correspondence"]


def _problem(arrays: dict[str, np.ndarray]) -> str | None:
    """What makes a correspondence unusable (None when it is sound): the one check the writer and the reader share."""
    missing = [k for k in ("mocap_points", "face_points") if k not in arrays]
    if missing:
        return f"correspondence lacks {', '.join(missing)}"
    mocap, face = arrays["mocap_points"], arrays["face_points"]
    if not (np.issubdtype(mocap.dtype, np.number) and np.issubdtype(face.dtype, np.number)):
        return "correspondence: points must be numbers"
    if mocap.ndim != 2 or mocap.shape[1:] != (3,) or face.shape != mocap.shape or mocap.shape[0] < 4:
        return f"correspondence: mocap_points {mocap.shape} and face_points {face.shape} must be the same (K, 3), K >= 4"
    if not (np.isfinite(mocap).all() and np.isfinite(face).all()):
        return "correspondence: points must be finite"
    if "labels" in arrays and arrays["labels"].shape != (mocap.shape[0],):
        return f"correspondence: {arrays['labels'].shape} labels for {mocap.shape[0]} points"
    if "units" in arrays and str(arrays["units"]) != "mm":
        return f"correspondence: units {str(arrays['units'])!r}, expected 'mm'"
    motion = arrays.get("mocap_from_stabilized")
    if motion is not None and (not np.issubdtype(motion.dtype, np.number) or motion.ndim != 3
                               or motion.shape[1:] != (4, 4) or not np.isfinite(motion).all()):
        return f"correspondence: mocap_from_stabilized must be finite (T, 4, 4), got {motion.shape}"
    return None


def write_mocap_correspondence(path: str | os.PathLike[str], mocap_points: Any, face_points: Any, labels: Any, *,
                               mocap_from_stabilized: Any = None) -> None:
    """Write ``correspondence.npz`` (mm).

    Parameters
    ----------
    path : path-like
    mocap_points : (K, 3) float array, mm
        Points in the (stabilised) mocap frame: the rest markers; K >= 4.
    face_points : (K, 3) float array, mm
        Where the face holds them (the result's frame, in mm): the map ``c`` of Bickel et al. 4.1 carries
        ``mocap_points`` there.
    labels : sequence of str
        One per point.
    mocap_from_stabilized : (T, 4, 4) float array, mm, optional
        Per frame, the rigid motion carrying the stabilised markers back to where the capture saw them.

    Raises
    ------
    ValueError
        On anything :func:`read_mocap_correspondence` would refuse (a bug of the caller, not a user's file).
    """
    arrays: dict[str, np.ndarray] = {"mocap_points": np.asarray(mocap_points, dtype=np.float64),
                                     "face_points": np.asarray(face_points, dtype=np.float64),
                                     "labels": np.asarray(list(labels), dtype=str), "units": np.asarray("mm")}
    if mocap_from_stabilized is not None:
        arrays["mocap_from_stabilized"] = np.asarray(mocap_from_stabilized, dtype=np.float64)
    problem = _problem(arrays)
    if problem is not None:
        raise ValueError(problem)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:  # a file object: np.savez would append .npz to a temporary name
            np.savez(f, **arrays)


def read_mocap_correspondence(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """Read ``correspondence.npz``: ``mocap_points``, ``face_points``, ``labels`` and, if stabilised,
    ``mocap_from_stabilized``.

    Raises
    ------
    FileFormatError
        Naming the file: missing, empty, truncated or not an npz archive, a missing array, shapes that do not
        agree, points that are not finite numbers, another unit than mm.
    """
    try:
        # the file opened here, so that it is closed when numpy's zip reader fails on a damaged archive
        with open(path, "rb") as f, np.load(f, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise FileFormatError(f"not a readable correspondence archive ({exc})", path=str(path)) from exc
    problem = _problem(arrays)
    if problem is not None:
        raise FileFormatError(problem, path=str(path))
    return arrays

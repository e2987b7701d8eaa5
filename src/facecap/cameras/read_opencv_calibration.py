"""One camera from an OpenCV FileStorage file (YAML or XML), and back.

The keys are those OpenCV's calibration sample (``samples/cpp/calibration.cpp``,
``saveCameraParams``) writes, plus the camera's pose in the mocap frame:

==========================  =====================================================
``camera_matrix``           3x3 ``!!opencv-matrix`` (required)
``distortion_coefficients`` 4, 5, 8, 12 or 14 values, any of 1xN or Nx1 (required)
``image_width``             int (required)
``image_height``            int (required)
``R``                       3x3 rotation, or a Rodrigues 3-vector (required, or ``rvec``)
``T``                       3-vector, ``x_cam = R X + T`` (required, or ``tvec``)
==========================  =====================================================

``rvec`` / ``tvec`` are accepted as names of ``R`` / ``T`` (what
``cv2.solvePnP`` returns); a file holding both spellings must agree. The
sample's other keys (``calibration_time``, ``board_width``,
``avg_reprojection_error``, ``extrinsic_parameters`` of the chessboard views,
...) are ignored: the chessboard's poses are not the camera's pose in the
mocap frame.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FileFormatError, InputError
from ..io.atomic_write import atomic_path
from ..units import mm_per_unit, normalize_unit
from .camera import Camera

__all__ = ["read_opencv_calibration", "write_opencv_calibration"]

OPENCV_SUFFIXES = (".yml", ".yaml", ".xml", ".json")


def _node_array(fs: Any, key: str) -> np.ndarray | None:
    node = fs.getNode(key)
    if node.empty():
        return None
    if node.isInt() or node.isReal():
        return np.array([node.real()])
    if node.isSeq():
        return np.array([node.at(i).real() for i in range(node.size())], dtype=np.float64)
    mat = node.mat()
    return None if mat is None else np.asarray(mat, dtype=np.float64)


def _rotation(value: np.ndarray, key: str, path: str) -> np.ndarray:
    import cv2

    if value.size == 9:
        return value.reshape(3, 3)
    if value.size == 3:
        R, _ = cv2.Rodrigues(value.reshape(3, 1).astype(np.float64))
        return R
    raise FileFormatError(f"{key}: expected a 3x3 rotation or a Rodrigues 3-vector, got {value.size} values",
                          path=path)


def read_opencv_calibration(path: str | os.PathLike[str], *, name: str | None = None,
                            unit: str = "mm") -> Camera:
    """Read one calibrated camera from an OpenCV FileStorage file (``cv2.FileStorage``).

    Parameters
    ----------
    path : str or path-like
        A ``.yml``/``.yaml``/``.xml`` (or OpenCV ``.json``) FileStorage file with
        the keys of the module notes.
    name : str or None, default None
        The camera's name; default the file's stem (``cam0.yml`` -> ``'cam0'``).
    unit : {'mm', 'cm', 'm', 'in'}, default 'mm'
        The length unit of ``T`` in the file (FileStorage files state none;
        the calibration sample's ``square_size`` sets it). ``T`` is converted to mm.

    Returns
    -------
    Camera
        With ``source_unit`` set to ``unit``.

    Raises
    ------
    FileFormatError
        If the file is missing, unreadable by OpenCV, lacks a required key, or
        holds a value of the wrong size; the message names the file and the key.
    InputError
        If the values do not make a camera (see :class:`Camera`), or ``unit`` is unknown.
    """
    import cv2

    unit = normalize_unit(unit, name="unit")
    file = Path(path)
    if not file.is_file():
        raise FileFormatError("calibration file not found", path=str(file))
    try:
        fs = cv2.FileStorage(str(file), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as exc:  # OpenCV's parser raises cv2.error, wrapped in SystemError by cv2
        detail = str(exc.__cause__ or exc).strip().splitlines()[-1]
        raise FileFormatError(f"not an OpenCV FileStorage file ({detail})", path=str(file)) from None
    try:
        if not fs.isOpened():
            raise FileFormatError("OpenCV cannot open it as a FileStorage file", path=str(file))
        values = {key: _node_array(fs, key) for key in
                  ("camera_matrix", "distortion_coefficients", "image_width", "image_height",
                   "R", "rvec", "T", "tvec")}
    finally:
        fs.release()
    for key in ("camera_matrix", "distortion_coefficients", "image_width", "image_height"):
        if values[key] is None:
            raise FileFormatError(f"no {key!r} (the keys of OpenCV's calibration sample are required)",
                                  path=str(file))
    rotations = [_rotation(values[k], k, str(file)) for k in ("R", "rvec") if values[k] is not None]
    translations = [values[k].ravel() for k in ("T", "tvec") if values[k] is not None]
    if not rotations or not translations:
        missing = "R (or rvec)" if not rotations else "T (or tvec)"
        raise FileFormatError(f"no {missing}: the camera's pose in the mocap frame, x_cam = R X + T",
                              path=str(file))
    if any(v.size != 3 for v in translations):
        raise FileFormatError(f"T: expected 3 values, got {[v.size for v in translations]}", path=str(file))
    for key, found in (("T", translations), ("R", rotations)):
        if len(found) == 2 and not np.allclose(found[0], found[1], rtol=0, atol=1e-9):
            raise FileFormatError(f"{key} and its alternative spelling ({'tvec' if key == 'T' else 'rvec'}) "
                                  "disagree", path=str(file))
    K = values["camera_matrix"]
    if K.size != 9:
        raise FileFormatError(f"camera_matrix: expected 3x3, got {K.size} values", path=str(file))
    try:
        return Camera(
            name if name is not None else file.stem,
            K=K.reshape(3, 3),
            distortion=values["distortion_coefficients"].ravel(),
            width=int(values["image_width"].ravel()[0]),
            height=int(values["image_height"].ravel()[0]),
            R=rotations[0],
            T=translations[0] * mm_per_unit(unit),
            source_unit=unit,
        )
    except InputError as exc:
        raise FileFormatError(str(exc), path=str(file)) from None


def write_opencv_calibration(path: str | os.PathLike[str], camera: Camera, *, unit: str | None = None,
                             rotation: str = "matrix") -> None:
    """Write one camera as an OpenCV FileStorage file (atomically), readable by ``cv2.FileStorage``.

    Parameters
    ----------
    path : str or path-like
        Destination ``.yml``, ``.yaml``, ``.xml`` or ``.json`` (OpenCV picks the format from the suffix).
    camera : Camera
    unit : {'mm', 'cm', 'm', 'in'} or None, default None
        Length unit of ``T`` in the file; default the camera's ``source_unit``.
    rotation : {'matrix', 'rodrigues'}, default 'matrix'
        Write ``R`` as a 3x3 matrix, or as a Rodrigues 3-vector.

    Raises
    ------
    InputError
        If the suffix is not one OpenCV writes, the folder does not exist, or an option is unknown.
    """
    import cv2

    file = Path(path)
    if file.suffix.lower() not in OPENCV_SUFFIXES:
        raise InputError(f"expected one of {OPENCV_SUFFIXES} (OpenCV picks the format from it)", path=str(file))
    if rotation not in ("matrix", "rodrigues"):
        raise InputError(f"rotation: expected 'matrix' or 'rodrigues', got {rotation!r}")
    unit = normalize_unit(unit if unit is not None else camera.source_unit, name="unit")
    R = camera.R if rotation == "matrix" else cv2.Rodrigues(np.ascontiguousarray(camera.R))[0]
    with atomic_path(file) as tmp:
        fs = cv2.FileStorage(str(tmp), cv2.FILE_STORAGE_WRITE)
        try:
            fs.write("image_width", camera.width)
            fs.write("image_height", camera.height)
            fs.write("camera_matrix", np.ascontiguousarray(camera.K))
            # no coefficients is the same model as five zeros, which every OpenCV reader takes
            dist = camera.distortion if camera.distortion.size else np.zeros(5)
            fs.write("distortion_coefficients", np.ascontiguousarray(dist.reshape(-1, 1)))
            fs.write("R", np.ascontiguousarray(R))
            fs.write("T", np.ascontiguousarray((camera.T / mm_per_unit(unit)).reshape(3, 1)))
            fs.writeComment(f"facecap camera {camera.name!r}: x_cam = R X + T, X in the mocap frame, T in {unit}")
        finally:
            fs.release()

"""The facecap camera file: every camera of a capture, the footage rate and its offset, in one JSON file.

Schema (version 1; ``docs/cameras.md`` has a full example)::

    {
      "format": "facecap-cameras",
      "version": 1,
      "unit": "mm",                       # length unit of every T below
      "footage": {"rate_hz": 12.5,        # video frame rate, or null if not known yet
                  "first_mocap_frame": 0},# mocap frame at which video frame 0 was exposed
      "cameras": [
        {"name": "cam0", "image_width": 1384, "image_height": 1038,
         "camera_matrix": [[fx, 0, cx], [0, fy, cy], [0, 0, 1]],
         "distortion_coefficients": [k1, k2, p1, p2, k3],
         "R": [[...], [...], [...]],      # or a Rodrigues 3-vector
         "T": [tx, ty, tz]}               # x_cam = R X + T, X in the mocap frame
      ]
    }

Keys are named as in OpenCV's calibration files so that one camera's entry
reads like its ``.yml``.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FileFormatError, InputError
from ..io.atomic_write import atomic_write_text
from ..units import mm_per_unit, normalize_unit
from .camera import Camera
from .synchronize import FootageSync, synchronize

__all__ = ["CameraSetup", "CAMERA_FILE_FORMAT", "read_camera_file", "write_camera_file"]

CAMERA_FILE_FORMAT = "facecap-cameras"
"""The ``format`` value of a facecap camera file."""

_VERSION = 1


@dataclass(frozen=True, eq=False)
class CameraSetup:
    """The cameras of a capture and how their footage lines up with the take.

    Parameters
    ----------
    cameras : tuple of Camera
        At least one, with distinct names, all in the mocap frame, in mm.
    video_rate_hz : float or None, default None
        Frame rate of the footage (all cameras are triggered together); None if not known.
    first_mocap_frame : float, default 0
        The mocap frame at which video frame 0 was exposed.
    source_unit : {'mm', 'cm', 'm', 'in'}, default 'mm'
        The unit of ``T`` in the file this came from (the cameras are in mm).

    Raises
    ------
    InputError
        On no camera, repeated names, a non-positive rate or a non-finite offset.
    """

    cameras: tuple[Camera, ...]
    video_rate_hz: float | None = None
    first_mocap_frame: float = 0.0
    source_unit: str = "mm"

    def __post_init__(self) -> None:
        cameras = tuple(self.cameras)
        if not cameras or not all(isinstance(c, Camera) for c in cameras):
            raise InputError("cameras: expected at least one Camera")
        names = [c.name for c in cameras]
        repeated = sorted({n for n in names if names.count(n) > 1})
        if repeated:
            raise InputError(f"cameras: names must be distinct, repeated: {repeated}")
        object.__setattr__(self, "cameras", cameras)
        if self.video_rate_hz is not None:
            rate = float(self.video_rate_hz)
            if not math.isfinite(rate) or rate <= 0:
                raise InputError(f"video_rate_hz: expected a positive number or None, got {self.video_rate_hz!r}")
            object.__setattr__(self, "video_rate_hz", rate)
        first = float(self.first_mocap_frame)
        if not math.isfinite(first):
            raise InputError(f"first_mocap_frame: expected a finite number, got {self.first_mocap_frame!r}")
        object.__setattr__(self, "first_mocap_frame", first)
        object.__setattr__(self, "source_unit", normalize_unit(self.source_unit, name="unit"))

    @property
    def names(self) -> tuple[str, ...]:
        """The cameras' names, in file order."""
        return tuple(c.name for c in self.cameras)

    def camera(self, name: str) -> Camera:
        """The camera called ``name``; InputError naming the known ones if there is none."""
        for cam in self.cameras:
            if cam.name == name:
                return cam
        raise InputError(f"no camera named {name!r}; the cameras are {list(self.names)}")

    def synchronize(self, mocap_rate_hz: float, n_mocap_frames: int, n_video_frames: int, *,
                    footage_name: str = "footage", allow_fractional_ratio: bool = False) -> FootageSync:
        """:func:`~facecap.cameras.synchronize` with this setup's rate and offset.

        Raises
        ------
        InputError
            If the setup has no video rate, or the footage does not cover the take.
        """
        if self.video_rate_hz is None:
            raise InputError("the camera setup gives no footage rate (footage.rate_hz); give the video rate")
        return synchronize(mocap_rate_hz, n_mocap_frames, self.video_rate_hz, n_video_frames,
                           first_mocap_frame=self.first_mocap_frame, footage_name=footage_name,
                           allow_fractional_ratio=allow_fractional_ratio)


def _camera_entry(camera: Camera, unit: str) -> dict[str, Any]:
    return {
        "name": camera.name,
        "image_width": camera.width,
        "image_height": camera.height,
        "camera_matrix": camera.K.tolist(),
        "distortion_coefficients": camera.distortion.tolist(),
        "R": camera.R.tolist(),
        "T": (camera.T / mm_per_unit(unit)).tolist(),
    }


def write_camera_file(path: str | os.PathLike[str], setup: CameraSetup, *, unit: str | None = None) -> None:
    """Write a facecap camera file (JSON, atomically).

    Parameters
    ----------
    path : str or path-like
        Destination, conventionally ``cameras.json``.
    setup : CameraSetup
    unit : {'mm', 'cm', 'm', 'in'} or None, default None
        Length unit of ``T`` in the file; default ``setup.source_unit``.

    Raises
    ------
    InputError
        If the folder does not exist or the unit is unknown.

    Notes
    -----
    Floats are written with Python's shortest round-trip repr, so a file read
    back gives bit-identical cameras when the unit is mm.
    """
    if not isinstance(setup, CameraSetup):
        raise InputError(f"setup: expected a CameraSetup, got {type(setup).__name__}")
    unit = normalize_unit(unit if unit is not None else setup.source_unit, name="unit")
    document = {
        "format": CAMERA_FILE_FORMAT,
        "version": _VERSION,
        "unit": unit,
        "convention": "OpenCV: x_cam = R X + T, X in the mocap frame; pixel (0, 0) is the centre of the "
                      "top-left pixel, u right, v down",
        "footage": {"rate_hz": setup.video_rate_hz, "first_mocap_frame": setup.first_mocap_frame},
        "cameras": [_camera_entry(c, unit) for c in setup.cameras],
    }
    atomic_write_text(path, json.dumps(document, indent=2) + "\n")


def _rotation(value: Any, where: str) -> np.ndarray:
    import cv2

    R = np.asarray(value, dtype=np.float64)
    if R.shape == (3, 3):
        return R
    if R.size == 3:
        return cv2.Rodrigues(R.reshape(3, 1))[0]
    raise InputError(f"{where}.R: expected a 3x3 rotation or a Rodrigues 3-vector, got shape {R.shape}")


def read_camera_file(path: str | os.PathLike[str]) -> CameraSetup:
    """Read a facecap camera file (see the module notes for the schema).

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    CameraSetup
        Cameras in mm, ``source_unit`` the file's unit.

    Raises
    ------
    FileFormatError
        If the file is missing, not JSON, not a facecap camera file, of a
        newer version, or lacks a key; the message names the file and the key.
    InputError
        (as FileFormatError) if a camera's values do not make a camera.
    """
    file = Path(path)
    if not file.is_file():
        raise FileFormatError("camera file not found", path=str(file))
    try:
        document = json.loads(file.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise FileFormatError(f"not a JSON file ({exc})", path=str(file)) from None
    if not isinstance(document, dict) or document.get("format") != CAMERA_FILE_FORMAT:
        raise FileFormatError(f"not a facecap camera file (no \"format\": \"{CAMERA_FILE_FORMAT}\")", path=str(file))
    version = document.get("version")
    if not isinstance(version, int) or version < 1 or version > _VERSION:
        raise FileFormatError(f"camera file version {version!r}; this facecap reads version {_VERSION}",
                              path=str(file))
    try:
        unit = normalize_unit(document.get("unit", "mm"), name="unit")
        footage = document.get("footage") or {}
        if not isinstance(footage, dict):
            raise InputError("footage: expected an object with rate_hz and first_mocap_frame")
        entries = document.get("cameras")
        if not isinstance(entries, list) or not entries:
            raise InputError("cameras: expected a non-empty list")
        cameras = []
        for i, entry in enumerate(entries):
            where = f"cameras[{i}]"
            if not isinstance(entry, dict):
                raise InputError(f"{where}: expected an object")
            missing = [k for k in ("name", "image_width", "image_height", "camera_matrix",
                                   "distortion_coefficients", "R", "T") if k not in entry]
            if missing:
                raise InputError(f"{where}: missing {missing}")
            try:
                T = np.asarray(entry["T"], dtype=np.float64).ravel() * mm_per_unit(unit)
                cameras.append(Camera(
                    entry["name"], K=entry["camera_matrix"], distortion=entry["distortion_coefficients"],
                    width=entry["image_width"], height=entry["image_height"],
                    R=_rotation(entry["R"], where), T=T, source_unit=unit,
                ))
            except (TypeError, ValueError) as exc:
                raise InputError(f"{where}: {exc}") from None
        rate = footage.get("rate_hz")
        return CameraSetup(tuple(cameras), video_rate_hz=rate, first_mocap_frame=footage.get("first_mocap_frame", 0),
                           source_unit=unit)
    except FileFormatError:
        raise
    except (InputError, TypeError, ValueError) as exc:
        raise FileFormatError(str(exc), path=str(file)) from None

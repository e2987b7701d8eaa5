"""The cameras that filmed each footage: a facecap camera file or one OpenCV calibration per camera, matched
to the footage in the order given."""

from __future__ import annotations

import os
from pathlib import Path
from typing import NamedTuple, Sequence

from ..errors import InputError
from .camera import Camera
from .camera_file import read_camera_file
from .read_opencv_calibration import read_opencv_calibration

__all__ = ["read_footage_cameras", "FootageCameras"]


class FootageCameras(NamedTuple):
    """The cameras of some footage, one per footage in its order, and the timing the camera file gives."""

    cameras: list[Camera]
    """One camera per footage, in the footage's order."""
    video_rate_hz: float | None
    """The footage rate the camera file gives (None: not given, or OpenCV calibration files)."""
    first_mocap_frame: float
    """The mocap frame of video frame 0 the camera file gives (0 for OpenCV calibration files)."""


def read_footage_cameras(camera_paths: Sequence[str | os.PathLike[str]], footage_paths: Sequence[str | os.PathLike[str]],
                         *, unit: str = "mm") -> FootageCameras:
    """Read the cameras that filmed each footage.

    Parameters
    ----------
    camera_paths : sequence of path
        One facecap camera file (``.json``, :func:`~facecap.cameras.read_camera_file`), or one OpenCV
        calibration file per footage, in the footage's order
        (:func:`~facecap.cameras.read_opencv_calibration`).
    footage_paths : sequence of path
        One image folder or video file per camera. With a camera file, footage named after its
        cameras (a folder's name, a video file's stem) is given those cameras; else the file must hold
        one camera per footage, taken in file order.
    unit : str, default 'mm'
        Length unit of ``T`` in OpenCV calibration files (a camera file states its own).

    Returns
    -------
    FootageCameras
        ``cameras`` (one per footage, in order), ``video_rate_hz`` and ``first_mocap_frame`` (the
        camera file's; None and 0 for OpenCV calibration files).

    Raises
    ------
    InputError
        On a camera count that does not match the footage, or a file that does not read.
    """
    if len(camera_paths) == 1 and Path(camera_paths[0]).suffix.lower() == ".json":
        setup = read_camera_file(camera_paths[0])
        stems = [Path(v).stem if Path(v).suffix else Path(v).name for v in footage_paths]
        if all(stem in setup.names for stem in stems):
            cameras = [setup.camera(stem) for stem in stems]
        elif len(setup.cameras) == len(footage_paths):
            cameras = list(setup.cameras)
        else:
            raise InputError(f"{camera_paths[0]}: {len(setup.cameras)} cameras ({', '.join(setup.names)}) for "
                             f"{len(footage_paths)} footage; name each footage after its camera or give one per camera")
        return FootageCameras(cameras, setup.video_rate_hz, setup.first_mocap_frame)
    if len(camera_paths) != len(footage_paths):
        raise InputError(f"--cameras: {len(camera_paths)} calibration files for {len(footage_paths)} footage "
                         "(one per camera)")
    return FootageCameras([read_opencv_calibration(p, unit=unit) for p in camera_paths], None, 0.0)

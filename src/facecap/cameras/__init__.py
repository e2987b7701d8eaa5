"""Cameras and footage: calibrated views of the mocap stage and the images they took.

One home for what the video-driven detail layers (the wrinkles of Bickel et al.
2007, section 5; shape from shading, Lo et al.) need from cameras. The
conventions are OpenCV's, stated in ``camera.py`` and ``docs/cameras.md``:
``x_cam = R X + T`` with ``X`` in the mocap frame in mm, pixel ``(0, 0)`` the
centre of the top-left pixel, ``u`` right, ``v`` down.

- :class:`Camera` (``camera.py``): intrinsics, lens distortion (4 to 14
  OpenCV coefficients), image size and pose; :meth:`Camera.project`
  (``cv2.projectPoints``' model, vectorised) and :meth:`Camera.pixel_rays` (its inverse).
- :func:`read_opencv_calibration` / :func:`write_opencv_calibration`
  (``read_opencv_calibration.py``): one camera per OpenCV FileStorage YAML/XML,
  the keys of OpenCV's calibration sample plus ``R`` and ``T``.
- :func:`read_camera_file` / :func:`write_camera_file` (``camera_file.py``):
  the facecap camera file (JSON): every camera, the footage rate and offset, as a
  :class:`CameraSetup`.
- :func:`read_footage_cameras` (``read_footage_cameras.py``): the camera of each footage,
  from a camera file or one calibration file per camera, with the file's footage timing,
  as a :class:`FootageCameras`.
- :func:`synchronize` (``synchronize.py``): a :class:`FootageSync` mapping video
  frames to mocap frames by rate ratio and offset, checking the footage covers the take.
- :func:`read_image` / :func:`write_image` (``io/image_file.py``): one PNG (8/16-bit),
  JPEG, TIFF or EXR image as stored; :func:`image_to_float`,
  :func:`srgb_to_linear`, :func:`linear_to_srgb` (``image_to_float.py``).
- :func:`open_footage` (``footage.py``): an image sequence or a video file
  (PyAV) as a lazy :class:`Footage`; :func:`write_image_sequence`
  (``write_image_sequence.py``) and :func:`write_video` (``write_video.py``,
  lossless FFV1 or PNG by default) write footage.
- :class:`Light` (``light.py``): a point, spot or directional light in the mocap frame, the direction
  and irradiance it sends to each point; :class:`LightSetup`, :func:`read_light_file` and
  :func:`write_light_file` (``light_file.py``): ``lights.json``, the stage's lights and ambient.
- :func:`calibrate_light` (``calibrate_light.py``): a point light's position (or a far light's direction)
  from a chrome sphere of known radius seen by calibrated cameras, as a :class:`LightCalibration`
  (:class:`LightCalibrationError` names the image that could not be measured).
- :class:`RayCaster` and :func:`ray_cast` (``ray_cast.py``): the point of the
  (deformed) mesh each pixel sees (Embree), which vertices a camera sees and
  which points a light reaches (cast shadows);
  :func:`project_performance` (``project_performance.py``): every vertex of a
  performance in a view, with visibility.
"""

from __future__ import annotations

from .camera import DISTORTION_SIZES, Camera, PixelRays, Projection
from .camera_file import CAMERA_FILE_FORMAT, CameraSetup, read_camera_file, write_camera_file
from .footage import VIDEO_SUFFIXES, Footage, open_footage
from ..io.image_file import IMAGE_SUFFIXES, read_image, write_image
from .light import LIGHT_KINDS, REFERENCE_DISTANCE_MM, Light
from .light_file import LIGHT_FILE_FORMAT, LightSetup, read_light_file, write_light_file
from .calibrate_light import EDGE_PROFILES, LightCalibration, LightCalibrationError, calibrate_light
from .image_to_float import image_to_float, linear_to_srgb, srgb_to_linear
from .project_performance import PerformanceProjection, project_performance
from .ray_cast import RayCaster, RayHits, ray_cast
from .read_opencv_calibration import read_opencv_calibration, write_opencv_calibration
from .read_footage_cameras import FootageCameras, read_footage_cameras
from .synchronize import FootageSync, VideoBracket, synchronize
from .write_image_sequence import SEQUENCE_FILE, write_image_sequence
from .write_video import LOSSLESS_VIDEO_CODECS, write_video

__all__ = [
    "Camera",
    "Projection",
    "PixelRays",
    "DISTORTION_SIZES",
    "read_opencv_calibration",
    "write_opencv_calibration",
    "CameraSetup",
    "CAMERA_FILE_FORMAT",
    "read_camera_file",
    "write_camera_file",
    "read_footage_cameras",
    "FootageCameras",
    "FootageSync",
    "VideoBracket",
    "synchronize",
    "read_image",
    "write_image",
    "IMAGE_SUFFIXES",
    "image_to_float",
    "srgb_to_linear",
    "linear_to_srgb",
    "Footage",
    "open_footage",
    "VIDEO_SUFFIXES",
    "write_image_sequence",
    "SEQUENCE_FILE",
    "write_video",
    "LOSSLESS_VIDEO_CODECS",
    "Light",
    "LIGHT_KINDS",
    "REFERENCE_DISTANCE_MM",
    "LightSetup",
    "LIGHT_FILE_FORMAT",
    "read_light_file",
    "write_light_file",
    "calibrate_light",
    "LightCalibration",
    "LightCalibrationError",
    "EDGE_PROFILES",
    "RayCaster",
    "RayHits",
    "ray_cast",
    "PerformanceProjection",
    "project_performance",
]

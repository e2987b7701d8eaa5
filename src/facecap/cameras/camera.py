"""A calibrated pinhole camera with lens distortion, in OpenCV's conventions, placed in the mocap frame.

Conventions (stated once, here; ``docs/cameras.md`` repeats them):

- world to camera: ``x_cam = R X + T`` with ``X`` in the mocap frame in **mm**;
  the camera looks down its +z axis, x to the right of the image, y down;
- pixel ``(u, v)``: ``u`` to the right, ``v`` down, the centre of the top-left
  pixel at ``(0, 0)``; an image is ``(H, W)`` or ``(H, W, C)``;
- ``K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` in pixels (no skew: OpenCV's
  ``projectPoints`` has none);
- distortion coefficients in OpenCV's order
  ``(k1, k2, p1, p2[, k3[, k4, k5, k6[, s1, s2, s3, s4[, tau_x, tau_y]]]])``:
  4, 5, 8, 12 or 14 of them (or none).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from ..errors import InputError
from ..typing import BoolArray, FloatArray
from ..units import normalize_unit

__all__ = ["Camera", "Projection", "PixelRays", "DISTORTION_SIZES"]

DISTORTION_SIZES = (0, 4, 5, 8, 12, 14)
"""The numbers of distortion coefficients OpenCV's camera model accepts."""

_ROTATION_TOLERANCE = 1e-6  # |R^T R - I| and |det R - 1|: a calibration's R is orthonormal to ~1e-12


class Projection(NamedTuple):
    """Points projected into a camera.

    Attributes
    ----------
    pixels : (..., 2) float64 array, px
        ``(u, v)`` of each point (also computed for points behind the camera,
        as ``cv2.projectPoints`` does; mask them with ``in_front``).
    depth : (...) float64 array, mm
        ``z`` of each point in the camera frame (distance along the optical axis).
    in_front : (...) bool array
        ``depth > 0``.
    in_image : (...) bool array
        In front and inside the image: ``-0.5 <= u < W - 0.5`` and ``-0.5 <= v < H - 0.5``.
    """

    pixels: FloatArray
    depth: FloatArray
    in_front: BoolArray
    in_image: BoolArray


class PixelRays(NamedTuple):
    """The rays through pixels, in the mocap frame.

    Attributes
    ----------
    origins : (..., 3) float64 array, mm
        The camera centre, repeated for every pixel.
    directions : (..., 3) float64 array
        Unit directions in the mocap frame.
    """

    origins: FloatArray
    directions: FloatArray


def _as_matrix(value: Any, shape: tuple[int, ...], name: str, camera: str) -> FloatArray:
    try:
        A = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"camera {camera!r}: {name}: expected a numeric {shape} array ({exc})") from None
    if A.shape != shape:
        raise InputError(f"camera {camera!r}: {name}: expected shape {shape}, got {A.shape}")
    if not np.all(np.isfinite(A)):
        raise InputError(f"camera {camera!r}: {name}: contains NaN or infinite values")
    A.setflags(write=False)
    return A


@dataclass(frozen=True, eq=False)
class Camera:
    """A calibrated camera: intrinsics, lens distortion, image size and pose in the mocap frame.

    Parameters
    ----------
    name : str
        The camera's name (used in file names and messages).
    K : (3, 3) float64 array, px
        Camera matrix ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``, fx, fy > 0.
    distortion : (d,) float64 array
        OpenCV distortion coefficients, d in {0, 4, 5, 8, 12, 14} (see the module notes).
    width, height : int
        Image size in pixels.
    R : (3, 3) float64 array
        Rotation from the mocap frame to the camera frame (orthonormal, det +1).
    T : (3,) float64 array, mm
        Translation: ``x_cam = R X + T``.
    source_unit : {'mm', 'cm', 'm', 'in'}, default 'mm'
        The length unit ``T`` was given in by the file it came from; ``T`` is already in mm.

    Raises
    ------
    InputError
        On a wrong shape, non-finite values, a skewed or non-positive ``K``, a
        distortion count OpenCV does not accept, a non-rotation ``R`` or a
        non-positive image size; the message names the camera.

    Examples
    --------
    >>> import numpy as np
    >>> cam = Camera("front", K=[[1000, 0, 319.5], [0, 1000, 239.5], [0, 0, 1]], distortion=[],
    ...              width=640, height=480, R=np.eye(3), T=[0, 0, 500])
    >>> cam.project([[0.0, 0.0, 0.0]]).pixels
    array([[319.5, 239.5]])
    """

    name: str
    K: FloatArray
    distortion: FloatArray
    width: int
    height: int
    R: FloatArray
    T: FloatArray
    source_unit: str = "mm"

    def __post_init__(self) -> None:
        name = str(self.name)
        if not name:
            raise InputError("camera: name must be a non-empty string")
        object.__setattr__(self, "name", name)
        K = _as_matrix(self.K, (3, 3), "K (camera_matrix)", name)
        if K[0, 1] != 0 or K[1, 0] != 0 or K[2, 0] != 0 or K[2, 1] != 0 or K[2, 2] != 1:
            raise InputError(
                f"camera {name!r}: K (camera_matrix) must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] "
                f"(OpenCV's model has no skew), got {K.tolist()}"
            )
        if K[0, 0] <= 0 or K[1, 1] <= 0:
            raise InputError(f"camera {name!r}: K (camera_matrix): focal lengths must be positive, got "
                             f"fx={K[0, 0]}, fy={K[1, 1]}")
        object.__setattr__(self, "K", K)
        dist = np.array(self.distortion if self.distortion is not None else [], dtype=np.float64).ravel()
        if dist.size not in DISTORTION_SIZES:
            raise InputError(f"camera {name!r}: distortion: OpenCV takes {DISTORTION_SIZES[1:]} coefficients "
                             f"(or none), got {dist.size}")
        if not np.all(np.isfinite(dist)):
            raise InputError(f"camera {name!r}: distortion: contains NaN or infinite values")
        dist.setflags(write=False)
        object.__setattr__(self, "distortion", dist)
        for attr in ("width", "height"):
            value = getattr(self, attr)
            if isinstance(value, bool) or not float(value).is_integer() or int(value) <= 0:
                raise InputError(f"camera {name!r}: image {attr} must be a positive integer, got {value!r}")
            object.__setattr__(self, attr, int(value))
        R = _as_matrix(self.R, (3, 3), "R", name)
        orthogonality = float(np.abs(R.T @ R - np.eye(3)).max())
        if orthogonality > _ROTATION_TOLERANCE or abs(np.linalg.det(R) - 1) > _ROTATION_TOLERANCE:
            raise InputError(f"camera {name!r}: R is not a rotation (|R^T R - I| = {orthogonality:.2e}, "
                             f"det = {np.linalg.det(R):.6f})")
        object.__setattr__(self, "R", R)
        object.__setattr__(self, "T", _as_matrix(np.ravel(self.T), (3,), "T", name))
        object.__setattr__(self, "source_unit", normalize_unit(self.source_unit, name=f"camera {name!r}: unit"))

    # -- pose -----------------------------------------------------------------------------------

    @property
    def centre(self) -> FloatArray:
        """(3,) float64, mm: the camera centre in the mocap frame, ``-R^T T``."""
        return -self.R.T @ self.T

    @property
    def view_direction(self) -> FloatArray:
        """(3,) float64: the optical axis (camera +z) in the mocap frame, unit length (``R[2]``)."""
        return self.R[2].copy()

    @property
    def image_size(self) -> tuple[int, int]:
        """``(width, height)`` in pixels, OpenCV's ``Size`` order."""
        return self.width, self.height

    @classmethod
    def look_at(cls, name: str, eye: Any, target: Any, *, up: Any = (0.0, 1.0, 0.0), focal_px: float,
                width: int, height: int, distortion: Any = ()) -> "Camera":
        """A camera at ``eye`` looking at ``target``, image up along ``up``, principal point at the centre.

        Parameters
        ----------
        name : str
        eye, target : (3,) array, mm
            Camera centre and a point on the optical axis, in the mocap frame.
        up : (3,) array, default (0, 1, 0)
            A direction that appears upwards in the image (not parallel to the view).
        focal_px : float
            Focal length in pixels (fx = fy).
        width, height : int
            Image size; the principal point is ``((W - 1) / 2, (H - 1) / 2)``.
        distortion : (d,) array, default none

        Returns
        -------
        Camera
        """
        eye = np.asarray(eye, dtype=np.float64)
        forward = np.asarray(target, dtype=np.float64) - eye
        if np.linalg.norm(forward) == 0:
            raise InputError(f"camera {name!r}: eye and target coincide")
        z = forward / np.linalg.norm(forward)
        down = -np.asarray(up, dtype=np.float64)
        y = down - (down @ z) * z
        if np.linalg.norm(y) < 1e-9:
            raise InputError(f"camera {name!r}: up is parallel to the view direction")
        y /= np.linalg.norm(y)
        x = np.cross(y, z)
        R = np.stack([x, y, z])
        K = [[focal_px, 0.0, (width - 1) / 2], [0.0, focal_px, (height - 1) / 2], [0.0, 0.0, 1.0]]
        return cls(name, K=K, distortion=distortion, width=width, height=height, R=R, T=-R @ eye)

    # -- projection -----------------------------------------------------------------------------

    def to_camera_frame(self, points_mm: Any) -> FloatArray:
        """Points ``(..., 3)`` in the mocap frame (mm) to the camera frame (mm): ``R X + T``."""
        X = _as_points(points_mm, self.name)
        return X @ self.R.T + self.T

    def project(self, points_mm: Any) -> Projection:
        """Project points of the mocap frame into the image, lens distortion included.

        Parameters
        ----------
        points_mm : (..., 3) array, mm
            Points in the mocap frame.

        Returns
        -------
        Projection
            ``pixels (..., 2)``, ``depth (...)`` in mm, ``in_front`` and ``in_image`` masks.

        Notes
        -----
        OpenCV's model (``cv2.projectPoints``), evaluated here in float64 numpy
        so that whole performances project in one call: with ``(x, y) = (X_c/Z_c, Y_c/Z_c)``
        and ``r^2 = x^2 + y^2``,

        .. math::
            x'' = x \\frac{1 + k_1 r^2 + k_2 r^4 + k_3 r^6}{1 + k_4 r^2 + k_5 r^4 + k_6 r^6}
                  + 2 p_1 x y + p_2 (r^2 + 2 x^2) + s_1 r^2 + s_2 r^4

        (and symmetrically for y''), then the tilted-sensor homography of
        ``(tau_x, tau_y)`` and ``u = f_x x''' + c_x``, ``v = f_y y''' + c_y``.
        The tests compare it with ``cv2.projectPoints`` for every coefficient count.
        """
        Xc = self.to_camera_frame(points_mm)
        depth = Xc[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            x = Xc[..., 0] / depth
            y = Xc[..., 1] / depth
        xd, yd = _distort(x, y, self.distortion)
        K = self.K
        pixels = np.stack([K[0, 0] * xd + K[0, 2], K[1, 1] * yd + K[1, 2]], axis=-1)
        in_front = depth > 0
        with np.errstate(invalid="ignore"):
            in_image = (in_front & (pixels[..., 0] >= -0.5) & (pixels[..., 0] < self.width - 0.5)
                        & (pixels[..., 1] >= -0.5) & (pixels[..., 1] < self.height - 0.5))
        return Projection(pixels, depth, in_front, in_image)

    def pixel_rays(self, pixels: Any) -> PixelRays:
        """The ray through each pixel, in the mocap frame (the inverse of :meth:`project`).

        Parameters
        ----------
        pixels : (..., 2) array, px
            ``(u, v)`` positions, distorted (as seen in the image).

        Returns
        -------
        PixelRays
            ``origins (..., 3)`` (the camera centre, mm) and unit ``directions (..., 3)``.

        Notes
        -----
        The distortion is inverted by ``cv2.undistortPoints`` (iterative, run to
        convergence: up to 100 iterations, reprojection change below 1e-12); a
        point projected by :meth:`project` lies on the ray of its pixel to
        about 1e-6 mm at 500 mm for the usual lenses (tested).
        """
        import cv2

        P = _as_points(pixels, self.name, width=2, name="pixels")
        if not np.all(np.isfinite(P)):
            raise InputError(f"camera {self.name!r}: pixels: contains NaN or infinite values")
        flat = P.reshape(-1, 1, 2)
        if self.distortion.size == 0 or not np.any(self.distortion):
            K = self.K
            normalized = np.stack([(flat[:, 0, 0] - K[0, 2]) / K[0, 0], (flat[:, 0, 1] - K[1, 2]) / K[1, 1]], -1)
        elif flat.shape[0] == 0:
            normalized = np.zeros((0, 2))
        else:
            criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
            normalized = cv2.undistortPoints(flat, self.K, self.distortion, criteria=criteria).reshape(-1, 2)
        d_cam = np.concatenate([normalized, np.ones((normalized.shape[0], 1))], axis=1)
        d_cam /= np.linalg.norm(d_cam, axis=1, keepdims=True)
        directions = (d_cam @ self.R).reshape(P.shape[:-1] + (3,))  # R^T d for each row
        origins = np.broadcast_to(self.centre, directions.shape).copy()
        return PixelRays(origins, directions)

    def pixel_grid(self, *, step: int = 1) -> FloatArray:
        """(H', W', 2) float64: the ``(u, v)`` of every ``step``-th pixel centre, row by row."""
        u = np.arange(0, self.width, step, dtype=np.float64)
        v = np.arange(0, self.height, step, dtype=np.float64)
        uu, vv = np.meshgrid(u, v)
        return np.stack([uu, vv], axis=-1)


def _as_points(points: Any, camera: str, *, width: int = 3, name: str = "points") -> FloatArray:
    """``points`` as a float64 ``(..., width)`` array, or an InputError naming the camera and the argument."""
    try:
        X = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"camera {camera!r}: {name}: expected a numeric (..., {width}) array ({exc})") from None
    if X.ndim < 1 or X.shape[-1] != width:
        raise InputError(f"camera {camera!r}: {name}: expected shape (..., {width}), got {X.shape}")
    return X


def _distort(x: np.ndarray, y: np.ndarray, distortion: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV's distortion of normalised coordinates (``cv2.projectPoints``' model, all 14 terms)."""
    if distortion.size == 0:
        return x, y
    c = np.zeros(14)
    c[: distortion.size] = distortion
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4, tau_x, tau_y = c
    r2 = x * x + y * y
    r4 = r2 * r2
    r6 = r4 * r2
    with np.errstate(divide="ignore", invalid="ignore"):
        radial = (1 + k1 * r2 + k2 * r4 + k3 * r6) / (1 + k4 * r2 + k5 * r4 + k6 * r6)
    xy2 = 2 * x * y
    xd = x * radial + p1 * xy2 + p2 * (r2 + 2 * x * x) + s1 * r2 + s2 * r4
    yd = y * radial + p1 * (r2 + 2 * y * y) + p2 * xy2 + s3 * r2 + s4 * r4
    if tau_x == 0 and tau_y == 0:
        return xd, yd
    tilt = _tilt_matrix(tau_x, tau_y)
    hx = tilt[0, 0] * xd + tilt[0, 1] * yd + tilt[0, 2]
    hy = tilt[1, 0] * xd + tilt[1, 1] * yd + tilt[1, 2]
    hz = tilt[2, 0] * xd + tilt[2, 1] * yd + tilt[2, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(hz != 0, 1.0 / hz, 1.0)
    return hx * inv, hy * inv


def _tilt_matrix(tau_x: float, tau_y: float) -> FloatArray:
    """OpenCV's ``computeTiltProjectionMatrix`` (the tilted sensor of the 14-coefficient model)."""
    cx, sx = np.cos(tau_x), np.sin(tau_x)
    cy, sy = np.cos(tau_y), np.sin(tau_y)
    rot_x = np.array([[1, 0, 0], [0, cx, sx], [0, -sx, cx]])
    rot_y = np.array([[cy, 0, -sy], [0, 1, 0], [sy, 0, cy]])
    rot_xy = rot_y @ rot_x
    proj_z = np.array([[rot_xy[2, 2], 0, -rot_xy[0, 2]], [0, rot_xy[2, 2], -rot_xy[1, 2]], [0, 0, 1]])
    return proj_z @ rot_xy

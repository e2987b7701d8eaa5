"""A light's position (or direction) from a chrome sphere of known radius seen by calibrated cameras.

The steps, per sphere position (a frame of every camera's footage):

1. the sphere's outline in each image: Otsu's threshold of the blurred grey
   image, the largest blob, an ellipse fitted to its contour
   (``cv2.fitEllipse``), then a sub-pixel edge point on each of
   :data:`EDGE_PROFILES` radial profiles: the centroid of the profile's falling
   slope about its steepest point (exact for an area-sampled straight edge,
   unlike a half-level crossing, and barely moved by the shading inside the rim);
2. the sphere's centre ``C``: every edge pixel's ray (``o``, unit ``d``,
   :meth:`Camera.pixel_rays`) is tangent to the sphere, so
   ``|(C - o) x d| = r``, solved in least squares over every camera
   (``scipy.optimize.least_squares``, three unknowns);
3. the highlight in each image: the brightest blob inside the outline, its
   intensity-weighted centroid (saturated pixels weigh alike);
4. its ray hits the sphere at ``P`` with normal ``n = (P - C) / r``; the light
   lies along the mirror reflection ``R = d - 2 (d . n) n`` from ``P``.

The point light is the least-squares nearest point to every reflected ray,
``X = (sum_i Q_i)^-1 sum_i Q_i P_i`` with ``Q_i = I - R_i R_i^T``. Its
covariance comes from each ray's direction error (the highlight's pixel error
``highlight_sigma_px`` and the centre's covariance, propagated by finite
differences): a ray whose direction is off by ``dR`` passes the light
``L_i dR`` away, ``L_i`` the distance along it, and ``X`` moves by
``(sum Q)^-1 Q_i L_i dR``. When the rays are too close to parallel for a
distance (the depth's standard deviation above ``far_ratio`` of the distance,
or the nearest point behind a ray), the light is returned as directional:
the mean reflected direction, reversed (the way the light travels).

Geometry, to judge a result: a sphere of radius ``r`` whose centre is off by
``e`` turns each reflected ray by about ``2 e / r``, which at a light ``D``
away is ``2 D e / r`` sideways: 0.05 mm on a 40 mm sphere is 3 mm at 1.2 m.
One sphere position gives rays that start a few millimetres apart, so the
light's distance from one position is weak (the reported depth sigma says
how weak); move the sphere across the capture volume (several frames) for a
point light. The sphere's rim reflects what is behind it; a rim that is
dark over a pixel biases the outline inwards (``docs/cameras.md``, "Lights").
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from ..errors import InputError
from ..typing import FloatArray
from .camera import Camera
from .image_to_float import image_to_float, srgb_to_linear
from .light import Light

__all__ = ["calibrate_light", "LightCalibration", "LightCalibrationError", "EDGE_PROFILES"]

EDGE_PROFILES = 360
"""Radial profiles on which the sphere's outline is measured, per image."""

_PROFILE_HALF_PX = 7.0  # each profile runs this far either side of the fitted ellipse
_PROFILE_STEP_PX = 0.1
_SLOPE_WINDOW_PX = 2.5  # the slope's centroid is taken this far either side of its steepest point
_EDGE_SCALE_PX = 0.1  # the robust loss's scale for the outline's edge points
_MIN_RADIUS_PX = 6.0  # a sphere smaller than this in an image is not measured
_MIN_CONTRAST = 0.03  # sphere minus backdrop, fraction of full scale, for an edge profile to count
_HIGHLIGHT_RATIO = 1.5  # the highlight's peak over the sphere's median, at least
_HIGHLIGHT_LEVEL = 0.2  # the highlight's blob: above this share of the way from the sphere's median to its peak


class LightCalibrationError(InputError):
    """An image in which the sphere or its highlight cannot be measured.

    Attributes
    ----------
    camera : int
        Index of the camera (its footage) in the order given.
    frame : int
        The frame (sphere position).
    """

    def __init__(self, message: str, *, camera: int, frame: int) -> None:
        super().__init__(message)
        self.camera = camera
        self.frame = frame


class LightCalibration(NamedTuple):
    """A light calibrated from a mirror sphere, with what it was measured from.

    Attributes
    ----------
    light : Light
        ``'point'`` (position, mm) or ``'directional'`` (the way the light travels).
    sphere_centres : (F, 3) float64 array, mm
        The sphere's centre at each position (frame).
    sphere_sigma_mm : (F,) float64 array, mm
        The centre's standard deviation (the largest axis) from its fit's residuals.
    outlines : (F, C, 5) float64 array
        Each image's fitted outline as ``cv2.fitEllipse`` gives it: centre ``u, v``,
        full axes (px) and angle (degrees).
    edge_rms_px : (F, C) float64 array, px
        RMS of the outline's edge points' distance from the fitted sphere's image (px at the sphere).
    highlights : (F, C, 2) float64 array, px
        The highlight's centroid ``(u, v)`` in each image.
    ray_origins, ray_directions : (F*C, 3) float64 arrays
        The reflected rays: mirror points on the sphere (mm) and unit directions
        toward the light; frame-major.
    ray_distances_mm : (F*C,) float64 array, mm
        Each ray's distance from the point light (for a directional light: its
        angle from the light's reversed direction times 1 m).
    spread_deg : float
        The largest angle between two reflected rays.
    covariance_mm2 : (3, 3) float64 array, mm^2
        The point light's covariance (see the module notes); inf for a directional light.
    sigma_mm : (3,) float64 array, mm
        Standard deviations of the point light along the principal axes of its
        covariance, largest first (the first is nearly its depth); inf for a directional light.
    direction_sigma_deg : float
        The direction's standard deviation (the mean over the rays, divided by
        the square root of their count).
    weak : str
        Why the geometry is weak ('' if it is not).
    """

    light: Light
    sphere_centres: FloatArray
    sphere_sigma_mm: FloatArray
    outlines: FloatArray
    edge_rms_px: FloatArray
    highlights: FloatArray
    ray_origins: FloatArray
    ray_directions: FloatArray
    ray_distances_mm: FloatArray
    spread_deg: float
    covariance_mm2: FloatArray
    sigma_mm: FloatArray
    direction_sigma_deg: float
    weak: str


# -- per image -------------------------------------------------------------------------------------

def _grey(image: Any, where: str, srgb: bool | None) -> FloatArray:
    """The image's mean of its colour channels, linear light, float64."""
    A = np.asarray(image)
    if A.ndim == 3 and A.shape[2] in (3, 4):
        A = A[:, :, :3]
    elif A.ndim != 2 and not (A.ndim == 3 and A.shape[2] == 1):
        raise InputError(f"{where}: expected an (H, W) or (H, W, 3) image, got shape {A.shape}")
    grey = image_to_float(A).astype(np.float64)
    if srgb or (srgb is None and A.dtype == np.uint8):  # an edge pixel mixes light linearly, not its sRGB code
        grey = srgb_to_linear(np.clip(grey, 0.0, 1.0))
    return grey.mean(axis=2) if grey.ndim == 3 else grey


def _outline(grey: FloatArray, where: str) -> tuple[Any, np.ndarray]:
    """The largest bright blob's fitted ellipse and its filled mask, or raise."""
    import cv2

    smooth = cv2.GaussianBlur(grey.astype(np.float32), (0, 0), 1.5)
    top = float(np.percentile(smooth, 99.5))
    scaled = np.clip(smooth / max(top, 1e-6) * 255.0, 0, 255).astype(np.uint8)
    _, mask = cv2.threshold(scaled, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if count < 2:
        raise InputError(f"{where}: no sphere found (no region brighter than the backdrop)")
    largest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    x, y, bw, bh = (int(stats[largest, k]) for k in (cv2.CC_STAT_LEFT, cv2.CC_STAT_TOP, cv2.CC_STAT_WIDTH,
                                                     cv2.CC_STAT_HEIGHT))
    if x == 0 or y == 0 or x + bw == grey.shape[1] or y + bh == grey.shape[0]:
        raise InputError(f"{where}: the sphere (the largest bright region) touches the image's edge; frame it wholly")
    blob = (labels == largest).astype(np.uint8)
    contours, _ = cv2.findContours(blob, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    contour = max(contours, key=len)
    if len(contour) < 20:
        raise InputError(f"{where}: no sphere found (the brightest region is {len(contour)} px round)")
    ellipse = cv2.fitEllipse(contour)
    (cu, cv), (a, b), _ = ellipse
    h, w = grey.shape
    if min(a, b) / 2 < _MIN_RADIUS_PX:
        raise InputError(f"{where}: no sphere found (the brightest region is {min(a, b):.1f} px across; "
                         f"at least {2 * _MIN_RADIUS_PX:.0f} px needed)")
    if min(a, b) / max(a, b) < 0.7:
        raise InputError(f"{where}: no sphere found (the brightest region is not round: axes {a:.0f} and "
                         f"{b:.0f} px)")
    filled = np.zeros_like(blob)
    cv2.ellipse(filled, ellipse, 1, -1)
    share = float((blob & filled).sum()) / max(float(filled.sum()), 1.0)
    if share < 0.85:
        raise InputError(f"{where}: no sphere found (the brightest region fills {share:.0%} of its ellipse)")
    margin = max(a, b) / 2 + _PROFILE_HALF_PX + 2
    if cu - margin < 0 or cv - margin < 0 or cu + margin > w - 1 or cv + margin > h - 1:
        raise InputError(f"{where}: the sphere touches the image's edge; frame it wholly")
    return ellipse, filled.astype(bool)


def _edge_points(grey: FloatArray, ellipse: Any, highlight_mask: np.ndarray) -> FloatArray:
    """Sub-pixel points of the outline: the first moment of each radial profile's step (px, (k, 2))."""
    from scipy.ndimage import map_coordinates

    (cu, cv), (a, b), angle = ellipse
    theta = np.linspace(0.0, 2 * np.pi, EDGE_PROFILES, endpoint=False)
    phi = np.radians(angle)
    # the ellipse's radius along each direction from its centre
    ct, st = np.cos(theta - phi), np.sin(theta - phi)
    radius = 1.0 / np.sqrt((ct / (a / 2)) ** 2 + (st / (b / 2)) ** 2)
    steps = np.arange(-_PROFILE_HALF_PX, _PROFILE_HALF_PX + 1e-9, _PROFILE_STEP_PX)
    rr = radius[:, None] + steps[None, :]
    u = cu + rr * np.cos(theta)[:, None]
    v = cv + rr * np.sin(theta)[:, None]
    profile = map_coordinates(grey, [v.ravel(), u.ravel()], order=1, mode="nearest").reshape(u.shape)
    near = map_coordinates(highlight_mask.astype(np.float64), [v.ravel(), u.ravel()], order=0,
                           mode="constant").reshape(u.shape).any(axis=1)
    n_in = int(round(1.5 / _PROFILE_STEP_PX))
    inner = np.median(profile[:, :n_in], axis=1)  # the sphere 5.5 to 7 px inside the fitted rim
    outer = np.median(profile[:, -n_in:], axis=1)  # the backdrop 5.5 to 7 px outside
    contrast = inner - outer
    # the edge is the centroid of the falling slope about its steepest point: exact for an area-sampled
    # straight edge under linear interpolation, and barely moved by the sphere's shading inside the rim
    slope = np.clip(profile[:, :-1] - profile[:, 1:], 0.0, None)
    middle = steps[:-1] + 0.5 * _PROFILE_STEP_PX
    peak = np.argmax(slope, axis=1)
    window = int(round(_SLOPE_WINDOW_PX / _PROFILE_STEP_PX))
    index = np.clip(peak[:, None] + np.arange(-window, window + 1)[None, :], 0, slope.shape[1] - 1)
    # the sphere's own shading just inside the rim (3 to 4.5 px in from the steepest point), taken off the
    # slope inside the edge: a rim that darkens toward its edge would pull the centroid inwards
    inside = np.clip(peak[:, None] - np.arange(int(3.0 / _PROFILE_STEP_PX), int(4.5 / _PROFILE_STEP_PX))[None, :],
                     0, slope.shape[1] - 1)
    shading = np.median(np.take_along_axis(profile[:, :-1] - profile[:, 1:], inside, axis=1), axis=1)
    w = np.take_along_axis(slope, index, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        edge = (w * middle[index]).sum(axis=1) / w.sum(axis=1)
        w = np.clip(w - np.where(middle[index] < edge[:, None], shading[:, None], 0.0), 0.0, None)
        edge = (w * middle[index]).sum(axis=1) / w.sum(axis=1)
    keep = (contrast > _MIN_CONTRAST) & ~near & (np.abs(edge) < _PROFILE_HALF_PX - 2.0) & np.isfinite(edge)
    r_edge = radius + edge
    points = np.stack([cu + r_edge * np.cos(theta), cv + r_edge * np.sin(theta)], axis=1)
    return points[keep]


def _highlight(grey: FloatArray, disc: np.ndarray, where: str) -> tuple[FloatArray, np.ndarray]:
    """The highlight's intensity-weighted centroid inside the sphere's disc (px) and its pixels' mask."""
    import cv2

    inside = cv2.erode(disc.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    values = np.where(inside, grey, -np.inf)
    peak = float(values.max())
    median = float(np.median(grey[inside]))
    if not peak > _HIGHLIGHT_RATIO * median or peak - median < 0.1:
        raise InputError(f"{where}: no highlight on the sphere (its brightest pixel, {peak:.3f}, against its "
                         f"median {median:.3f}); is the light on and reflected toward this camera?")
    level = median + _HIGHLIGHT_LEVEL * (peak - median)
    above = (values >= level).astype(np.uint8)
    _, labels = cv2.connectedComponents(above, connectivity=8)
    row, col = np.unravel_index(int(np.argmax(values)), grey.shape)
    blob = labels == labels[row, col]
    weights = np.where(blob, grey - level, 0.0)
    vv, uu = np.nonzero(blob)
    wsum = weights[vv, uu].sum()
    centroid = np.array([(uu * weights[vv, uu]).sum() / wsum, (vv * weights[vv, uu]).sum() / wsum])
    grown = cv2.dilate(blob.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    return centroid, grown


# -- geometry --------------------------------------------------------------------------------------

def _tangent_residuals(C: FloatArray, origins: FloatArray, directions: FloatArray, radius: float) -> FloatArray:
    return np.linalg.norm(np.cross(C - origins, directions), axis=1) - radius


def _sphere_centre(outlines: list[tuple[Camera, FloatArray, Any]],
                   radius: float) -> tuple[FloatArray, float, FloatArray, list[float]]:
    """Least-squares centre from every camera's edge rays; its sigma (mm), covariance and each camera's edge RMS (px)."""
    from scipy.optimize import least_squares

    guesses, origins, directions, owner = [], [], [], []
    for k, (camera, points, ellipse) in enumerate(outlines):
        (cu, cv), (a, b), _ = ellipse
        o, d = camera.pixel_rays(points)
        axis = camera.pixel_rays(np.array([cu, cv])).directions
        half_angle = np.median(np.arccos(np.clip(d @ axis, -1.0, 1.0)))  # the outline's cone about its axis
        guesses.append(camera.centre + axis * radius / np.sin(half_angle))
        origins.append(o)
        directions.append(d)
        owner.append(np.full(len(points), k))
    o_all, d_all, who = np.concatenate(origins), np.concatenate(directions), np.concatenate(owner)
    guess = np.mean(guesses, axis=0)
    mm_per_px = np.median([float(camera.to_camera_frame(guess)[2]) / camera.K[0, 0] for camera, _, _ in outlines])
    # a robust loss: a few profiles (a reflection's edge crossing the rim) are off by tenths of a pixel
    fit = least_squares(_tangent_residuals, guess, args=(o_all, d_all, radius), loss="soft_l1",
                        f_scale=_EDGE_SCALE_PX * mm_per_px, xtol=1e-12, ftol=1e-12, gtol=1e-12)
    C = fit.x
    res = fit.fun
    dof = max(res.size - 3, 1)
    cov = np.linalg.pinv(fit.jac.T @ fit.jac) * float(res @ res) / dof
    sigma = float(np.sqrt(max(np.linalg.eigvalsh(cov).max(), 0.0)))
    rms_px = []
    for k, (camera, _, _) in enumerate(outlines):
        depth = float(camera.to_camera_frame(C)[2])
        mm_per_px = depth / camera.K[0, 0]
        rms_px.append(float(np.sqrt(np.mean(res[who == k] ** 2))) / mm_per_px)
    return C, sigma, cov, rms_px


def _reflect(camera: Camera, pixel: FloatArray, C: FloatArray, radius: float) -> tuple[FloatArray, FloatArray] | None:
    """The mirror point on the sphere and the unit reflected direction of a pixel's ray, None if it misses."""
    o, d = camera.pixel_rays(np.asarray(pixel, dtype=np.float64))
    oc = o - C
    b = float(d @ oc)
    disc = b * b - (float(oc @ oc) - radius * radius)
    if disc < 0:
        return None
    P = o + (-b - np.sqrt(disc)) * d
    n = (P - C) / radius
    return P, d - 2.0 * float(d @ n) * n


def _direction_cov(camera: Camera, pixel: FloatArray, C: FloatArray, C_cov: FloatArray, radius: float,
                   highlight_sigma_px: float) -> FloatArray:
    """(3, 3) covariance of the reflected direction from the highlight's and the centre's errors (finite differences)."""
    _, R0 = _reflect(camera, pixel, C, radius)  # type: ignore[misc]
    J = []
    for step, base in ((np.array([0.1, 0.0]), "px"), (np.array([0.0, 0.1]), "px")):
        moved = _reflect(camera, pixel + step, C, radius) or _reflect(camera, pixel - step, C, radius)
        J.append((moved[1] - R0) / 0.1 if moved is not None else np.zeros(3))
    J_px = np.stack(J, axis=1)
    J_C = np.zeros((3, 3))
    for axis in range(3):
        step = np.zeros(3)
        step[axis] = 1e-3
        moved = _reflect(camera, pixel, C + step, radius)
        if moved is not None:
            J_C[:, axis] = (moved[1] - R0) / 1e-3
    return highlight_sigma_px ** 2 * J_px @ J_px.T + J_C @ C_cov @ J_C.T


# -- the light ------------------------------------------------------------------------------------

def _check_frames(images: Sequence[Any], cameras: Sequence[Camera]) -> int:
    if len(cameras) < 1 or len(images) != len(cameras):
        raise InputError(f"images: expected one sequence of frames per camera ({len(cameras)}), got {len(images)}")
    counts = [len(frames) for frames in images]
    if min(counts) < 1:
        raise InputError("images: every camera needs at least one frame")
    if len(set(counts)) != 1:
        raise InputError(f"images: the cameras' frame counts differ ({counts}); each frame is one sphere position "
                         "seen by every camera")
    return counts[0]


def calibrate_light(
    images: Sequence[Sequence[Any]],
    cameras: Sequence[Camera],
    sphere_radius_mm: float,
    *,
    kind: str = "auto",
    intensity: float = 1.0,
    highlight_sigma_px: float = 0.5,
    far_ratio: float = 0.5,
    srgb: bool | None = None,
) -> LightCalibration:
    """Calibrate a light from images of a chrome sphere of known radius seen by calibrated cameras.

    Parameters
    ----------
    images : sequence over cameras of sequences over frames of (H, W) or (H, W, 3) arrays
        ``images[c][f]``: camera ``c``'s view of sphere position ``f`` (uint8,
        uint16 or float; sRGB or linear alike). A :class:`~facecap.cameras.Footage`
        is such a sequence of frames. Every camera has the same frame count.
    cameras : sequence of Camera
        One per footage, in the same order; mocap frame, mm.
    sphere_radius_mm : float, mm
        The sphere's radius (half its diameter), > 0.
    kind : {'auto', 'point', 'directional'}, default 'auto'
        'auto' returns a directional light when the rays are too close to
        parallel for a distance (see the module notes).
    intensity : float, default 1
        Written into the light (relative; a mirror sphere does not measure it).
    highlight_sigma_px : float, default 0.5
        The highlight centroid's assumed standard deviation, px, for the uncertainty.
    far_ratio : float, default 0.5
        'auto' gives a directional light when the point's depth sigma exceeds
        this share of its distance from the rays' origins.
    srgb : bool or None, default None
        Whether the images hold sRGB codes, decoded to linear light before
        measuring (an edge pixel is a linear mix of sphere and backdrop); None:
        ``uint8`` images are sRGB (8-bit PNG, JPEG, ordinary video), others linear.

    Returns
    -------
    LightCalibration
        The light, the sphere's centres and what each image showed, the
        reflected rays, their distances from the light, their spread and the
        light's uncertainty; ``weak`` says why the geometry is weak, if it is.

    Raises
    ------
    LightCalibrationError
        (an :class:`~facecap.errors.InputError`) naming the camera and frame: no sphere found, a sphere
        touching the image's edge, no highlight, a highlight whose ray misses the fitted sphere.
    InputError
        Mismatching counts, a non-positive radius, an unknown ``kind``, fewer than two reflected rays.

    Notes
    -----
    The sphere's tangent rays: ``|(C - o_j) x d_j| = r`` for each edge pixel ``j``;
    the reflection: ``R = d - 2 (d . n) n``; the nearest point to rays
    ``(P_i, R_i)``: ``X = (sum Q_i)^-1 sum Q_i P_i``, ``Q_i = I - R_i R_i^T``, with covariance
    ``(sum Q)^-1 [sum Q_i L_i^2 Sigma_Ri Q_i] (sum Q)^-1`` for direction covariances
    ``Sigma_Ri`` and distances ``L_i`` along the rays.
    """
    if kind not in ("auto", "point", "directional"):
        raise InputError(f"kind: expected 'auto', 'point' or 'directional', got {kind!r}")
    radius = float(sphere_radius_mm)
    if not np.isfinite(radius) or radius <= 0:
        raise InputError(f"sphere_radius_mm: expected a positive radius, got {sphere_radius_mm!r}")
    n_frames = _check_frames(images, cameras)
    n_cams = len(cameras)
    centres = np.zeros((n_frames, 3))
    centre_sigma = np.zeros(n_frames)
    outlines_out = np.zeros((n_frames, n_cams, 5))
    edge_rms = np.zeros((n_frames, n_cams))
    highlights = np.zeros((n_frames, n_cams, 2))
    P_all, R_all, Rcov_all = [], [], []
    for f in range(n_frames):
        measured = []
        for c, camera in enumerate(cameras):
            where = f"camera {camera.name!r}, frame {f}"
            try:
                grey = _grey(images[c][f], where, srgb)
                if grey.shape != (camera.height, camera.width):
                    raise InputError(f"{where}: the image is {grey.shape[1]}x{grey.shape[0]}, the camera is "
                                     f"calibrated for {camera.width}x{camera.height}")
                ellipse, disc = _outline(grey, where)
                centroid, glare = _highlight(grey, disc, where)
                points = _edge_points(grey, ellipse, glare)
                if len(points) < 20:
                    raise InputError(f"{where}: the sphere's outline is too faint to measure ({len(points)} of "
                                     f"{EDGE_PROFILES} edge points; light the room it reflects or darken the backdrop)")
            except LightCalibrationError:
                raise
            except InputError as exc:
                raise LightCalibrationError(exc.message, camera=c, frame=f) from None
            measured.append((camera, points, ellipse))
            (cu, cv), (a, b), angle = ellipse
            outlines_out[f, c] = (cu, cv, a, b, angle)
            highlights[f, c] = centroid
        C, sigma, C_cov, rms = _sphere_centre(measured, radius)
        centres[f], centre_sigma[f], edge_rms[f] = C, sigma, rms
        for c, camera in enumerate(cameras):
            hit = _reflect(camera, highlights[f, c], C, radius)
            if hit is None:
                raise LightCalibrationError(
                    f"camera {camera.name!r}, frame {f}: the highlight at ({highlights[f, c, 0]:.1f}, "
                    f"{highlights[f, c, 1]:.1f}) px is not on the sphere fitted from every camera (a wrong "
                    "calibration, sphere radius or camera order?)", camera=c, frame=f)
            P_all.append(hit[0])
            R_all.append(hit[1])
            Rcov_all.append(_direction_cov(camera, highlights[f, c], C, C_cov, radius, highlight_sigma_px))
    P, R, Rcov = np.array(P_all), np.array(R_all), np.array(Rcov_all)
    if len(P) < 2:
        raise InputError("one reflected ray: a light needs two cameras, or one camera and two sphere positions")
    cosines = np.clip(R @ R.T, -1.0, 1.0)
    spread = float(np.degrees(np.arccos(cosines.min())))
    mean_direction = R.mean(axis=0)
    mean_direction /= np.linalg.norm(mean_direction)
    ray_angles = np.arccos(np.clip(R @ mean_direction, -1.0, 1.0))
    angular_sigma = np.sqrt(np.trace(Rcov, axis1=1, axis2=2) / 2.0)
    direction_sigma = float(np.degrees(np.sqrt(np.mean(angular_sigma ** 2) / len(R))))

    Q = np.eye(3)[None] - R[:, :, None] * R[:, None, :]
    A = Q.sum(axis=0)
    eig = np.linalg.eigvalsh(A)
    weak = ""
    X = None
    sigma_mm = np.full(3, np.inf)
    X_cov = np.full((3, 3), np.inf)
    if eig[0] > 1e-10 * len(R):
        X = np.linalg.solve(A, np.einsum("nij,nj->i", Q, P))
        L = np.einsum("nj,nj->n", X - P, R)
        A_inv = np.linalg.inv(A)
        middle = np.einsum("nij,njk,nkl->il", Q, Rcov * (L ** 2)[:, None, None], Q)
        X_cov = A_inv @ middle @ A_inv
        sigma_mm = np.sqrt(np.clip(np.linalg.eigvalsh(X_cov)[::-1], 0.0, None))
        distance = float(np.mean(np.abs(L)))
        if np.any(L <= 0):
            weak = "the rays' nearest point lies behind a mirror point: the rays are nearly parallel (a far light)"
        elif sigma_mm[0] > far_ratio * distance:
            weak = (f"the light's depth is uncertain by {sigma_mm[0]:.0f} mm at {distance:.0f} mm (rays spread "
                    f"{spread:.2f} deg): move the sphere across the capture volume for a point light")
    else:
        weak = "the reflected rays are parallel (a far light)"
    if kind == "point" and X is None:
        raise InputError("the reflected rays are parallel: no point light; calibrate it as directional")
    if kind == "point" or (kind == "auto" and not weak):
        light = Light("point", intensity=intensity, position=X)
        distances = np.linalg.norm(np.cross(X - P, R), axis=1)
    else:
        light = Light("directional", intensity=intensity, direction=-mean_direction)
        distances = np.sin(ray_angles) * 1000.0
    return LightCalibration(light, centres, centre_sigma, outlines_out, edge_rms, highlights, P, R, distances,
                            spread, X_cov, sigma_mm, direction_sigma, weak)

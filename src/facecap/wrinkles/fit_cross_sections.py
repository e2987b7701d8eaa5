"""Depth and width along valley splines from one image: the ratio fit of eq. 7 (Bickel et al. 2007, 5.2).

Every cross-section of a frame is fitted at once: the intensity profiles are
sampled perpendicular to the splines with one ``cv2.remap``, and Gauss-Newton
on ``(log w, d/w)`` runs batched (a 2x2 normal equation per cross-section,
3x3 with ``fit_offset``; the Jacobian by finite differences of the closed-form
eq. 6 of ``cross_section.py``), so a camera frame of about 100 cross-sections
costs 0.2 s where the paper's Matlab spent eight minutes. The model is the
paper's ``S`` with its bottom rounded (``rounding``, default 2; 0 is the
paper's exact ``S``): see ``docs/wrinkles.md`` for why and what it costs.
"""

from __future__ import annotations

from typing import Any, NamedTuple, Sequence

import numpy as np

from ..errors import InputError
from ..typing import BoolArray, FloatArray, IntArray
from .cross_section import wedge_intensity

__all__ = ["CrossSections", "ProfileFit", "fit_profiles", "sample_cross_sections", "fit_cross_sections",
           "CrossSectionSamples"]

DEFAULT_WIDTH_RANGE_MM = (0.3, 4.5)  # the bulge tops (about 1.55 w) stay inside the default +-7 mm
DEFAULT_HALF_EXTENT_MM = 7.0
DEFAULT_SAMPLE_STEP_MM = 0.1
DEFAULT_SECTION_SPACING_PX = 12.0
DEFAULT_BAND_PX = 9
DEFAULT_CHROMA_TOLERANCE = 0.06
DEFAULT_DETECTION_THRESHOLD = 100.0
DEFAULT_ROUNDING = 2.0
_GRID_WIDTHS = 8
_GRID_RATIOS = (0.0, 0.06, 0.14, 0.26, 0.42, 0.7)


class ProfileFit(NamedTuple):
    """Eq. 7 fitted to a batch of intensity profiles (one row each).

    Attributes
    ----------
    width : (n,) float64 array, mm
        Half-width ``w`` of ``S`` (its zero crossing); NaN where the profile had too few samples.
    depth : (n,) float64 array, mm
        Depth ``d``; 0 where no wrinkle is detected.
    has_wrinkle : (n,) bool array
        The fitted valley explains the profile significantly better than a flat surface.
    offset : (n,) float64 array, mm
        Where the valley line lies on the profile (0: where the spline put it).
    ambient : (n,) float64 array
        ``I_ambient`` in the image's units: the unshadowed level (the paper's ``I_obs(m)``).
    rms : (n,) float64 array
        RMS of the ratio residual of eq. 7 at the solution.
    iterations : int
        Gauss-Newton iterations run.
    """

    width: FloatArray
    depth: FloatArray
    has_wrinkle: BoolArray
    offset: FloatArray
    ambient: FloatArray
    rms: FloatArray
    iterations: int


class CrossSectionSamples(NamedTuple):
    """Intensity profiles sampled perpendicular to valley splines.

    Attributes
    ----------
    curve : (n,) int64 array
        Which input spline each cross-section lies on.
    centres_px : (n, 2) float64 array, px
        Cross-section centres ``(u, v)`` on the splines.
    normals_px : (n, 2) float64 array
        Unit image direction the profile is sampled along (perpendicular to the spline).
    mm_per_px : (n,) float64 array, mm/px
        Surface distance perpendicular to the 3D valley line per pixel along ``normals_px``
        (the large-scale surface's projection Jacobian at the centre); NaN where the ray misses.
    p : (k,) float64 array, mm
        Sample positions across the valley (the same for every cross-section).
    intensity : (n, k) float64 array
        Band-averaged intensity at ``p`` (projected on the paint's colour for colour images).
    valid : (n, k) bool array
        Inside the image, on the surface and on the same paint as the valley.
    noise : (n,) float64 array
        Standard deviation of the sensor's noise on ``intensity`` (the spread of the band's
        lines over the square root of their number; NaN for a band of one line).
    """

    curve: IntArray
    centres_px: FloatArray
    normals_px: FloatArray
    mm_per_px: FloatArray
    p: FloatArray
    intensity: FloatArray
    valid: BoolArray
    noise: FloatArray


class CrossSections(NamedTuple):
    """Cross-sections along valley splines in one image: where, and the fitted ``S(w, d, p)``.

    Attributes
    ----------
    samples : CrossSectionSamples
    fit : ProfileFit
    """

    samples: CrossSectionSamples
    fit: ProfileFit

    @property
    def width(self) -> FloatArray:
        """(n,) float64, mm: ``w`` per cross-section."""
        return self.fit.width

    @property
    def depth(self) -> FloatArray:
        """(n,) float64, mm: ``d`` per cross-section (0 where no wrinkle)."""
        return self.fit.depth


def _residuals(log_w: FloatArray, ratio: FloatArray, p: FloatArray, y: FloatArray,
               weights: FloatArray, rounding: float = 0.0) -> tuple[FloatArray, FloatArray]:
    """Weighted residual of eq. 7, the unshadowed level ``a + b p`` by least squares; and that level at p = 0.

    The level is linear across the profile because the large-scale surface's own
    curvature shades the neighbourhood unevenly (a nasolabial fold's cheek side
    sees more sky than its nose side).
    """
    w = np.exp(log_w)[:, None]
    model = wedge_intensity(p, w, ratio[:, None] * w, rounding=rounding)
    A = weights * model
    B = A * p
    wy = weights * y
    aa, ab, bb = (A * A).sum(1), (A * B).sum(1), (B * B).sum(1)
    ay, by = (A * wy).sum(1), (B * wy).sum(1)
    det = aa * bb - ab * ab
    ok = det > 1e-12 * np.maximum(aa * bb, 1e-300)
    safe = np.where(ok, det, 1.0)
    level = np.where(ok, (bb * ay - ab * by) / safe, ay / np.maximum(aa, 1e-300))
    trend = np.where(ok, (aa * by - ab * ay) / safe, 0.0)
    return wy - level[:, None] * A - trend[:, None] * B, level


def fit_profiles(p: object, intensity: object, *, valid: object = None, noise: object = None,
                 width_range_mm: tuple[float, float] = DEFAULT_WIDTH_RANGE_MM, iterations: int = 12,
                 detection_threshold: float = DEFAULT_DETECTION_THRESHOLD,
                 rounding: float = DEFAULT_ROUNDING, fit_offset: bool = False) -> ProfileFit:
    """Fit ``S(w, d, p)`` to intensity profiles across valleys: eq. 7 by batched Gauss-Newton.

    Parameters
    ----------
    p : (k,) or (n, k) array_like, mm
        Sample positions across each valley (0 on the valley line).
    intensity : (n, k) array_like
        Observed intensities (any linear unit: only ratios matter).
    valid : (n, k) bool array_like, optional
        Samples to use (default all finite ones).
    noise : (n,) array_like, optional
        Standard deviation of the noise on each sample (as
        :attr:`CrossSectionSamples.noise`); default: from the fit's residual.
    width_range_mm : (float, float), default (0.3, 4.5)
        Bounds of ``w``: the initial grid spans them and the iterations are clamped to them.
        A fit that ends at the upper bound is reported as no wrinkle (``d = 0``): the
        shading is broader than a valley whose bulges the profile holds (keep the upper
        bound below the profile's half extent over 1.6).
    iterations : int, default 12
        Gauss-Newton iterations after the grid.
    detection_threshold : float, default 100
        A wrinkle is reported where the fit lowers the sum of squares of a flat
        surface by more than this many times the noise variance (``noise``, or
        the residual's); elsewhere ``d = 0``. A likelihood-ratio test; 100 rather
        than a chi-square quantile because finely sampled pixels are correlated.
    rounding : float, default 2
        The valley bottom's rounding (:func:`~facecap.wrinkles.cross_section`); 0: the
        paper's ``S`` with its kink.
    fit_offset : bool, default False
        Also fit where the valley line lies across the profile (a third unknown, for
        splines off the valley); off by default: on the generated footage it changed
        nothing but the number of false wrinkles.

    Returns
    -------
    ProfileFit

    Notes
    -----
    Eq. 7 minimises ``sum_p (I_obs(p) / I_obs(m) - I(p))^2`` with ``I_obs(m)``
    the intensity at an unshadowed bulge point ``m``. One pixel's intensity
    carries its sensor noise into every ratio (at the footage's 0.5 % noise a
    shallow wrinkle's 5 % dip would be misjudged by a tenth), so here
    the unshadowed level is the least-squares ``a + b p`` given the current
    ``(w, d)`` (variable projection): the level every sample agrees on, ``a``
    being ``I_obs(m)`` without the noise (the model's ``I`` is 1 exactly at the
    bulge tops) and ``b`` the large scale's own uneven shading across the profile. The unknowns are ``log w`` and
    ``d / w`` (the intensity depends on the shape only through ``|p|/w`` and
    ``d/w``): an initial grid (8 widths x 6 ratios) then Gauss-Newton with
    step halving, ``d/w >= 0``.
    """
    Y = np.asarray(intensity, dtype=np.float64)
    if Y.ndim != 2:
        raise InputError(f"intensity: expected an (n, k) array, got shape {Y.shape}")
    n, k = Y.shape
    P = np.asarray(p, dtype=np.float64)
    if P.shape not in ((k,), (n, k)):
        raise InputError(f"p: expected shape ({k},) or ({n}, {k}), got {P.shape}")
    if P.ndim == 2:
        raise InputError("p: per-row sample positions are not supported; resample to one (k,) grid")
    mask = np.isfinite(Y) if valid is None else (np.asarray(valid, dtype=bool) & np.isfinite(Y))
    if mask.shape != Y.shape:
        raise InputError(f"valid: expected shape {Y.shape}, got {mask.shape}")
    w_lo, w_hi = (float(x) for x in width_range_mm)
    if not 0 < w_lo < w_hi:
        raise InputError(f"width_range_mm: expected 0 < low < high, got {width_range_mm!r}")
    weights = mask.astype(np.float64)
    y = np.where(mask, Y, 0.0)
    count = weights.sum(1)
    usable = count >= 8

    def residuals(theta: FloatArray) -> tuple[FloatArray, FloatArray]:
        shift = theta[:, 2:3] if fit_offset else np.zeros((1, 1))
        return _residuals(theta[:, 0], theta[:, 1], P[None, :] - shift, y, weights, rounding)

    # initial grid: every (w, d/w) pair for every profile at once, the best kept
    m = 3 if fit_offset else 2
    log_grid = np.linspace(np.log(w_lo * 1.2), np.log(w_hi / 1.2), _GRID_WIDTHS)
    best_cost = np.full(n, np.inf)
    theta = np.zeros((n, m))
    for lw in log_grid:
        for r in _GRID_RATIOS:
            trial = np.zeros((n, m))
            trial[:, 0], trial[:, 1] = lw, r
            res, _ = residuals(trial)
            cost = (res * res).sum(1)
            better = cost < best_cost
            best_cost = np.where(better, cost, best_cost)
            theta[better] = trial[better]

    steps = np.array([1e-4, 1e-5, 1e-4])[:m]  # forward-difference steps: log w, d/w, offset (mm)
    limits = np.array([0.5, 0.3, 0.3])[:m]  # largest step per iteration
    bounds = (np.log(w_lo), np.log(w_hi))
    res, _ = residuals(theta)
    cost = (res * res).sum(1)
    for _ in range(int(iterations)):
        J = np.empty((n, k, m))
        for j in range(m):
            moved = theta.copy()
            moved[:, j] += steps[j]
            J[:, :, j] = (residuals(moved)[0] - res) / steps[j]
        JtJ = np.einsum("nki,nkj->nij", J, J) + 1e-12 * np.eye(m)
        g = -np.einsum("nki,nk->ni", J, res)
        step = np.linalg.solve(JtJ, g[..., None])[..., 0]  # batched m x m normal equations
        step = np.clip(np.nan_to_num(step), -limits, limits)
        accepted = np.zeros(n, dtype=bool)
        scale = 1.0
        for _half in range(5):
            trial = theta + scale * step
            trial[:, 0] = np.clip(trial[:, 0], *bounds)
            trial[:, 1] = np.maximum(trial[:, 1], 0.0)
            if fit_offset:
                trial[:, 2] = np.clip(trial[:, 2], -np.exp(trial[:, 0]), np.exp(trial[:, 0]))
            trial_res, _ = residuals(trial)
            trial_cost = (trial_res * trial_res).sum(1)
            take = ~accepted & (trial_cost <= cost)
            theta[take] = trial[take]
            cost = np.where(take, trial_cost, cost)
            res = np.where(take[:, None], trial_res, res)
            accepted |= take
            if accepted.all():
                break
            scale *= 0.5

    log_w, ratio = theta[:, 0], theta[:, 1]
    offset = theta[:, 2] if fit_offset else np.zeros(n)
    res, ambient = residuals(theta)
    cost = (res * res).sum(1)
    flat = theta.copy()
    flat[:, 1] = 0.0
    flat_res, flat_ambient = residuals(flat)
    flat_cost = (flat_res * flat_res).sum(1)
    variance = cost / np.maximum(count - 3.0, 1.0)  # the residual's: noise and any mismatch of the model
    if noise is not None:
        measured = np.broadcast_to(np.asarray(noise, dtype=np.float64), (n,)) ** 2
        variance = np.where(np.isfinite(measured) & (measured > 0), measured, variance)
    noise = variance
    # a fit pinned at the widest width is shading broader than any valley the profile holds
    # (the large scale's own creases), not a wrinkle
    within = np.exp(log_w) < 0.98 * w_hi
    has_wrinkle = usable & within & (ratio > 0) & (flat_cost - cost > detection_threshold * np.maximum(noise, 1e-300))
    width = np.where(usable, np.exp(log_w), np.nan)
    depth = np.where(has_wrinkle, ratio * width, np.where(usable, 0.0, np.nan))
    ambient = np.where(has_wrinkle, ambient, flat_ambient)
    rms = np.sqrt(np.where(has_wrinkle, cost, flat_cost) / np.maximum(count, 1.0)) / np.maximum(ambient, 1e-300)
    return ProfileFit(width, depth, has_wrinkle, np.where(usable, offset, np.nan), np.where(usable, ambient, np.nan),
                      np.where(usable, rms, np.nan), int(iterations))


def _resample_polyline(points: FloatArray, spacing_px: float) -> tuple[FloatArray, FloatArray]:
    """Points every ``spacing_px`` along a polyline (ends excluded by half a spacing) and unit tangents."""
    seg = np.diff(points, axis=0)
    length = np.linalg.norm(seg, axis=1)
    keep = np.concatenate([[True], length > 1e-9])
    points = points[keep]
    seg = np.diff(points, axis=0)
    length = np.linalg.norm(seg, axis=1)
    arc = np.concatenate([[0.0], np.cumsum(length)])
    total = arc[-1]
    count = int(np.floor(total / spacing_px))
    if count < 1:
        return np.empty((0, 2)), np.empty((0, 2))
    s = (np.arange(count) + 0.5) * total / count
    centres = np.column_stack([np.interp(s, arc, points[:, 0]), np.interp(s, arc, points[:, 1])])
    # tangent from a chord of +-spacing/2: smoother than the segment a centre falls on
    half = 0.5 * spacing_px
    ahead = np.column_stack([np.interp(np.minimum(s + half, total), arc, points[:, 0]),
                             np.interp(np.minimum(s + half, total), arc, points[:, 1])])
    behind = np.column_stack([np.interp(np.maximum(s - half, 0.0), arc, points[:, 0]),
                              np.interp(np.maximum(s - half, 0.0), arc, points[:, 1])])
    tangent = ahead - behind
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    return centres, tangent


def _perpendicular_scale(camera: Any, points: FloatArray, normals: FloatArray, along_px: FloatArray,
                         across_px: FloatArray) -> FloatArray:
    """mm of surface distance perpendicular to the 3D valley line per pixel along ``across_px``."""
    helper = np.where(np.abs(normals[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    t1 = np.cross(normals, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(normals, t1)
    eps = 0.05  # mm: the projection is smooth at this scale, and far above round-off
    base = camera.project(points).pixels
    J = np.stack([(camera.project(points + eps * t1).pixels - base) / eps,
                  (camera.project(points + eps * t2).pixels - base) / eps], axis=2)  # (n, 2 px, 2 tangent)
    J_inv = np.linalg.inv(J)  # px -> mm in the tangent basis
    along = np.einsum("nij,nj->ni", J_inv, along_px)
    across = np.einsum("nij,nj->ni", J_inv, across_px)
    along /= np.linalg.norm(along, axis=1, keepdims=True)
    perpendicular = across - (across * along).sum(1, keepdims=True) * along
    return np.linalg.norm(perpendicular, axis=1)


def _surface_hits(surface: Any, camera: Any, pixels: FloatArray) -> tuple[FloatArray, FloatArray]:
    from ..cameras import RayCaster

    if isinstance(surface, RayCaster):
        caster = surface
    else:
        try:
            V, F = surface
        except (TypeError, ValueError):
            raise InputError("surface: expected a facecap.cameras.RayCaster or (V, F) in the camera's frame") from None
        caster = RayCaster(V, F)
    hits = caster.cast_pixels(camera, pixels)
    normals = hits.normals
    # the normal towards the camera, whatever the winding
    toward = camera.centre[None, :] - hits.points
    normals = np.where(((normals * toward).sum(1) < 0)[:, None], -normals, normals)
    return hits.points, normals


def sample_cross_sections(image: object, splines_px: Sequence[object], camera: Any, surface: Any, *,
                          spacing_px: float = DEFAULT_SECTION_SPACING_PX,
                          half_extent_mm: float = DEFAULT_HALF_EXTENT_MM,
                          step_mm: float = DEFAULT_SAMPLE_STEP_MM, band_px: int = DEFAULT_BAND_PX,
                          chroma_tolerance: float = DEFAULT_CHROMA_TOLERANCE) -> CrossSectionSamples:
    """Intensity profiles perpendicular to valley splines, on a common grid in mm across the valley.

    Parameters
    ----------
    image : (h, w) or (h, w, 3) array_like
        One linear image (float, or integer codes: only ratios matter) of ``camera``.
    splines_px : sequence of (m, 2) array_like, px
        Each valley as a polyline in the image (a tracked B-spline evaluated densely, or
        projected truth curves); ``(u, v)`` with (0, 0) the centre of the top-left pixel.
    camera : facecap.cameras.Camera
    surface : facecap.cameras.RayCaster or (V, F)
        The large-scale (unwrinkled) surface in the camera's (mocap) frame, mm: gives the
        pixel-to-mm scale across each valley.
    spacing_px : float, default 12
        Distance between cross-sections along a spline.
    half_extent_mm : float, default 7
        Profiles span ``[-half_extent_mm, half_extent_mm]`` across the valley.
    step_mm : float, default 0.1
    band_px : int, default 9
        Each profile averages this many parallel lines, 1 px apart along the spline (noise).
    chroma_tolerance : float, default 0.06
        Colour images: a sample counts only while its chromaticity ``rgb / sum(rgb)``
        stays this close to the valley's (the paint's: shading does not change it),
        walking out from the valley on each side.

    Returns
    -------
    CrossSectionSamples
    """
    import cv2

    from ..cameras import Camera

    if not isinstance(camera, Camera):
        raise InputError(f"camera: expected a facecap.cameras.Camera, got {type(camera).__name__}")
    img = np.asarray(image)
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] not in (1, 3)):
        raise InputError(f"image: expected (h, w) or (h, w, 3), got shape {img.shape}")
    img = img.astype(np.float32)
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[..., 0]
    if band_px < 1 or spacing_px <= 0 or half_extent_mm <= 0 or step_mm <= 0:
        raise InputError("band_px, spacing_px, half_extent_mm, step_mm: expected positive values")
    centres, tangents, curve = [], [], []
    for index, spline in enumerate(splines_px):
        pts = np.asarray(spline, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] < 2 or not np.isfinite(pts).all():
            raise InputError(f"splines_px[{index}]: expected a finite (m >= 2, 2) polyline, got shape {pts.shape}")
        c, t = _resample_polyline(pts, float(spacing_px))
        centres.append(c)
        tangents.append(t)
        curve.append(np.full(c.shape[0], index, dtype=np.int64))
    C = np.concatenate(centres) if centres else np.empty((0, 2))
    U = np.concatenate(tangents) if tangents else np.empty((0, 2))
    curve_index = np.concatenate(curve) if curve else np.empty(0, dtype=np.int64)
    N = np.column_stack([-U[:, 1], U[:, 0]])
    p = np.arange(-half_extent_mm, half_extent_mm + step_mm / 2, step_mm)
    n, k = C.shape[0], p.size
    if n == 0:
        empty = np.empty((0, k))
        return CrossSectionSamples(curve_index, C, N, np.empty(0), p, empty, empty.astype(bool), np.empty(0))

    points, normals = _surface_hits(surface, camera, C)
    scale = np.full(n, np.nan)
    on_surface = np.isfinite(points).all(1)
    if on_surface.any():
        scale[on_surface] = _perpendicular_scale(camera, points[on_surface], normals[on_surface],
                                                 U[on_surface], N[on_surface])
    offsets_px = p[None, :] / np.where(on_surface, scale, 1.0)[:, None]  # (n, k)
    band = np.arange(band_px) - (band_px - 1) / 2.0
    # (band, n, k, 2) pixel positions, one remap for everything
    where = (C[None, :, None, :] + offsets_px[None, :, :, None] * N[None, :, None, :]
             + band[:, None, None, None] * U[None, :, None, :])
    map_u = where[..., 0].reshape(band_px, -1).astype(np.float32)
    map_v = where[..., 1].reshape(band_px, -1).astype(np.float32)
    sampled = cv2.remap(img, map_u, map_v, interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                        borderValue=np.nan)
    lines = sampled.reshape((band_px, n, k) + img.shape[2:])
    sampled = lines.mean(axis=0)
    height, width = img.shape[:2]
    inside = ((where[..., 0] >= 0) & (where[..., 0] <= width - 1) & (where[..., 1] >= 0)
              & (where[..., 1] <= height - 1)).all(axis=0)
    valid = inside & on_surface[:, None] & np.isfinite(sampled.reshape(n, k, -1)).all(-1)
    if img.ndim == 3:
        total = sampled.sum(-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            chroma = sampled / total[..., None]
        centre = np.abs(p) <= max(0.5, 2 * step_mm)
        reference = np.nanmedian(np.where(centre[None, :, None], chroma, np.nan), axis=1)  # (n, 3)
        same_paint = np.abs(chroma - reference[:, None, :]).max(-1) <= chroma_tolerance
        # walk out from the valley on each side: the first foreign sample ends the profile there
        middle = int(np.argmin(np.abs(p)))
        right = np.cumprod(same_paint[:, middle:], axis=1).astype(bool)
        left = np.cumprod(same_paint[:, : middle + 1][:, ::-1], axis=1).astype(bool)[:, ::-1]
        contiguous = np.concatenate([left[:, :-1], right], axis=1)
        valid &= contiguous
        direction = reference / np.linalg.norm(reference, axis=1, keepdims=True)
        intensity = (sampled * direction[:, None, :]).sum(-1)
        line_intensity = (lines * direction[None, :, None, :]).sum(-1)
    else:
        intensity = sampled
        line_intensity = lines
    # the sensor's noise on a band average, from the spread of its lines (the valley barely changes
    # over a band): independent of any model, it decides whether a fitted valley is real
    if band_px > 1:
        spread = np.where(valid, line_intensity.std(axis=0, ddof=1), np.nan)
        with np.errstate(all="ignore"):
            noise = np.nanmedian(spread, axis=1) / np.sqrt(band_px)
    else:
        noise = np.full(n, np.nan)
    intensity = np.where(valid, intensity, np.nan).astype(np.float64)
    return CrossSectionSamples(curve_index, C, N, scale, p, intensity, valid, noise)


def fit_cross_sections(image: object, splines_px: Sequence[object], camera: Any, surface: Any, *,
                       spacing_px: float = DEFAULT_SECTION_SPACING_PX,
                       half_extent_mm: float = DEFAULT_HALF_EXTENT_MM, step_mm: float = DEFAULT_SAMPLE_STEP_MM,
                       band_px: int = DEFAULT_BAND_PX, chroma_tolerance: float = DEFAULT_CHROMA_TOLERANCE,
                       width_range_mm: tuple[float, float] = DEFAULT_WIDTH_RANGE_MM, iterations: int = 12,
                       detection_threshold: float = DEFAULT_DETECTION_THRESHOLD,
                       rounding: float = DEFAULT_ROUNDING, fit_offset: bool = False) -> CrossSections:
    """Depth and width of the valley along every spline of one image (Bickel et al. 2007, 5.2).

    :func:`sample_cross_sections` then :func:`fit_profiles`; the options are theirs.

    Parameters
    ----------
    image : (h, w) or (h, w, 3) array_like
        Linear intensities (uniform ambient light, diffuse paint on the valleys).
    splines_px : sequence of (m, 2) array_like, px
        Valley polylines in the image.
    camera : facecap.cameras.Camera
    surface : facecap.cameras.RayCaster or (V, F)
        The large-scale surface in the camera's frame, mm.

    spacing_px, half_extent_mm, step_mm, band_px, chroma_tolerance
        See :func:`sample_cross_sections`.
    width_range_mm, iterations, detection_threshold, rounding, fit_offset
        See :func:`fit_profiles`.

    Returns
    -------
    CrossSections
        ``width`` and ``depth`` in mm on the surface (``d = 0`` where no wrinkle), per
        cross-section, with where they were taken.
    """
    samples = sample_cross_sections(image, splines_px, camera, surface, spacing_px=spacing_px,
                                    half_extent_mm=half_extent_mm, step_mm=step_mm, band_px=band_px,
                                    chroma_tolerance=chroma_tolerance)
    fit = fit_profiles(samples.p, samples.intensity, valid=samples.valid, noise=samples.noise,
                       width_range_mm=width_range_mm,
                       iterations=iterations, detection_threshold=detection_threshold, rounding=rounding,
                       fit_offset=fit_offset)
    return CrossSections(samples, fit)

"""A wrinkle valley as a smooth 2D curve: the weighted uniform cubic B-spline of Bickel et al. (2007), eq. 5."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError
from ..typing import FloatArray

__all__ = ["WrinkleSpline", "fit_wrinkle_spline", "darkness_weights", "control_points_for_length"]

MIN_CONTROL_POINTS = 5
MAX_CONTROL_POINTS = 12


@dataclass(frozen=True)
class WrinkleSpline:
    """A uniform cubic B-spline ``v(x)`` in image space over the patch's principal axis.

    Attributes
    ----------
    control_points : (n, 2) float64 array, px
        ``(u, v)`` of the control points, OpenCV's pixel convention (centre of the top-left
        pixel at (0, 0)).
    x_range : (2,) float64 array, px
        The parameter interval ``[x_lo, x_hi]`` the knots span: positions along the axis.
    origin : (2,) float64 array, px
        The patch's mean pixel ``p_bar``.
    axis : (2,) float64 array
        The patch's principal axis ``a`` (unit; ``x = (p - p_bar) . a``).
    half_width : float, px
        The painted stripe's half-width, from the spread of the pixels about the curve
        (``sqrt(3)`` times their RMS distance: a uniform band).
    """

    control_points: FloatArray
    x_range: FloatArray
    origin: FloatArray
    axis: FloatArray
    half_width: float

    @property
    def n_control(self) -> int:
        return int(self.control_points.shape[0])

    @property
    def elongation(self) -> float:
        """Length over width, ``(x_hi - x_lo) / (2 half_width)``: a valley-shaped patch is long and thin;
        one near 1-2 is cut short (by the face's silhouette, the image border) or seen end-on, and
        its principal axis need not follow the wrinkle."""
        return float((self.x_range[1] - self.x_range[0]) / max(2.0 * self.half_width, 1e-9))

    def knots(self) -> FloatArray:
        return _uniform_knots(self.x_range[0], self.x_range[1], self.n_control)

    def evaluate(self, x: Any) -> FloatArray:
        """``v(x)``: (m,) axis positions (px, clipped to ``x_range``) -> (m, 2) pixels."""
        X = np.clip(np.atleast_1d(np.asarray(x, dtype=np.float64)), self.x_range[0], self.x_range[1])
        return _design(X, self.knots(), self.n_control) @ self.control_points

    def sample(self, n: int = 64, *, trim: float = 0.0) -> FloatArray:
        """``n`` points evenly spaced in ``x`` over ``x_range`` less ``trim`` px at each end: (n, 2) px."""
        lo, hi = self.x_range[0] + trim, self.x_range[1] - trim
        if hi <= lo:
            lo = hi = 0.5 * (self.x_range[0] + self.x_range[1])
        return self.evaluate(np.linspace(lo, hi, n))


def _uniform_knots(lo: float, hi: float, n_control: int) -> FloatArray:
    spans = n_control - 3
    h = (hi - lo) / spans
    return lo + h * np.arange(-3, spans + 4, dtype=np.float64)


def _design(x: FloatArray, knots: FloatArray, n_control: int) -> FloatArray:
    from scipy.interpolate import BSpline

    # the last knot span is closed: x == x_hi belongs to it
    x = np.minimum(x, np.nextafter(knots[n_control], -np.inf))
    return BSpline.design_matrix(x, knots, 3).toarray()


def control_points_for_length(length_px: float, *, spacing_px: float = 30.0) -> int:
    """Control points for a patch ``length_px`` long: one per ``spacing_px`` plus the ends, within 5-12.

    Examples
    --------
    >>> control_points_for_length(60.0), control_points_for_length(300.0), control_points_for_length(900.0)
    (5, 11, 12)
    """
    return int(np.clip(round(length_px / spacing_px) + 1, MIN_CONTROL_POINTS, MAX_CONTROL_POINTS))


def darkness_weights(gray: Any, *, floor: float = 0.05) -> FloatArray:
    """The paper's weights, inversely proportional to the grey level: ``(g_max - g_min) / (g - g_min)``.

    Parameters
    ----------
    gray : (k,) float array
        Grey level of each patch pixel.
    floor : float, default 0.05
        Added to ``(g - g_min) / (g_max - g_min)`` before dividing, so the darkest pixel
        weighs ``1 / floor`` rather than infinity; ``g_min`` and ``g_max`` are the 1st and 99th
        percentiles (one noisy pixel does not set them).

    Returns
    -------
    (k,) float64 array
        In ``[1 / (1 + floor), 1 / floor]``.
    """
    g = np.asarray(gray, dtype=np.float64)
    lo, hi = np.percentile(g, [1.0, 99.0])
    span = max(hi - lo, 1e-9)
    return 1.0 / (np.clip((g - lo) / span, 0.0, 1.0) + floor)


def fit_wrinkle_spline(pixels: Any, weights: Any = None, *, n_control: int | None = None,
                       spacing_px: float = 30.0, smoothing: float = 1e-6) -> WrinkleSpline:
    """Fit the valley spline of eq. 5 to a patch of wrinkle pixels.

    Parameters
    ----------
    pixels : (k, 2) float array, px
        ``(u, v)`` of the patch's pixels.
    weights : (k,) float array, optional
        ``w_i`` of eq. 5 (e.g. :func:`darkness_weights`); uniform if not given.
    n_control : int, optional
        Control points (5-12); by the patch's length (:func:`control_points_for_length`) if not given.
    spacing_px : float, default 30.0
        Passed to :func:`control_points_for_length`.
    smoothing : float, default 1e-6
        Weight, relative to the data term's, of the control polygon's second differences
        (keeps a knot span with few pixels determined; negligible otherwise).

    Returns
    -------
    WrinkleSpline

    Raises
    ------
    InputError
        If fewer than 8 pixels are given or the weights do not match.

    Notes
    -----
    PCA of the pixels gives the mean ``p_bar`` and principal axis ``a``; each pixel's parameter
    is ``x_i = (p_i - p_bar)^T a``, and the control points minimise

    .. math:: E_{spline} = \\sum_i w_i \\| p_i - v(x_i) \\|^2 \\qquad (5)

    with ``v`` a uniform cubic B-spline over ``[min x_i, max x_i]``: a linear least-squares
    problem. The axis points along +u (or +v when vertical) so a wrinkle keeps its direction
    from frame to frame.
    """
    P = np.asarray(pixels, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 2:
        raise InputError(f"pixels: expected (k, 2) pixel positions, got shape {P.shape}")
    if P.shape[0] < 8:
        raise InputError(f"pixels: {P.shape[0]} pixels are too few for a spline (8 or more)")
    w = np.ones(P.shape[0]) if weights is None else np.asarray(weights, dtype=np.float64)
    if w.shape != (P.shape[0],) or not np.all(np.isfinite(w)) or np.any(w < 0):
        raise InputError(f"weights: expected {P.shape[0]} finite non-negative values, got shape {w.shape}")
    origin = P.mean(axis=0)
    centred = P - origin
    _, vectors = np.linalg.eigh(centred.T @ centred)
    axis = vectors[:, -1]
    if axis[0] < -1e-9 or (abs(axis[0]) <= 1e-9 and axis[1] < 0):
        axis = -axis
    x = centred @ axis
    lo, hi = float(x.min()), float(x.max())
    if hi - lo < 1e-6:
        raise InputError("pixels: the patch has no extent along its axis")
    n = control_points_for_length(hi - lo, spacing_px=spacing_px) if n_control is None else int(n_control)
    if not MIN_CONTROL_POINTS <= n <= MAX_CONTROL_POINTS:
        raise InputError(f"n_control: expected {MIN_CONTROL_POINTS}-{MAX_CONTROL_POINTS}, got {n}")
    from scipy.interpolate import BSpline

    knots = _uniform_knots(lo, hi, n)
    B = BSpline.design_matrix(np.minimum(x, np.nextafter(knots[n], -np.inf)), knots, 3)  # sparse, 4 per row
    w = w / w.sum()
    D2 = np.diff(np.eye(n), 2, axis=0)
    # the normal equations of eq. 5: (B^T W B + s D2^T D2) c = B^T W p, an n x n solve (n <= 12)
    normal = (B.T @ B.multiply(w[:, None])).toarray() + smoothing * (D2.T @ D2)
    control = np.linalg.solve(normal, B.T @ (w[:, None] * P))
    residual = P - B @ control
    rms = np.sqrt(np.mean(np.sum(residual**2, axis=1)))
    return WrinkleSpline(control_points=control, x_range=np.array([lo, hi]), origin=origin, axis=axis,
                         half_width=float(np.sqrt(3.0) * rms))

"""The wrinkle cross-section of Bickel et al. 2007 (section 5.2) and its sky-lit intensity (eq. 6).

The valley model is ``S(w, d, p) = d (|p|/w - 1) exp(-|p|/w)``: depth ``d``
(the valley bottom ``S(0) = -d``), half-width ``w`` (the zero crossing
``S(+-w) = 0``), bulges ``d e^-2`` high at ``|p| = 2 w``. Under a uniform sky
a Lambertian point of an extruded (2.5D) profile sees the sky through a
*wedge* between its two horizons, and eq. 6 reduces to a closed form: with
the horizon elevations ``e_left``, ``e_right`` and the tilt ``tau`` of the
normal,

    I / I_ambient = (cos(e_left + tau) + cos(e_right - tau)) / 2,

(the cosine-weighted integral over the wedge; 1 on a flat plane). Because
``S`` scales with ``d`` in height and ``w`` in width, the horizon *slopes*
of the unit profile ``s(q) = (|q| - 1) e^-|q|`` do not depend on ``d/w``:
they are tabulated once over ``q = |p|/w`` (:func:`_horizon_slopes`) and
the intensity is exact arithmetic on them for any ``(w, d)``, vectorised.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..errors import InputError
from ..typing import FloatArray

__all__ = ["cross_section", "wedge_intensity", "profile_sky_visibility"]

_TABLE_MAX_Q = 16.0  # beyond it the unit profile is below 2e-6: flat for the horizon
_TABLE_STEP = 1.0 / 256.0


def cross_section(p: object, w: object, d: object, *, rounding: float = 0.0) -> FloatArray:
    """Height of the wrinkle model ``S(w, d, p) = d (|p|/w - 1) exp(-|p|/w)`` (Bickel et al. 2007).

    Parameters
    ----------
    p : array_like, mm
        Signed distance from the valley line, orthogonal to it.
    w : array_like, mm
        Half-width (``S(+-w) = 0``); > 0. Broadcast against ``p``.
    d : array_like, mm
        Depth (``S(0) = -d``). Broadcast against ``p``.

    Returns
    -------
    float64 array, mm
        Height above the unwrinkled surface (negative in the valley).

    Examples
    --------
    >>> float(cross_section(0.0, 2.0, 0.5)), float(cross_section(2.0, 2.0, 0.5))
    (-0.5, 0.0)
    """
    q = np.asarray(p, dtype=np.float64) / np.asarray(w, dtype=np.float64)
    return np.asarray(d, dtype=np.float64) * _unit_profile(q, float(rounding))


def _rounded_distance(q: FloatArray, rounding: float) -> FloatArray:
    """``rho(q)``: ``|q|`` (rounding 0) or its hyperbolic rounding, scaled so ``rho = 1`` at ``|q| = 1``."""
    a = np.abs(q)
    if rounding == 0.0:
        return a
    scale = np.sqrt(1.0 + 2.0 * rounding)  # keeps the zero crossing at |q| = 1
    return np.sqrt((a * scale) ** 2 + rounding**2) - rounding


def _unit_profile(q: FloatArray, rounding: float = 0.0) -> FloatArray:
    rho = _rounded_distance(q, rounding)
    return (rho - 1.0) * np.exp(-rho)


def _unit_slope(q: FloatArray, rounding: float = 0.0) -> FloatArray:
    """ds/dq of the unit profile for q >= 0 (without rounding the one-sided limit 2 at the kink q = 0)."""
    rho = _rounded_distance(q, rounding)
    if rounding == 0.0:
        return (2.0 - q) * np.exp(-q)
    scale2 = 1.0 + 2.0 * rounding
    drho = scale2 * q / (rho + rounding)
    return (2.0 - rho) * np.exp(-rho) * drho


def profile_sky_visibility(p: object, h: object) -> FloatArray:
    """Eq. 6 on any sampled 2.5D profile: the cosine-weighted sky each sample sees (brute force).

    For each sample ``(p_i, h_i)`` the horizon on each side is the steepest
    elevation to any other sample on that side (never below the point's own
    tangent nor the flat far field), and the visible wedge between the two
    horizons is integrated in closed form. ``O(n^2)``: a reference, not the
    fitter's path.

    Parameters
    ----------
    p : (n,) array_like, mm
        Increasing sample positions across the wrinkle.
    h : (n,) array_like, mm
        Heights at ``p``.

    Returns
    -------
    (n,) float64 array
        ``I / I_ambient`` in [0, 1].
    """
    P = np.asarray(p, dtype=np.float64)
    H = np.asarray(h, dtype=np.float64)
    if P.ndim != 1 or P.shape != H.shape or P.size < 3 or np.any(np.diff(P) <= 0):
        raise InputError(f"p, h: expected two (n,) arrays, n >= 3, p increasing; got {P.shape}, {H.shape}")
    slope = np.gradient(H, P)
    dp = P[None, :] - P[:, None]
    dh = H[None, :] - H[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        rise = dh / np.abs(dp)
    right = np.where(dp > 0, rise, -np.inf).max(axis=1)
    left = np.where(dp < 0, rise, -np.inf).max(axis=1)
    right = np.maximum(np.maximum(right, slope), 0.0)
    left = np.maximum(np.maximum(left, -slope), 0.0)
    return _wedge(left, right, slope)


def _wedge(left_slope: FloatArray, right_slope: FloatArray, surface_slope: FloatArray) -> FloatArray:
    """(cos(e_l + tau) + cos(e_r - tau)) / 2 from the tangents of the horizons and of the surface."""
    norm_t = np.sqrt(1.0 + surface_slope**2)
    left = (1.0 - left_slope * surface_slope) / (np.sqrt(1.0 + left_slope**2) * norm_t)
    right = (1.0 + right_slope * surface_slope) / (np.sqrt(1.0 + right_slope**2) * norm_t)
    return 0.5 * (left + right)


@lru_cache(maxsize=8)
def _horizon_slopes(rounding: float = 0.0) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Horizon slopes of the unit profile at q >= 0: (q grid, toward +q, toward -q).

    ``max over q' of (s(q') - s(q)) / |q' - q|`` on each side, at least the
    point's own tangent (the limit q' -> q) and 0 (the flat far field).
    Computed once (about 0.3 s) on a 1/256 grid, q' on a finer grid near q.
    """
    q = np.arange(0.0, _TABLE_MAX_Q + _TABLE_STEP / 2, _TABLE_STEP)
    # candidate q': fine (1/1024) within 4 of 0 where the profile bends, coarser beyond
    far = np.concatenate([np.arange(0.0, 4.0, 1.0 / 1024.0), np.arange(4.0, 3 * _TABLE_MAX_Q, 1.0 / 64.0)])
    candidates = np.concatenate([-far[::-1], far[1:]])
    s_c = _unit_profile(candidates, rounding)
    s_q = _unit_profile(q, rounding)
    right = np.empty_like(q)
    left = np.empty_like(q)
    for start in range(0, q.size, 256):
        block = slice(start, start + 256)
        dq = candidates[None, :] - q[block, None]
        ds = s_c[None, :] - s_q[block, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            rise = ds / np.abs(dq)
        right[block] = np.where(dq > 0, rise, -np.inf).max(axis=1)
        left[block] = np.where(dq < 0, rise, -np.inf).max(axis=1)
    tangent = _unit_slope(q, rounding)
    right = np.maximum(np.maximum(right, tangent), 0.0)
    left = np.maximum(np.maximum(left, -tangent), 0.0)
    return q, right, left


def wedge_intensity(p: object, w: object, d: object, *, rounding: float = 0.0) -> FloatArray:
    """Eq. 6 for the model ``S(w, d, p)``: the fraction of the ambient light reaching each point.

    The 2.5D integral of Bickel et al. (2007) over the spherical wedge
    between the point's horizons, ``(1/pi) int V(p, omega) (n . omega) d omega``,
    in closed form on tabulated horizon slopes (see the module notes):
    vectorised over any broadcast shape of ``p``, ``w``, ``d``.

    Parameters
    ----------
    p : array_like, mm
        Signed distance from the valley line.
    w : array_like, mm
        Half-width, > 0.
    d : array_like, mm
        Depth, >= 0 (0: a flat surface, intensity 1).

    Returns
    -------
    float64 array
        ``I(p) / I_ambient`` in (0, 1]; symmetric in ``p``; 1 at the bulge tops ``|p| = 2 w``.

    Notes
    -----
    The horizon slopes are linear interpolation in a 1/256 table of
    ``q = |p|/w`` (and 0 beyond ``q = 16``); against the brute force
    :func:`profile_sky_visibility` the intensity agrees to about 1e-5
    (tested). At the kink ``p = 0`` the one-sided limit is used.

    Examples
    --------
    >>> round(float(wedge_intensity(4.0, 2.0, 0.5)), 6)  # the bulge top: the whole sky
    1.0
    >>> float(wedge_intensity(0.0, 2.0, 0.0))
    1.0
    """
    grid, right_t, left_t = _horizon_slopes(float(rounding))
    q = np.abs(np.asarray(p, dtype=np.float64)) / np.asarray(w, dtype=np.float64)
    ratio = np.asarray(d, dtype=np.float64) / np.asarray(w, dtype=np.float64)
    right = np.interp(q, grid, right_t, right=0.0)
    left = np.interp(q, grid, left_t, right=0.0)
    slope = _unit_slope(q, float(rounding))
    return _wedge(ratio * left, ratio * right, ratio * slope)

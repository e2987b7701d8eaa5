"""The anisotropic muscle term: passive and active force-length curves along a fibre direction.

Blemker, Pinsky and Delp 2005's along-fibre model, the one Teran et al. 2003/2005 and
Sifakis et al. 2005 use: with fibre stretch ``lambda = |F d|`` (``d`` the unit rest fibre
direction) and normalised stretch ``s = lambda / lambda_ofl``, the fibre stress is

    sigma_max * (f_passive(s) + a * f_active(s))

and the energy density (kPa) is its integral from the rest length,
``psi(lambda) = sigma_max * lambda_ofl * (Phi_passive(s) + a * Phi_active(s))`` with
``Phi(s) = int_1^s f(t) dt``. The activation ``a`` enters linearly, so the nodal force
is affine in the activations (Sifakis et al. 2005, eq. 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..typing import FloatArray
from .mooney_rivlin import StressResponse

__all__ = ["MuscleFibre", "active_force_length", "passive_force_length", "fibre_response"]


@dataclass(frozen=True)
class MuscleFibre:
    """Constants of the along-fibre muscle response (Blemker, Pinsky and Delp 2005).

    Parameters
    ----------
    max_stress_kpa : float, kPa
        ``sigma_max``, the peak isometric stress of fully activated fibres at optimal
        length. Default 300 kPa (Blemker et al. 2005; Zajac 1989 quotes 200-350 kPa for
        skeletal muscle). A model scales it per muscle (Sifakis et al. 2005 scaled each
        muscle's strength by hand) through ``FleshModel``'s ``muscle_strength``.
    optimal_stretch : float
        ``lambda_ofl``, the fibre stretch of optimal length relative to the rest mesh.
        Default 1 (the rest pose is at optimal length).
    passive_scale, passive_exponent, passive_linear_stretch : float
        ``P1, P2, lambda*`` of the passive curve ``P1 (exp(P2 (s - 1)) - 1)`` for
        ``1 < s < lambda*``, linear beyond (C1). Defaults 0.05, 6.6 and 1.4 (Blemker et al.).
    """

    max_stress_kpa: float = 300.0
    optimal_stretch: float = 1.0
    passive_scale: float = 0.05
    passive_exponent: float = 6.6
    passive_linear_stretch: float = 1.4

    def __post_init__(self) -> None:
        if not (np.isfinite(self.max_stress_kpa) and self.max_stress_kpa >= 0):
            raise InputError(f"max_stress_kpa: expected a finite value >= 0, got {self.max_stress_kpa!r}")
        if not (np.isfinite(self.optimal_stretch) and self.optimal_stretch > 0):
            raise InputError(f"optimal_stretch: expected a positive value, got {self.optimal_stretch!r}")
        if not (self.passive_scale >= 0 and self.passive_exponent > 0 and self.passive_linear_stretch > 1):
            raise InputError("passive curve: expected passive_scale >= 0, passive_exponent > 0, "
                             "passive_linear_stretch > 1")


# Blemker et al. 2005's active curve: 9 (s - 0.4)^2 on [0.4, 0.6], 1 - 4 (1 - s)^2 on
# [0.6, 1.4], 9 (s - 1.6)^2 on [1.4, 1.6], zero outside [0.4, 1.6]. Its antiderivative
# from 0.4, at the two joins, so that Phi_active is continuous:
_A06 = 3.0 * 0.2**3
_A14 = _A06 + 0.8 + 4.0 / 3.0 * ((-0.4) ** 3 - 0.4**3)


def _active_antiderivative(s: FloatArray) -> FloatArray:
    s = np.clip(s, 0.4, 1.6)
    low = 3.0 * (s - 0.4) ** 3
    mid = _A06 + (s - 0.6) + 4.0 / 3.0 * ((1.0 - s) ** 3 - 0.4**3)
    high = _A14 + 3.0 * (s - 1.6) ** 3 + 3.0 * 0.2**3
    return np.where(s <= 0.6, low, np.where(s < 1.4, mid, high))


_ACTIVE_AT_REST = float(_active_antiderivative(np.array(1.0)))


def active_force_length(stretch: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Blemker et al. 2005's active force-length curve, its slope and its integral from 1.

    Parameters
    ----------
    stretch : float64 array
        Normalised fibre stretch ``s = lambda / lambda_ofl``.

    Returns
    -------
    value, slope, integral : float64 arrays like ``stretch``
        ``f_active(s)`` (1 at ``s = 1``, 0 outside [0.4, 1.6]), ``f_active'(s)`` and
        ``Phi_active(s) = int_1^s f_active``.

    Examples
    --------
    >>> import numpy as np
    >>> v, d, i = active_force_length(np.array([1.0, 0.5, 2.0]))
    >>> np.round(v, 3).tolist()
    [1.0, 0.09, 0.0]
    """
    s = np.asarray(stretch, dtype=np.float64)
    low, high = (s > 0.4) & (s <= 0.6), (s >= 1.4) & (s < 1.6)
    mid = (s > 0.6) & (s < 1.4)
    value = np.where(low, 9.0 * (s - 0.4) ** 2, np.where(mid, 1.0 - 4.0 * (1.0 - s) ** 2,
                                                         np.where(high, 9.0 * (s - 1.6) ** 2, 0.0)))
    slope = np.where(low, 18.0 * (s - 0.4), np.where(mid, 8.0 * (1.0 - s), np.where(high, 18.0 * (s - 1.6), 0.0)))
    return value, slope, _active_antiderivative(s) - _ACTIVE_AT_REST


def passive_force_length(stretch: FloatArray, fibre: MuscleFibre = MuscleFibre()) -> tuple[FloatArray, FloatArray,
                                                                                             FloatArray]:
    """Blemker et al. 2005's passive fibre curve, its slope and its integral from 1.

    Parameters
    ----------
    stretch : float64 array
        Normalised fibre stretch ``s``.
    fibre : MuscleFibre
        Supplies ``P1, P2, lambda*``.

    Returns
    -------
    value, slope, integral : float64 arrays like ``stretch``
        Zero for ``s <= 1`` (fibres carry no passive load in compression).
    """
    s = np.asarray(stretch, dtype=np.float64)
    p1, p2, s_lin = fibre.passive_scale, fibre.passive_exponent, fibre.passive_linear_stretch
    p3 = p1 * p2 * np.exp(p2 * (s_lin - 1.0))
    value_lin = p1 * (np.exp(p2 * (s_lin - 1.0)) - 1.0)
    integral_lin = p1 * ((np.exp(p2 * (s_lin - 1.0)) - 1.0) / p2 - (s_lin - 1.0))
    se = np.clip(s, 1.0, s_lin)
    e = np.exp(p2 * (se - 1.0))
    stretched, linear = (s > 1.0) & (s < s_lin), s >= s_lin
    value = np.where(stretched, p1 * (e - 1.0), np.where(linear, value_lin + p3 * (s - s_lin), 0.0))
    slope = np.where(stretched, p1 * p2 * e, np.where(linear, p3, 0.0))
    integral = np.where(stretched, p1 * ((e - 1.0) / p2 - (se - 1.0)),
                        np.where(linear, integral_lin + value_lin * (s - s_lin) + 0.5 * p3 * (s - s_lin) ** 2, 0.0))
    return value, slope, integral


def fibre_response(F: FloatArray, directions: FloatArray, passive_weight: FloatArray, active_weight: FloatArray,
                   fibre: MuscleFibre = MuscleFibre(), *, derivatives: int = 2) -> StressResponse:
    """The fibre term's energy density, stress and stress derivative for a batch of fibres.

    Parameters
    ----------
    F : (p, 3, 3) float64 array
        Deformation gradient of each fibre's tetrahedron.
    directions : (p, 3) float64 array
        Unit rest fibre directions.
    passive_weight, active_weight : (p,) float64 arrays
        Multipliers of the passive and active curves (volume fraction x strength x
        force-length scale; the active one also x activation).
    fibre : MuscleFibre
    derivatives : {0, 1, 2}, default 2

    Returns
    -------
    StressResponse
        ``energy_density (p,)``, ``stress (p, 3, 3)``, ``stress_derivative (p, 9, 9)``, kPa.

    Notes
    -----
    With ``q = F d``, ``lambda = |q|`` and ``n = q d^T / lambda``: ``P = psi'(lambda) n`` and
    ``d2 psi / dF dF = psi'' n (x) n + psi' / lambda (I (x) d d^T - n (x) n)``. Both curves
    vanish near ``lambda = 0`` (active below 0.4, passive below 1), so the ``1 / lambda``
    is never reached with a non-zero multiplier.
    """
    F = np.asarray(F, dtype=np.float64)
    d = np.asarray(directions, dtype=np.float64)
    ofl, smax = fibre.optimal_stretch, fibre.max_stress_kpa
    q = (F @ d[:, :, None])[:, :, 0]
    stretch = np.sqrt((q * q).sum(axis=1))
    s = stretch / ofl
    fa, dfa, ia = active_force_length(s)
    fp, dfp, ip = passive_force_length(s, fibre)
    psi = smax * ofl * (passive_weight * ip + active_weight * ia)
    if derivatives == 0:
        return StressResponse(psi, None, None)
    dpsi = smax * (passive_weight * fp + active_weight * fa)
    safe = np.maximum(stretch, 1e-12)
    n = (q / safe[:, None])[:, :, None] * d[:, None, :]
    P = dpsi[:, None, None] * n
    if derivatives == 1:
        return StressResponse(psi, P, None)
    d2psi = smax / ofl * (passive_weight * dfp + active_weight * dfa)
    m = F.shape[0]
    nf = n.reshape(m, 9)
    nn = nf[:, :, None] * nf[:, None, :]
    dd = d[:, :, None] * d[:, None, :]
    A = (d2psi - dpsi / safe)[:, None, None] * nn
    # + psi' / lambda * (d_ik d_j d_l): the block diagonal of three copies of d d^T
    blocks = A.reshape(m, 3, 3, 3, 3)
    scaled = (dpsi / safe)[:, None, None] * dd
    for i in range(3):
        blocks[:, i, :, i, :] += scaled
    return StressResponse(psi, P, A)

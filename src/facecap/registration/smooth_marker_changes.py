"""What the markers say about a basis beyond their noise: a Gaussian process over the face, fitted by likelihood."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..errors import InputError
from ..typing import FloatArray

__all__ = ["SmoothedChanges", "smooth_marker_changes"]

# candidate length scales of the smooth part (mm): a re-performed expression differs from its frame
# by muscle-sized patches, a registration by what one marker's neighbourhood holds
_LENGTHS_MM = (6.0, 10.0, 15.0, 22.0, 33.0, 50.0)
_AMPLITUDES_MM = np.geomspace(0.005, 3.0, 24)
_NOISES_MM = np.geomspace(0.005, 1.0, 24)
_MIN_POOLED_MARKERS = 10


class SmoothedChanges(NamedTuple):
    """Result of :func:`smooth_marker_changes`.

    Attributes
    ----------
    changes : (K, M, 3) float64 array, mm
        The posterior mean of the smooth part at the markers: what the fit should move.
    length_mm, amplitude_mm, noise_mm : float
        The hyperparameters chosen: the smooth part's length scale and standard deviation, and the
        independent per-marker part (marker noise and placement), by marginal likelihood.
    """

    changes: FloatArray
    length_mm: float
    amplitude_mm: float
    noise_mm: float


def smooth_marker_changes(changes: Any, positions: Any, *, weights: Any = None) -> SmoothedChanges:
    """Split each basis's marker changes into a smooth field over the face and independent noise.

    Section 7 of Huang et al. 2011 moves every basis until its markers equal its frame's markers.
    The difference holds two things: how the scanned expression differs from the frame's (the actor
    performed it again), which is smooth over the face, and each marker's own noise and placement
    error, which is not. Pinning the basis to the markers copies the second into it: on generated
    takes with colour-aligned bases, 0.2 mm of marker noise added 0.05 mm to every basis. This
    models the changes as a Gaussian process ``f + e`` with ``f ~ GP(0, a^2 exp(-r^2 / 2 l^2))``
    over the markers' rest positions and ``e ~ N(0, s^2)`` per marker and coordinate, the same
    ``(l, a, s)`` for every basis and coordinate, chosen on a grid by the pooled marginal
    likelihood, and returns the posterior mean of ``f`` at the markers.

    Parameters
    ----------
    changes : (K, M, 3) float array, mm
        Frame markers minus the markers on each basis (after the rigid fit of the frame onto it).
    positions : (M, 3) float array, mm
        The markers' places on the template (rest), for the distances.
    weights : (K, M) float array or None, optional
        1 for a change that counts, 0 for one that does not (a marker the scan did not show, whose
        place on the basis is a guess): left out of the likelihood, and its change predicted from
        the others. None: all count.

    Returns
    -------
    SmoothedChanges

    Raises
    ------
    InputError
        If the shapes do not match or a value is not finite.

    Examples
    --------
    A smooth change plus noise is brought back to the smooth change:

    >>> rng = np.random.default_rng(0)
    >>> P = rng.uniform(-60, 60, (90, 3))
    >>> smooth = 0.5 * np.sin(P[:, :1] / 25.0) * np.ones((1, 3))
    >>> noisy = smooth[None] + rng.normal(scale=0.2, size=(10, 90, 3))
    >>> out = smooth_marker_changes(noisy, P)
    >>> bool(np.abs(out.changes - smooth).mean() < 0.5 * np.abs(noisy - smooth).mean())
    True
    """
    Y = np.asarray(changes, dtype=np.float64)
    P = np.asarray(positions, dtype=np.float64)
    if Y.ndim != 3 or Y.shape[2] != 3 or P.shape != (Y.shape[1], 3):
        raise InputError(f"changes (K, M, 3) and positions (M, 3) expected, got {Y.shape} and {P.shape}")
    if not (np.all(np.isfinite(Y)) and np.all(np.isfinite(P))):
        raise InputError("changes and positions must be finite")
    K, M = Y.shape[:2]
    W = np.ones((K, M), dtype=bool) if weights is None else np.asarray(weights) > 0
    if W.shape != (K, M):
        raise InputError(f"weights: expected shape ({K}, {M}), got {W.shape}")
    d2 = np.sum((P[:, None] - P[None]) ** 2, axis=2)
    # the likelihood pools every basis over the markers that count in all of them (a single-view scan
    # misses a few side-of-face markers in every basis); the left-out ones are predicted afterwards
    rows = np.flatnonzero(W.all(axis=0))
    if rows.size < _MIN_POOLED_MARKERS:
        rows = np.arange(M)  # too few markers seen everywhere: all of them, the guessed ones included
    pool = Y[:, rows].transpose(1, 0, 2).reshape(rows.size, -1)
    best = (-np.inf, _LENGTHS_MM[0], _AMPLITUDES_MM[0], _NOISES_MM[0])
    n_cols = pool.shape[1]
    for length in _LENGTHS_MM:
        lam, Q = np.linalg.eigh(np.exp(-0.5 * d2[np.ix_(rows, rows)] / length**2))
        lam = np.clip(lam, 0.0, None)
        z2 = np.sum((Q.T @ pool) ** 2, axis=1)  # (M,) energy of the data along each eigenvector
        var = _AMPLITUDES_MM[:, None, None] ** 2 * lam[None, None] + _NOISES_MM[None, :, None] ** 2
        loglik = -0.5 * np.sum(z2 / var, axis=2) - 0.5 * n_cols * np.sum(np.log(var), axis=2)
        i, j = np.unravel_index(int(np.argmax(loglik)), loglik.shape)
        if loglik[i, j] > best[0]:
            best = (float(loglik[i, j]), length, float(_AMPLITUDES_MM[i]), float(_NOISES_MM[j]))
    _, length, amplitude, noise = best
    kernel = amplitude**2 * np.exp(-0.5 * d2 / length**2)
    out = np.empty_like(Y)
    for k in range(K):
        seen = np.flatnonzero(W[k])
        if seen.size == 0:
            out[k] = 0.0
            continue
        C = kernel[np.ix_(seen, seen)] + noise**2 * np.eye(seen.size)
        out[k] = kernel[:, seen] @ np.linalg.solve(C, Y[k, seen])
    return SmoothedChanges(out, float(length), float(amplitude), float(noise))

"""What a scanner's colour camera records of the skin: exposure, shading, sensor noise, sRGB."""

from __future__ import annotations

import numpy as np

from ..cameras.image_to_float import linear_to_srgb
from ..errors import InputError
from ..typing import FloatArray
from ..validate import as_points, as_positive

__all__ = ["capture_colors"]


def capture_colors(
    albedo: FloatArray,
    points: FloatArray | None = None,
    *,
    seed: int,
    exposure_range: tuple[float, float] = (0.85, 1.15),
    shading_amplitude: float = 0.08,
    noise: float = 0.01,
) -> FloatArray:
    """Per-vertex colours as a scanner's camera records them: sRGB-encoded, in [0, 1].

    Parameters
    ----------
    albedo : (n, 3) float64 array
        Linear RGB reflectance, e.g. from :func:`~facecap.synth.skin_albedo.skin_albedo`.
    points : (n, 3) float64 array, mm, or None, optional
        Where the vertices are during this capture (any frame): the shading
        field is a function of them. None (default): no shading.
    seed : int
        Seeds this capture's exposure, shading field and sensor noise.
    exposure_range : (float, float), default (0.85, 1.15)
        Range of the per-capture exposure (uniform), a factor on linear light.
    shading_amplitude : float, default 0.08
        Largest relative change of the smooth shading field (a product of
        low-frequency cosines, wavelengths 80-250 mm), in [0, 1).
    noise : float, default 0.01
        Standard deviation of the Gaussian sensor noise, in linear light.

    Returns
    -------
    (n, 3) float32 array
        ``albedo * exposure * shading(points) + noise`` clipped to [0, 1] and sRGB-encoded
        (:func:`~facecap.cameras.linear_to_srgb`),
        ready for :attr:`facecap.structures.Mesh.vertex_colors`.

    Raises
    ------
    InputError
        If the arrays have the wrong shape or an option is out of range.

    Notes
    -----
    ``shading(p) = 1 + s * mean_j cos(k_j . p + phi_j)`` over 4 random waves,
    so ``|shading - 1| <= s``. Undo it by :func:`~facecap.cameras.srgb_to_linear` and dividing by
    the exposure (and shading) to get the albedo back to within the noise.

    Examples
    --------
    >>> import numpy as np
    >>> a = np.full((4, 3), 0.2)
    >>> c = capture_colors(a, seed=0, exposure_range=(1.0, 1.0), noise=0.0)
    >>> from facecap.cameras import srgb_to_linear
    >>> bool(np.allclose(srgb_to_linear(c), 0.2, atol=1e-6))
    True
    """
    A = np.asarray(albedo, dtype=np.float64)
    if A.ndim != 2 or A.shape[1] != 3 or not np.all(np.isfinite(A)):
        raise InputError(f"albedo: expected a finite (n, 3) array, got shape {A.shape}")
    lo, hi = (as_positive(x, name="exposure_range") for x in exposure_range)
    if hi < lo:
        raise InputError(f"exposure_range: expected (low, high) with low <= high, got {exposure_range!r}")
    s = as_positive(shading_amplitude, name="shading_amplitude", allow_zero=True)
    if s >= 1.0:
        raise InputError(f"shading_amplitude: expected a value in [0, 1), got {shading_amplitude!r}")
    sigma = as_positive(noise, name="noise", allow_zero=True)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0xCA97]))
    exposure = rng.uniform(lo, hi)
    linear = A * exposure
    direction = rng.normal(size=(4, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    k = direction * (2.0 * np.pi / rng.uniform(80.0, 250.0, 4))[:, None]
    phase = rng.uniform(0.0, 2.0 * np.pi, 4)
    if points is not None and s > 0:
        P = as_points(points, name="points")
        if P.shape[0] != A.shape[0]:
            raise InputError(f"points: expected {A.shape[0]} points (one per albedo row), got {P.shape[0]}")
        linear = linear * (1.0 + s * np.cos(P @ k.T + phase).mean(axis=1))[:, None]
    if sigma > 0:
        linear = linear + rng.normal(0.0, sigma, A.shape)
    return linear_to_srgb(np.clip(linear, 0.0, 1.0)).astype(np.float32)

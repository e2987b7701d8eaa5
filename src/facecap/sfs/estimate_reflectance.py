"""Reflectance from the rest frame: albedo per sample or per region, and the specular lobe (Lo et al. 4.1, 6).

The paper fits ``R = (k_d, k_s, alpha)`` uniform over a region, diffuse first,
then specular, and names per-sample reflectance as future work (section 6). Here,
on frames where the surface is the layer below (the rest frame: no expression
detail yet), the model ``I_o = a D_o + k_s S_o(alpha)`` is linear in the albedo
``a`` and ``k_s`` for each ``alpha``: with the albedo per sample it is eliminated
sample by sample (each sample's observations from the cameras and frames), which
leaves one quadratic in ``k_s``, solved exactly; ``alpha`` is the exponent of a
short list that fits best. Two views make the specular visible: the diffuse is
the same from both, the lobe is not. Residuals are relative (divided by the
observed intensity), as the height solve's are.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from ..errors import InputError
from ..typing import FloatArray
from .phong_shading import phong_shading
from .solve_heights import ShadedFrame

__all__ = ["Reflectance", "estimate_reflectance", "PHONG_EXPONENTS"]

PHONG_EXPONENTS = (4.0, 8.0, 16.0, 32.0, 64.0)
"""Exponents tried for the specular lobe: skin's measured Phong fits lie between about 5 and 60."""


class Reflectance(NamedTuple):
    """What the rest frame says about the skin's reflectance.

    Attributes
    ----------
    albedo : (r,) float64 array
        Diffuse albedo per sample (relative to the lights' intensities and the camera's exposure).
    k_s : float
    alpha : float
    residual : float
        Weighted RMS relative residual of the rest frame with this reflectance.
    per_sample : bool
        Whether ``albedo`` varies per sample (else it is one value per region).
    """

    albedo: FloatArray
    k_s: float
    alpha: float
    residual: float
    per_sample: bool


def _parts(frames: Sequence[ShadedFrame], alpha: float, ambient: float) -> tuple[FloatArray, ...]:
    """Per observation (frames x cameras, samples): I, relative weight (``w / I^2``), D, S, the weight ``w``."""
    I, W, D, S, plain = [], [], [], [], []
    for f in frames:
        for c in range(f.to_eye.shape[0]):
            shading = phong_shading(f.normals, f.to_light, f.irradiance, f.to_eye[c], albedo=1.0, k_s=1.0,
                                    alpha=alpha, ambient=ambient)
            I.append(f.intensity[c])
            seen = f.weight[c] > 0
            floor = 0.02 * max(float(np.median(f.intensity[c][seen])) if np.any(seen) else 1.0, 1e-9)
            W.append(f.weight[c] / np.maximum(f.intensity[c], floor) ** 2)
            plain.append(f.weight[c])
            D.append(shading.diffuse)
            S.append(shading.specular)
    return np.array(I), np.array(W), np.array(D), np.array(S), np.array(plain)


def estimate_reflectance(frames: Sequence[ShadedFrame], *, ambient: float = 0.0, per_sample: bool = True,
                         labels: FloatArray | None = None, exponents: Sequence[float] = PHONG_EXPONENTS,
                         specular: bool = True) -> Reflectance:
    """The albedo and Phong lobe that explain frames of the base surface best.

    Parameters
    ----------
    frames : sequence of ShadedFrame
        Frames whose surface is the base (no detail), e.g. the rest frame.
    ambient : float, default 0
    per_sample : bool, default True
        An albedo per sample (freckles, moles and brows then shade nothing), else one per region (the paper).
    labels : (r,) int array, optional
        Regions for ``per_sample=False`` (default: one region).
    exponents : sequence of float
        The ``alpha`` tried.
    specular : bool, default True
        False fits the diffuse alone (``k_s = 0``), the paper's first stage.

    Returns
    -------
    Reflectance
        Samples no camera saw take the median albedo of those seen.

    Raises
    ------
    InputError
        No frame, or no sample seen by any camera.
    """
    frames = list(frames)
    if not frames:
        raise InputError("frames: expected at least one frame")
    r = frames[0].normals.shape[0]
    groups = np.zeros(r, dtype=np.int64) if (per_sample or labels is None) else np.asarray(labels, dtype=np.int64)
    best = None
    for alpha in (exponents if specular else (float(exponents[0]),)):
        I, W, D, S, plain = _parts(frames, float(alpha), ambient)
        if not np.any(W > 0):
            raise InputError("no sample of the rest frame is seen by any camera")
        if not specular:
            S = np.zeros_like(S)

        def sums(x: FloatArray) -> FloatArray:
            per = np.sum(W * x, axis=0)
            return per if per_sample else np.bincount(groups, weights=per)[groups]

        Sdd, Sds, Sss = sums(D * D), sums(D * S), sums(S * S)
        Sid, Sis = sums(I * D), sums(I * S)
        ok = Sdd > 1e-300
        inv = np.where(ok, 1.0 / np.where(ok, Sdd, 1.0), 0.0)
        if per_sample:
            top = np.sum((Sis - Sid * Sds * inv)[ok])
            bottom = np.sum((Sss - Sds * Sds * inv)[ok])
        else:  # each region's sums are repeated on its samples: count each region once
            first = np.unique(groups, return_index=True)[1]
            keep = ok[first]
            top = np.sum((Sis - Sid * Sds * inv)[first][keep])
            bottom = np.sum((Sss - Sds * Sds * inv)[first][keep])
        k_s = max(top / bottom, 0.0) if (specular and bottom > 1e-300) else 0.0
        albedo = np.where(ok, (Sid - k_s * Sds) * inv, np.nan)
        res = I - albedo[None] * D - k_s * S
        rms = float(np.sqrt(np.nansum(W * res * res) / max(np.sum(plain[:, ok]), 1e-300)))
        if best is None or rms < best.residual:
            best = Reflectance(albedo, float(k_s), float(alpha), rms, bool(per_sample))
    assert best is not None
    albedo = best.albedo
    if np.any(~np.isfinite(albedo)):
        albedo = np.where(np.isfinite(albedo), albedo, np.nanmedian(albedo))
    return best._replace(albedo=albedo)

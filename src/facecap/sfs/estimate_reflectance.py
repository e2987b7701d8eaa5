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

from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np

from ..errors import InputError
from ..typing import FloatArray
from .phong_shading import phong_shading
from .solve_heights import ShadedFrame

__all__ = ["Reflectance", "estimate_reflectance", "rest_misfit", "PHONG_EXPONENTS", "REST_MISFIT_LIMIT"]

REST_MISFIT_LIMIT = 0.08
"""Samples the rest frame's fit leaves further off than this (relative RMS over the cameras) are left out of
the detail: 8 %, four times the misfit of well-placed skin under the generator's sensor noise (about 2 %)."""

PHONG_EXPONENTS = (4.0, 8.0, 16.0, 32.0, 64.0)
"""Exponents tried for the specular lobe: skin's measured Phong fits lie between about 5 and 60."""


class Reflectance(NamedTuple):
    """What the rest frame says about the skin's reflectance.

    Attributes
    ----------
    albedo : (r,) float64 array
        Diffuse albedo per sample (relative to the lights' intensities and the camera's exposure).
    k_s : float or (r,) float64 array
    alpha : float or (r,) float64 array
        One lobe, or one per patch given to each of its samples.
    residual : float
        Weighted RMS relative residual of the rest frame with this reflectance.
    per_sample : bool
        Whether ``albedo`` varies per sample (else it is one value per region).
    """

    albedo: FloatArray
    k_s: float | FloatArray
    alpha: float | FloatArray
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
                         specular: bool = True, patches: FloatArray | None = None,
                         smooth: Callable[[FloatArray], FloatArray] | None = None) -> Reflectance:
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
    patches : (r,) int array, optional
        A lobe (``k_s``, ``alpha``) per patch instead of one for all samples (skin is oilier on the forehead
        and nose than on the cheeks); needs ``per_sample``. ``k_s`` and ``alpha`` are then per sample.
    smooth : callable, optional
        With ``patches``: applied to the per-sample ``k_s`` and ``log alpha`` before the albedo is fitted
        (e.g. a :class:`~facecap.sfs.SurfaceLowPass`), so that the lobe has no step at a patch's edge.

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
    if patches is not None and specular and per_sample:
        return _per_patch(frames, ambient, np.asarray(patches, dtype=np.int64), exponents, smooth)
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


def _per_patch(frames: Sequence[ShadedFrame], ambient: float, patches: np.ndarray,
               exponents: Sequence[float], smooth: Callable[[FloatArray], FloatArray] | None) -> Reflectance:
    """Per-sample albedo with a Phong lobe per patch: for each exponent, each patch's ``k_s`` exactly, then
    the exponent that fits the patch best."""
    labels = np.unique(patches, return_inverse=True)[1]
    n_patches = int(labels.max()) + 1
    best_rms = np.full(n_patches, np.inf)
    best_ks = np.zeros(n_patches)
    best_alpha = np.full(n_patches, float(exponents[0]))
    for alpha in exponents:
        I, W, D, S, plain = _parts(frames, float(alpha), ambient)
        Sdd, Sds, Sss = (np.sum(W * x, axis=0) for x in (D * D, D * S, S * S))
        Sid, Sis, Sii = (np.sum(W * x, axis=0) for x in (I * D, I * S, I * I))
        ok = Sdd > 1e-300
        inv = np.where(ok, 1.0 / np.where(ok, Sdd, 1.0), 0.0)
        top = np.bincount(labels, weights=np.where(ok, Sis - Sid * Sds * inv, 0.0), minlength=n_patches)
        bottom = np.bincount(labels, weights=np.where(ok, Sss - Sds * Sds * inv, 0.0), minlength=n_patches)
        # shrunk toward the pooled lobe: a patch the lights leave no highlight on (bottom near 0) says nothing
        # about its k_s and takes the pooled one instead of a ratio of two small numbers
        pooled = max(top.sum() / bottom.sum(), 0.0) if bottom.sum() > 1e-300 else 0.0
        strength = 0.01 * float(np.median(bottom[bottom > 0])) if np.any(bottom > 0) else 1.0
        k_s = np.maximum((top + strength * pooled) / (bottom + strength), 0.0)
        # each sample's weighted residual with its albedo eliminated: Sii - Sid^2/Sdd - 2 k (..) + k^2 (..)
        k = k_s[labels]
        per = np.where(ok, (Sii - Sid * Sid * inv) - 2 * k * (Sis - Sid * Sds * inv)
                       + k * k * (Sss - Sds * Sds * inv), 0.0)
        weight = np.bincount(labels, weights=np.sum(plain, axis=0) * ok, minlength=n_patches)
        rms = np.sqrt(np.maximum(np.bincount(labels, weights=per, minlength=n_patches), 0.0)
                      / np.maximum(weight, 1e-300))
        better = rms < best_rms
        best_rms = np.where(better, rms, best_rms)
        best_ks = np.where(better, k_s, best_ks)
        best_alpha = np.where(better, float(alpha), best_alpha)
    k_s, alpha = best_ks[labels], best_alpha[labels]
    if smooth is not None:  # no step in the lobe at a patch's edge: it would shade as a line
        k_s = np.maximum(smooth(k_s), 0.0)
        alpha = np.exp(smooth(np.log(alpha)))
    I, W, D, S, plain = _parts(frames, alpha, ambient)
    Sdd = np.sum(W * D * D, axis=0)
    ok = Sdd > 1e-300
    a = (np.sum(W * I * D, axis=0) - k_s * np.sum(W * D * S, axis=0)) / np.where(ok, Sdd, 1.0)
    albedo = np.where(ok, a, np.nan)
    res = I - a[None] * D - k_s[None] * S
    total_res = float(np.sum((W * res * res)[:, ok]))
    total_w = float(np.sum(plain[:, ok]))
    if np.any(~np.isfinite(albedo)):
        albedo = np.where(np.isfinite(albedo), albedo, np.nanmedian(albedo))
    return Reflectance(albedo, k_s, alpha, float(np.sqrt(total_res / max(total_w, 1e-300))), True)


def rest_misfit(frames: Sequence[ShadedFrame], reflectance: Reflectance, *, ambient: float = 0.0) -> FloatArray:
    """(r,) RMS relative residual of each sample on the frames the reflectance was fitted on (NaN where unseen).

    With an albedo per sample and two cameras, a sample the fit leaves far off is one the cameras disagree
    on: it is not where the layer below says (a lid that is closing, a fold), or one view is blocked by
    something the mesh lacks. Its shading cannot be trusted later either.
    """
    total = 0.0
    weight = 0.0
    for f in frames:
        for c in range(f.to_eye.shape[0]):
            shading = phong_shading(f.normals, f.to_light, f.irradiance, f.to_eye[c], albedo=reflectance.albedo,
                                    k_s=reflectance.k_s, alpha=reflectance.alpha, ambient=ambient)
            res = (f.intensity[c] - shading.radiance) / np.maximum(shading.radiance, 1e-9)
            total = total + f.weight[c] * res * res
            weight = weight + f.weight[c]
    return np.where(weight > 0, np.sqrt(total / np.where(weight > 0, weight, 1.0)), np.nan)

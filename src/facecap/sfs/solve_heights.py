"""The space-time solve of Lo et al. (eqs. 2-8, 4.1-4.2): heights along the base normals over a window of frames.

For the frames ``t`` of a window and the samples ``p`` of a region (vertices of
the layer below, ``A``), the detail is a height ``h_tp`` along the base normal
``N_tp``. The normal of the detailed surface is ``n = (N - P grad h) / |...|``
(``P`` the projection onto the tangent plane, ``grad`` the vertex gradient of
:mod:`~facecap.sfs.vertex_gradient`), shaded by Phong's model
(:func:`~facecap.sfs.phong_shading`) and compared with every camera that sees the
sample. The objective (eq. 8, with the paper's two constraints and a third):

``sum_ctp w_ctp ((Syn_ctp(h_t) - I_ctp) / s_ctp)^2``  image term, relative to the base's shading ``s``
``+ k_cs sum_tp (h_tp - mean_{j ~ p} h_tj)^2``          eq. 6, the one-ring (the mesh's 8-neighbourhood)
``+ k_ct sum_tp (h_tp - mean_{0 < |i| <= 3} h_(t+i)p)^2``  eq. 7, +-3 frames within the window
``+ k_anchor sum_tp h_tp^2``                            the base is right at the scales the markers see

The anchor is what the paper's sweep leaves implicit: shading sees the
gradient of ``h``, so a slow ramp costs the image term almost nothing; the
anchor lets long wavelengths (longer than about ``2 pi sqrt(|b|^2 / k_anchor)``,
``|b|`` the shading's sensitivity to the normal) stay with the layer below.

Gauss-Newton on the heights (the paper used conjugate gradients on the whole
objective): each iteration linearises the shading about the current heights
and solves the window's normal equations by Jacobi-preconditioned conjugate
gradients, matrix-free: per frame the gradient, the projection onto the shading's
sensitivity, each camera's blur and back, in one compiled pass each
(:class:`~facecap.sfs.normal_product.FrameNormalProduct`); the temporal term
couples the frames.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import InputError
from ..typing import FloatArray
from .normal_product import FrameNormalProduct, OneRingPattern, compile_blur
from .phong_shading import phong_shading
from .vertex_gradient import VertexGradient

__all__ = ["ShadedFrame", "HeightWeights", "HeightSolve", "solve_heights", "shade_frame", "TEMPORAL_REACH"]

TEMPORAL_REACH = 3
"""Frames on each side in the temporal term (eq. 7: ``i = [-3, 3]``)."""


class ShadedFrame(NamedTuple):
    """One frame of a region as the cameras and lights see its base surface.

    Attributes
    ----------
    normals : (r, 3) float array
        Unit normals of the base surface (mocap frame).
    gradient : VertexGradient
        Of the base surface at this frame, region by region (r, r).
    to_light : (L, r, 3) float array
        Unit directions toward each light.
    irradiance : (L, r) float array
        What each light sends to a surface facing it, 0 where it is blocked.
    to_eye : (C, r, 3) float array
        Unit directions toward each camera.
    intensity : (C, r) float array
        What each camera saw at the sample (linear), divided by any gain taken out first.
    weight : (C, r) float array
        Confidence of each observation: 0 where the camera does not see the sample.
    blur : sequence (per camera) of (r, r) sparse matrices, or None
        The camera's point spread on the skin (:func:`~facecap.sfs.camera_blur`): a sample sees the change of
        shading the detail makes blurred by it; None: each sample sees its own.
    """

    normals: FloatArray
    gradient: VertexGradient
    to_light: FloatArray
    irradiance: FloatArray
    to_eye: FloatArray
    intensity: FloatArray
    weight: FloatArray
    blur: Any = None


class HeightWeights(NamedTuple):
    """The constants of the objective (see the module notes); dimensionless image term, heights in mm.

    Attributes
    ----------
    spatial : float, 1/mm^2
        ``k_cs`` of eq. 6.
    temporal : float, 1/mm^2
        ``k_ct`` of eq. 7. 3 (it was 1): on the generator's tuned seed-0 footage the frame-to-frame change of
        the detail on held expressions fell from 0.38 to 0.27 of the single-frame Lambertian baseline's and
        the error ratio on the lines from 0.829 to 0.818 (8: 0.23 and 0.815; 3 keeps most of the gain and
        smears a fast-forming line less); ``benchmarks/RESULTS.md``, "Fine detail from video".
    anchor : float, 1/mm^2
        The pull toward the base surface.
    sparsity_mm : float or None, 1 mm
        With a length ``delta``, the anchor is reweighted at each Gauss-Newton step by
        ``delta / (|h| + delta)`` (iteratively reweighted least squares toward an L1 anchor): detail is
        sparse, so the skin between the lines stays on the base and a line keeps its depth, instead of the
        zero-mean compromise a quadratic anchor makes (shading sees the gradient, not the level). None: a
        quadratic anchor.
    bulge : float, default 100
        The anchor on heights above the base is this many times stronger than below: expression-driven
        detail is skin folding in (creases, valleys), and shading alone cannot tell a valley beside a ridge
        from a ridge beside a valley. On the generator's seed-0 footage with the true surface as the base
        (``benchmarks/RESULTS.md``, "Fine detail from video"), 1, 10 and 100 gave error ratios 0.77,
        0.64 and 0.56 on the lines, correlations 0.14, 0.23 and 0.37: chosen there, not yet checked held out.
    """

    spatial: float = 2.0
    temporal: float = 3.0
    anchor: float = 0.5
    sparsity_mm: float | None = 0.01
    bulge: float = 100.0


class HeightSolve(NamedTuple):
    """Heights of a window, and how well they explain the images.

    Attributes
    ----------
    heights : (T, r) float64 array, mm
        Along the base normals.
    residual : (T,) float64 array
        Weighted RMS of the relative image residual per frame, after the solve.
    residual_before : (T,) float64 array
        The same for the base surface (no heights).
    iterations : int
        Conjugate-gradient iterations, all Gauss-Newton steps together.
    """

    heights: FloatArray
    residual: FloatArray
    residual_before: FloatArray
    iterations: int


def _detailed_normals(frame: ShadedFrame, h: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Normals of the base moved by heights ``h``, the tangent gradient, and ``|N - P g|``."""
    N = frame.normals
    g = frame.gradient.apply(h)
    g_t = g - np.sum(g * N, axis=1, keepdims=True) * N
    m = N - g_t
    length = np.linalg.norm(m, axis=1)
    return m / length[:, None], g_t, length


def shade_frame(frame: ShadedFrame, h: FloatArray, albedo: Any, k_s: Any, alpha: Any, ambient: float,
                *, gradient: bool = False) -> tuple[FloatArray, FloatArray | None, FloatArray]:
    """Radiance each camera would see of the base moved by heights ``h``; optionally ``d radiance / d h``'s factors.

    Returns
    -------
    radiance : (C, r) float array
    b : (C, r, 3) float array or None
        With ``gradient``: ``d radiance_c / d h = b_c . (grad h)`` linearised at ``h`` (the chain through the
        normal's tangent projection and normalisation).
    normals : (r, 3) float array
        The detailed normals.
    """
    n, _, length = _detailed_normals(frame, h)
    N = frame.normals
    out, bs = [], []
    for c in range(frame.to_eye.shape[0]):
        shading = phong_shading(n, frame.to_light, frame.irradiance, frame.to_eye[c], albedo=albedo, k_s=k_s,
                                alpha=alpha, ambient=ambient, gradient=gradient)
        out.append(shading.radiance)
        if gradient:
            d = shading.d_normal
            # n = m / |m|, m = N - P g, P = I - N N^T: dn/dg = -(I - n n^T) P / |m|; b = (dn/dg)^T d
            d_t = d - np.sum(d * n, axis=1, keepdims=True) * n
            b = -(d_t - np.sum(d_t * N, axis=1, keepdims=True) * N) / length[:, None]
            bs.append(b)
    return np.stack(out), (np.stack(bs) if gradient else None), n


def _one_ring_average(gradient: VertexGradient) -> sp.csr_matrix:
    """``I - D^-1 Adj`` over the region from the gradient's pattern (its one-ring): eq. 6's operator."""
    pattern = (abs(gradient.x) + abs(gradient.y) + abs(gradient.z)).tocsr()
    pattern.data[:] = 1.0
    pattern.setdiag(0.0)
    pattern.eliminate_zeros()
    degree = np.asarray(pattern.sum(axis=1)).ravel()
    inverse = sp.diags(1.0 / np.maximum(degree, 1.0))
    return (sp.identity(pattern.shape[0], format="csr") - inverse @ pattern).tocsr()


def _temporal_operator(T: int, reach: int) -> FloatArray:
    """(T, T): row t is ``e_t - mean of e_(t+i), 0 < |i| <= reach`` within the window."""
    C = np.eye(T)
    for t in range(T):
        others = [t + i for i in range(-reach, reach + 1) if i != 0 and 0 <= t + i < T]
        if others:
            C[t, others] -= 1.0 / len(others)
        else:
            C[t, t] = 0.0
    return C


def solve_heights(frames: Sequence[ShadedFrame], *, albedo: Any, k_s: Any = 0.0, alpha: Any = 10.0,
                  ambient: float = 0.0, weights: HeightWeights = HeightWeights(), iterations: int = 3,
                  initial: FloatArray | None = None, tolerance: float = 1e-2, max_cg: int = 100) -> HeightSolve:
    """Heights along the base normals that make the shading match the footage over a window of frames.

    Parameters
    ----------
    frames : sequence of ShadedFrame
        The window's frames in time order, all over the same region (r samples).
    albedo : float or (r,) float array
        Diffuse albedo: per region (the paper's ``k_d``) or per sample.
    k_s, alpha : float or (r,) float arrays
        Specular coefficient and Phong exponent.
    ambient : float
    weights : HeightWeights
    iterations : int, default 3
        Gauss-Newton steps.
    initial : (T, r) float array, optional
        Heights to start from (default 0: the base surface).
    tolerance : float, default 1e-2
        Relative residual at which conjugate gradients stop: each Gauss-Newton step is solved inexactly
        (the next one relinearises). On a 140 880-sample window of the generator's footage 1e-2 took 122
        iterations against 1e-3's 253, and the heights moved 0.003 mm RMS (their own RMS 0.025, their error on
        the lines unchanged: ratio 0.923 against 0.925).
    max_cg : int, default 100

    Returns
    -------
    HeightSolve

    Raises
    ------
    InputError
        No frame, frames over different regions, or weights that are negative.
    """
    frames = list(frames)
    if not frames:
        raise InputError("frames: expected at least one frame")
    r = frames[0].normals.shape[0]
    if any(f.normals.shape[0] != r for f in frames):
        raise InputError("frames: every frame of a window must cover the same samples")
    if min(weights.spatial, weights.temporal, weights.anchor) < 0 or (weights.sparsity_mm or 1.0) <= 0 \
            or weights.bulge < 1:
        raise InputError(f"weights: expected values >= 0, got {weights}")
    T = len(frames)
    h = np.zeros((T, r)) if initial is None else np.array(initial, dtype=np.float64, copy=True).reshape(T, r)
    scale, bases = [], []
    for f in frames:  # the base's own shading: residuals are relative to what the sample looks like
        base, _, _ = shade_frame(f, np.zeros(r), albedo, k_s, alpha, ambient)
        floor = 0.05 * max(float(np.median(base[f.weight > 0])) if np.any(f.weight > 0) else 1.0, 1e-12)
        scale.append(np.maximum(base, floor))
        bases.append(base)

    def seen(t: int, syn: FloatArray) -> FloatArray:
        """What the cameras see of shading ``syn`` at frame ``t``: the base plus the blurred change."""
        f = frames[t]
        if f.blur is None:
            return syn
        return np.stack([bases[t][c] + f.blur[c] @ (syn[c] - bases[t][c]) for c in range(syn.shape[0])])
    spatial = _one_ring_average(frames[0].gradient)
    StS = (spatial.T @ spatial).tocsr() * weights.spatial
    C = _temporal_operator(T, TEMPORAL_REACH)
    CtC = weights.temporal * (C.T @ C)

    def residual_rms(h_now: FloatArray) -> FloatArray:
        out = np.empty(T)
        for t, f in enumerate(frames):
            syn, _, _ = shade_frame(f, h_now[t], albedo, k_s, alpha, ambient)
            res = (seen(t, syn) - f.intensity) / scale[t]
            out[t] = np.sqrt(np.sum(f.weight * res * res) / max(np.sum(f.weight), 1e-12))
        return out

    def objective(h_now: FloatArray, anchor_now: FloatArray) -> float:
        """The window's whole objective (with the anchor's weights of this step)."""
        total = 0.0
        for t, f in enumerate(frames):
            syn, _, _ = shade_frame(f, h_now[t], albedo, k_s, alpha, ambient)
            res = (seen(t, syn) - f.intensity) / scale[t]
            total += float(np.sum(f.weight * res * res)) + float(h_now[t] @ (StS @ h_now[t]))
        return total + float(np.sum(anchor_now * h_now * h_now)) + float(np.sum(h_now * (CtC @ h_now)))

    patterns: dict[int, OneRingPattern] = {}
    blurs: dict[int, Any] = {}

    def pattern_of(G: VertexGradient) -> OneRingPattern:
        """The gradient's and eq. 6's shared pattern (frames usually share one gradient)."""
        if id(G) not in patterns:
            patterns[id(G)] = OneRingPattern(G, spatial * np.sqrt(weights.spatial))
        return patterns[id(G)]

    def compiled_blur(t: int) -> Any:
        """Frame ``t``'s blurs in the compiled layout, made once for every Gauss-Newton step."""
        if t not in blurs:
            blurs[t] = None if frames[t].blur is None else compile_blur(frames[t].blur)
        return blurs[t]

    before = residual_rms(np.zeros((T, r)))
    total_cg = 0
    for _ in range(int(iterations)):
        if weights.sparsity_mm is None:
            anchor = np.full((T, r), weights.anchor)
        else:
            anchor = weights.anchor * weights.sparsity_mm / (np.abs(h) + weights.sparsity_mm)
        anchor = anchor * np.where(h > 0, weights.bulge, 1.0)
        blocks, products, rhs = [], [], np.zeros((T, r))
        for t, f in enumerate(frames):
            syn, b, _ = shade_frame(f, h[t], albedo, k_s, alpha, ambient, gradient=True)
            b = b / scale[t][..., None]
            res = (f.intensity - seen(t, syn)) / scale[t]
            G = f.gradient
            g_old = G.apply(h[t])
            # the unknown is the new heights: J h_new ~ r + J h_old. Per sample the unblurred data term's normal
            # matrix is B_p = sum_c w b b^T (3x3), and J^T W r = G^T sum_c w r b; the blurred one goes through
            # each camera's blur and back (B then serves the preconditioner only)
            B = np.einsum("cr,cri,crj->rij", f.weight, b, b)
            if f.blur is None:
                q = np.einsum("cr,cri->ri", f.weight * res, b) + np.einsum("rij,rj->ri", B, g_old)
            else:
                q = np.zeros((r, 3))
                for c in range(b.shape[0]):
                    target = res[c] + f.blur[c] @ np.sum(b[c] * g_old, axis=1)
                    q += (f.blur[c].T @ (f.weight[c] * target))[:, None] * b[c]
            rhs[t] = G.x.T @ q[:, 0] + G.y.T @ q[:, 1] + G.z.T @ q[:, 2]
            blocks.append((G, B, b, f))
            products.append(FrameNormalProduct(pattern_of(G), b, f.weight, compiled_blur(t)))

        def matvec(x: FloatArray) -> FloatArray:
            X = x.reshape(T, r)
            out = np.empty_like(X)
            for t, product in enumerate(products):
                product(X[t], out[t])
            out += anchor * X + CtC @ X
            return out.ravel()

        diagonal = np.empty((T, r))
        sts_diag = StS.diagonal()
        for t, (G, B, _, _) in enumerate(blocks):
            parts = (G.x, G.y, G.z)
            d = np.zeros(r)
            for i in range(3):
                for j in range(3):
                    d += np.asarray(parts[i].multiply(parts[j]).T @ B[:, i, j]).ravel()
            diagonal[t] = d + sts_diag + anchor[t] + CtC[t, t]
        inverse = 1.0 / np.maximum(diagonal.ravel(), 1e-12)
        A = spla.LinearOperator((T * r, T * r), matvec=matvec, dtype=np.float64)
        M = spla.LinearOperator((T * r, T * r), matvec=lambda v: inverse * v, dtype=np.float64)
        count = [0]

        def counter(_: Any) -> None:
            count[0] += 1

        x, _ = spla.cg(A, rhs.ravel(), x0=h.ravel(), rtol=tolerance, maxiter=max_cg, M=M, callback=counter)
        total_cg += count[0]
        # the shading is far from linear (a specular lobe, the cosine's kink): the Gauss-Newton step is
        # halved until the true objective falls, as a backtracking line search does
        step = x.reshape(T, r) - h
        start = objective(h, anchor)
        for fraction in (1.0, 0.5, 0.25, 0.125):
            trial = h + fraction * step
            if objective(trial, anchor) < start:
                h = trial
                break
        else:
            break
    return HeightSolve(h, residual_rms(h), before, total_cg)

"""Fine detail below the marker spacing: expression lines a fraction of a millimetre deep, and the skin's own bumps.

The detail layer (space-time shape from shading, Lo et al.; issue 30) is judged on footage whose fine
detail is known exactly. Two kinds, both finer than the markers and neither moving them:

- **fine lines** (:func:`place_fine_lines`): forehead lines on brow raise, glabella lines on frown, crow's
  feet on smile and squint, fine lines under the eyes; 0.02-0.3 mm deep, 0.3-1.5 mm across (the valley,
  ``2 w``), drawn with the wrinkle machinery (:func:`~facecap.synth.wrinkles.wrinkle_curves_on_surface`,
  :func:`~facecap.synth.wrinkles.add_wrinkles`) at these scales;
- **skin texture** (:func:`skin_texture_heights`): a static bump field of the scan itself, 0.01 mm RMS,
  wavelengths 2-6 mm, that no expression changes.

Two cross-sections: :func:`~facecap.synth.wrinkles.wrinkle_profile` (round valley, bulges beside it) for the
Phong footage, and :func:`double_crease_profile` (two V creases, no bulge) for the independent footage the
solver is measured on.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import InputError
from ..io.ict_sample import IctSample
from ..structures import Mesh
from ..typing import FloatArray
from .skin_albedo import band_noise
from .wrinkles import WrinkleCurves, wrinkle_curves_on_surface, wrinkle_profile

__all__ = ["FINE_LINE_KINDS", "FINE_LINE_PROFILES", "place_fine_lines", "double_crease_profile",
           "skin_texture_heights", "SKIN_TEXTURE_RMS_MM"]

FINE_LINE_KINDS = ("forehead", "glabella", "crows_feet", "under_eye")
"""The families :func:`place_fine_lines` draws."""

SKIN_TEXTURE_RMS_MM = 0.010
"""RMS height of the static skin texture (mm): bumps of 10-30 um."""
_TEXTURE_WAVELENGTHS_MM = (2.0, 6.0)  # the default scan's 0.94 mm forehead edges hold 2 mm (Nyquist 1.9 mm)

# kind: (depth range mm, half-width w range mm: valley line to zero crossing), full activation, mid-line
_FAMILIES = {
    "forehead": ((0.10, 0.30), (0.45, 0.75)),
    "glabella": ((0.08, 0.25), (0.35, 0.60)),
    "crows_feet": ((0.04, 0.15), (0.25, 0.50)),
    "under_eye": ((0.02, 0.08), (0.15, 0.35)),
}
_MIN_WIDTH_FRACTION = 0.7


def double_crease_profile(distance: FloatArray, depth: FloatArray, width: FloatArray) -> FloatArray:
    """Height of a double crease at ``distance`` from its centre line (mm; the independent footage's lines).

    Two V creases ``0.45 w`` either side of the line, each ``0.6 w`` wide at the top, no bulge:
    ``h = -d (v(q - 0.45) + v(q + 0.45))``, ``v(x) = max(0, 1 - |x| / 0.6)``, ``q = |p| / w``:
    ``-d`` at the creases, ``-d / 2`` on the ridge between them (the line itself), 0 from ``q = 1.05``.

    Examples
    --------
    >>> double_crease_profile(np.array([0.0, 0.45, 1.05, 2.0]), 0.1, 1.0).round(6).tolist()
    [-0.05, -0.1, -0.0, -0.0]
    """
    q = np.abs(np.asarray(distance, dtype=np.float64)) / np.asarray(width, dtype=np.float64)
    v = lambda x: np.clip(1.0 - np.abs(x) / 0.6, 0.0, None)  # noqa: E731
    return -np.asarray(depth, dtype=np.float64) * (v(q - 0.45) + v(q + 0.45))


FINE_LINE_PROFILES: dict[str, Callable[[FloatArray, FloatArray, FloatArray], FloatArray]] = {
    "phong": wrinkle_profile, "independent": double_crease_profile}
"""The lines' cross-section for each appearance of the detail footage."""


def _drivers(kind: str, side: str) -> dict[str, float]:
    """Expressions that make a line, with gains: activation = clip(sum gain * weight, 0, 1)."""
    if kind == "forehead":
        return {"browInnerUp_L": 0.5, "browInnerUp_R": 0.5, "browOuterUp_L": 0.3, "browOuterUp_R": 0.3}
    if kind == "glabella":
        return {f"browDown_{side}": 1.0, f"noseSneer_{side}": 0.3}
    if kind == "crows_feet":
        return {f"eyeSquint_{side}": 0.6, f"cheekSquint_{side}": 0.6, f"mouthSmile_{side}": 0.5}
    return {f"eyeSquint_{side}": 0.7, f"cheekSquint_{side}": 0.5, f"mouthSmile_{side}": 0.4}  # under the eye


def _lines(kind: str, L: FloatArray, forehead_top: float, rng: np.random.Generator
           ) -> list[tuple[str, str, FloatArray]]:
    """(name, side, (m, 2) xy polyline) of each line of a family, from the landmarks' positions ``L``."""
    brow_top = float(L[17:27, 1].max())
    out = []
    if kind == "forehead":  # 4-6 shallow lines, 4-7 mm apart, between the brow hair and the hairline
        low, high = brow_top + 7.0, forehead_top - 4.0
        count = int(rng.integers(4, 7))
        spacing = min(rng.uniform(4.0, 7.0), (high - low) / (count - 1))
        for i in range(count):
            half = rng.uniform(18.0, 34.0)
            x = np.linspace(-half, half, 40) + rng.uniform(-6.0, 6.0)
            y = low + spacing * i + rng.uniform(-1.0, 1.0) - rng.uniform(0.002, 0.006) * x * x \
                + rng.uniform(0.2, 0.5) * np.sin(2 * np.pi * x / rng.uniform(25, 50) + rng.uniform(0, 2 * np.pi))
            out.append((f"forehead_{i}", "", np.column_stack([x, y])))
        return out
    for side, sign in (("L", 1.0), ("R", -1.0)):
        if kind == "glabella":  # 1-2 near-vertical lines each side of the midline, between the brows
            for j in range(int(rng.integers(1, 3))):
                x0 = sign * (rng.uniform(3.5, 5.5) + 2.5 * j)
                y = np.linspace(brow_top - 9.0, brow_top + rng.uniform(2.0, 6.0), 20)
                x = x0 + sign * rng.uniform(0.5, 2.0) * (y - y[0]) / (y[-1] - y[0])
                out.append((f"glabella_{side}_{j}", side, np.column_stack([x, y])))
        elif kind == "crows_feet":  # 3-4 short lines fanning from the outer eye corner
            corner = L[45 if sign > 0 else 36, :2]
            count = int(rng.integers(3, 5))
            for j, a in enumerate(np.deg2rad(np.linspace(-35.0, 30.0, count) + rng.uniform(-5, 5, count))):
                direction = np.array([sign * np.cos(a), np.sin(a)])
                start = corner + direction * rng.uniform(4.0, 6.0)
                t = np.linspace(0.0, rng.uniform(6.0, 10.0), 20)[:, None]
                out.append((f"crows_feet_{side}_{j}", side, start + t * direction))
        else:  # under the eye: two arcs following the lower lid, 3-7 mm below it
            lid = L[[46, 47] if sign > 0 else [41, 40], :2]  # the lower lid, outer to inner
            inner, outer = L[42 if sign > 0 else 39, :2], L[45 if sign > 0 else 36, :2]
            for j, drop in enumerate((rng.uniform(3.0, 4.5), rng.uniform(5.5, 7.0))):
                t = np.linspace(0.15, 0.9, 20)[:, None]
                base = (1 - t) * inner + t * outer
                sag = lid[:, 1].mean() - 0.5 * (inner[1] + outer[1])
                y = base[:, 1] + sag * 4 * t[:, 0] * (1 - t[:, 0]) - drop
                out.append((f"under_eye_{side}_{j}", side, np.column_stack([base[:, 0], y])))
    return out


def place_fine_lines(scan: Mesh, sample: IctSample, *, seed: int = 0) -> WrinkleCurves:
    """Draw the fine expression lines on a face of ICT topology, from its landmarks.

    Forehead lines (4-6, 4-7 mm apart, between the brows and the top of the forehead region),
    glabella lines (1-2 each side of the midline between the brows), crow's feet (3-4 each side,
    fanning from the outer eye corner) and fine lines under the eyes (two arcs each side following
    the lower lid, 3-7 mm below it); each with a seeded depth and half-width ``w`` at full
    activation (mid-line), and ``0.7 w`` as it starts to form:

    ============  ============  =================  ====================================
    family        depth, mm     half-width w, mm   made by
    ============  ============  =================  ====================================
    forehead      0.10-0.30     0.45-0.75          browInnerUp, browOuterUp
    glabella      0.08-0.25     0.35-0.60          browDown, noseSneer
    crows_feet    0.04-0.15     0.25-0.50          eyeSquint, cheekSquint, mouthSmile
    under_eye     0.02-0.08     0.15-0.35          eyeSquint, cheekSquint, mouthSmile
    ============  ============  =================  ====================================

    Parameters
    ----------
    scan : Mesh
        The rest face (mm), of ICT topology or refined from it with its original vertices first.
    sample : IctSample
        The landmarks, regions and expression names.
    seed : int, default 0

    Returns
    -------
    WrinkleCurves
        Kinds from :data:`FINE_LINE_KINDS`; heights with
        :func:`~facecap.synth.wrinkles.add_wrinkles` and a profile of :data:`FINE_LINE_PROFILES`.

    Raises
    ------
    InputError
        If the scan is not of ICT topology or a line runs off the face.

    Notes
    -----
    The same construction as :func:`~facecap.synth.wrinkles.place_wrinkles` (lines drawn in the
    frontal plane and dropped onto the surface, activation ``clip(sum gain weight, 0, 1)``, depth
    ``a d_max sqrt(sin(pi s))``, width ``(w_min + a (w_max - w_min)) (0.7 + 0.3 sin(pi s))``) at the
    scale of fine lines. The same seed on any refinement of the same surface gives the same lines.
    """
    n = sample.n_vertices
    if scan.n_vertices < n:
        raise InputError(f"scan: {scan.n_vertices} vertices; expected the ICT topology (or a refinement of it)")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0xF1E]))
    V = scan.vertices
    forehead = (sample.region_labels == sample.region_names.index("forehead")) & (np.abs(V[:n, 0]) < 20.0)
    forehead_top = float(V[:n][forehead, 1].max())
    L = V[sample.landmarks]
    rows, kinds = [], []
    for kind in FINE_LINE_KINDS:
        lines = _lines(kind, L, forehead_top, rng)
        rows += lines
        kinds += [kind] * len(lines)
    index = {s: i for i, s in enumerate(sample.expression_names)}
    gains = np.zeros((len(rows), len(index)))
    depth, width = np.zeros(len(rows)), np.zeros(len(rows))
    for i, ((_, side, _), kind) in enumerate(zip(rows, kinds)):
        for expr, g in _drivers(kind, side).items():
            gains[i, index[expr]] = g
        (d_lo, d_hi), (w_lo, w_hi) = _FAMILIES[kind]
        depth[i], width[i] = rng.uniform(d_lo, d_hi), rng.uniform(w_lo, w_hi)
    return wrinkle_curves_on_surface(scan, [r[2] for r in rows], names=[r[0] for r in rows], kinds=kinds,
                                     gains=gains, max_depth=depth, max_width=width,
                                     min_width=_MIN_WIDTH_FRACTION * width)


def skin_texture_heights(points: FloatArray, *, seed: int = 0, rms_mm: float = SKIN_TEXTURE_RMS_MM) -> FloatArray:
    """The skin's static bumps: a height (mm, along the normal) at each material point of the rest face.

    Parameters
    ----------
    points : (n, 3) float array, mm
        Points of the rest surface (a solid texture: the same point gets the same height on any mesh).
    seed : int, default 0
    rms_mm : float, default 0.010

    Returns
    -------
    (n,) float64 array, mm
        Band-limited noise (wavelengths 2-6 mm, 256 random-phase cosines) scaled to ``rms_mm``:
        most bumps 10-30 um high.

    Examples
    --------
    >>> P = np.random.default_rng(0).uniform(-50, 50, (20000, 3))
    >>> h = skin_texture_heights(P, seed=1)
    >>> round(float(h.std()) * 1000), bool(np.abs(h).max() < 0.06)
    (10, True)
    """
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x7E47]))
    return float(rms_mm) * band_noise(points, _TEXTURE_WAVELENGTHS_MM, waves=256, rng=rng)

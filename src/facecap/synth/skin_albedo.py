"""Facial skin reflectance as a solid texture: a colour for every material point of the face."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..errors import InputError
from ..typing import FloatArray, IntArray
from ..validate import as_points

__all__ = ["skin_albedo", "skin_albedo_layers", "SkinLayers", "SkinRegions", "BASE_SKIN_TONE", "band_noise"]

BASE_SKIN_TONE = (0.55, 0.38, 0.30)
"""Mean linear-light RGB reflectance of the generated skin before the per-seed variation."""

# (wavelength range mm, waves, std of the luminance factor, std of the red shift)
_BLOTCH = ((15.0, 40.0), 192, 0.03, 0.015)
_MOTTLE = ((3.0, 8.0), 256, 0.025, 0.006)
_FRECKLE_CELL_MM = 6.0
_FRECKLE_SLOTS = 3
_FRECKLE_RADIUS_MM = (0.8, 2.5)
_FRECKLE_DARKNESS = (0.10, 0.30)
_FRECKLE_TINT = np.array([0.85, 1.0, 1.15])  # darker in blue than in red: brownish
_FRECKLES_PER_CM2 = 0.6  # intended surface density (spots whose disc meets the surface)
_BROW_DARKNESS = 0.40
_BROW_STRIPE_MM = 0.7
_LIP_TINT = np.array([0.97, 0.72, 0.76])  # vermilion: redder and a little darker
# moles: rarer, larger and darker than freckles, the same hashed field with their own constants
_MOLE_CELL_MM = 20.0
_MOLE_RADIUS_MM = (0.9, 1.8)
_MOLE_DARKNESS = (0.45, 0.65)
_MOLES_PER_CM2 = 0.03
_MOLE_TINT = np.array([0.9, 1.0, 1.08])
# pores and fine texture, what a scanner's texture resolves at 0.1-0.5 mm a texel: the same hashed field
# at pore scale (0.1-0.4 mm across, about 120 per cm^2, 10-30 % darker) and a fine luminance noise
_PORE_CELL_MM = 0.5
_PORE_RADIUS_MM = (0.05, 0.2)
_PORE_DARKNESS = (0.10, 0.30)
_PORES_PER_CM2 = 120.0
_FINE = ((0.3, 1.2), 64, 0.03)


class SkinRegions(NamedTuple):
    """Where the face has brows and lips, for :func:`skin_albedo`.

    Attributes
    ----------
    labels : (n,) int64 array
        Face region of each queried point, an index into ``names`` (e.g. the
        ICT sample's ``region_labels`` when the points are its vertices).
    names : tuple of str
        Region names; ``'brows'`` gets brow hair and ``'mouth'`` (when
        ``lip_outline`` is given) the vermilion of the lips.
    lip_outline : (k, 3) float64 array, mm, or None
        The outer lip contour in the material frame, in order around the
        mouth (dlib-68 landmarks 48..59, e.g.
        ``mesh.vertices[landmarks[48:60]]``). None: no lip colour.
    """

    labels: IntArray
    names: tuple[str, ...]
    lip_outline: FloatArray | None = None


def _waves(rng: np.random.Generator, band: tuple[float, float], count: int) -> tuple[FloatArray, FloatArray]:
    """Random wave vectors (count, 3), rad/mm, with log-uniform wavelengths in ``band``, and phases."""
    direction = rng.normal(size=(count, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    wavelength = np.exp(rng.uniform(np.log(band[0]), np.log(band[1]), count))
    return direction * (2.0 * np.pi / wavelength)[:, None], rng.uniform(0.0, 2.0 * np.pi, count)


def band_noise(points: FloatArray, wavelengths_mm: tuple[float, float], *, waves: int,
               rng: np.random.Generator) -> FloatArray:
    """Unit-variance band-limited solid noise at ``points`` (mm): ``waves`` random-phase cosines.

    Isotropic directions, log-uniform wavelengths in ``wavelengths_mm``:
    ``sqrt(2/K) sum_k cos(k_k . p + phi_k)``, smooth and with no lattice; a function of the point alone
    for a given ``rng`` state.

    Examples
    --------
    >>> P = np.random.default_rng(0).uniform(-50, 50, (20000, 3))
    >>> round(float(band_noise(P, (2.0, 6.0), waves=256, rng=np.random.default_rng(1)).std()), 1)
    1.0
    """
    return _band_noise(np.asarray(points, dtype=np.float64), *_waves(rng, wavelengths_mm, int(waves)))


def _band_noise(P: FloatArray, k: FloatArray, phase: FloatArray) -> FloatArray:
    """Unit-variance band-limited noise at points ``P``: sum of random-phase cosines."""
    out = np.empty(P.shape[0])
    for a in range(0, P.shape[0], 8192):  # blocks bound the (block, waves) temporary
        out[a : a + 8192] = np.cos(P[a : a + 8192] @ k.T + phase).sum(axis=1)
    return out * np.sqrt(2.0 / k.shape[0])


def _hash_uniform(keys: np.ndarray) -> FloatArray:
    """Uniform [0, 1) numbers from uint64 keys (splitmix64 finaliser), elementwise."""
    z = keys.astype(np.uint64, copy=True)
    z += np.uint64(0x9E3779B97F4A7C15)
    z ^= z >> np.uint64(30)
    z *= np.uint64(0xBF58476D1CE4E5B9)
    z ^= z >> np.uint64(27)
    z *= np.uint64(0x94D049BB133111EB)
    z ^= z >> np.uint64(31)
    return (z >> np.uint64(11)).astype(np.float64) / float(2**53)


def _freckle_darkening(P: FloatArray, seed_key: int, *, cell: float = _FRECKLE_CELL_MM,
                       radius_mm: tuple[float, float] = _FRECKLE_RADIUS_MM,
                       darkness: tuple[float, float] = _FRECKLE_DARKNESS,
                       per_cm2: float = _FRECKLES_PER_CM2) -> FloatArray:
    """(n,) fraction of light removed by freckles and moles: a 3D Poisson field of balls.

    Space is cut into cubes of ``_FRECKLE_CELL_MM``; each cube holds up to
    ``_FRECKLE_SLOTS`` ball centres, each present with a probability drawn from
    a hash of (cube, slot, seed), so the field is a function of the point alone.
    """
    r_lo, r_hi = radius_mm
    # a ball of radius r meets a surface within r of its centre: volume density = surface density / (2 mean r)
    per_mm2 = per_cm2 / 100.0
    p_slot = per_mm2 / (2.0 * 0.5 * (r_lo + r_hi)) * cell**3 / _FRECKLE_SLOTS
    base = np.floor(P / cell).astype(np.int64)
    out = np.zeros(P.shape[0])
    salt = np.array([seed_key], dtype=np.int64).view(np.uint64)
    offsets = np.stack(np.meshgrid([-1, 0, 1], [-1, 0, 1], [-1, 0, 1], indexing="ij"), -1).reshape(-1, 3)
    for off in offsets:
        c = (base + off).view(np.uint64)
        key = (c[:, 0] * np.uint64(0x8DA6B343)) ^ (c[:, 1] * np.uint64(0xD8163841)) \
            ^ (c[:, 2] * np.uint64(0xCB1AB31F)) ^ salt
        for slot in range(_FRECKLE_SLOTS):
            k = _hash_uniform(key ^ np.uint64(0x165667B1 * (slot + 1)))
            u = [_hash_uniform(k.view(np.uint64) + np.uint64(j + 1)) for j in range(6)]
            present = k < p_slot
            if not present.any():
                continue
            centre = (base + off + np.stack(u[:3], 1)) * cell
            radius = r_lo + (r_hi - r_lo) * u[3]
            depth = darkness[0] + (darkness[1] - darkness[0]) * u[4]
            d2 = np.einsum("kd,kd->k", P - centre, P - centre) / radius**2
            # a soft-edged spot: full depth in the middle, smooth to 0 at the radius
            profile = np.clip(1.0 - d2, 0.0, 1.0) ** 0.5
            out = np.maximum(out, np.where(present, depth * profile, 0.0))
    return out


def _lip_weight(P: FloatArray, outline: FloatArray, *, edge_mm: float = 1.0) -> FloatArray:
    """(n,) 1 inside the lip outline (projected on its plane), fading to 0 over ``edge_mm``."""
    centre = outline.mean(axis=0)
    _, _, Vt = np.linalg.svd(outline - centre)
    q = (P - centre) @ Vt[:2].T
    poly = (outline - centre) @ Vt[:2].T
    a, b = poly, np.roll(poly, -1, axis=0)
    # crossing number, vectorised over points x edges
    qy, qx = q[:, 1:2], q[:, 0:1]
    straddle = (a[:, 1] > qy) != (b[:, 1] > qy)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = a[:, 0] + (qy - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    inside = (np.count_nonzero(straddle & (qx < x_cross), axis=1) % 2) == 1
    ab = b - a
    t = np.clip(((q[:, None, :] - a) * ab).sum(-1) / (ab * ab).sum(-1), 0.0, 1.0)
    dist = np.linalg.norm(q[:, None, :] - (a + t[..., None] * ab), axis=2).min(axis=1)
    near_plane = np.abs((P - centre) @ Vt[2]) < 15.0
    return np.where(inside & near_plane, np.clip(dist / edge_mm, 0.0, 1.0), 0.0)


def skin_albedo(
    points: FloatArray,
    *,
    seed: int = 0,
    region: SkinRegions | None = None,
) -> FloatArray:
    """Linear-light RGB reflectance of facial skin at material points: a solid texture.

    The colour is a function of the 3D material point alone (its rest position
    on the neutral face, mm), so a point of skin keeps its colour however the
    face moves: evaluate it at the rest positions, never at posed ones.

    Parameters
    ----------
    points : (n, 3) float64 array, mm
        Material points: positions on the rest (neutral) surface of the identity.
    seed : int, default 0
        Seeds the skin tone, the noise fields and the freckles (one skin per seed).
    region : SkinRegions or None, optional
        Per-point face regions: brows get hair, lips (inside
        ``region.lip_outline``) vermilion. None (default): skin everywhere.

    Returns
    -------
    (n, 3) float64 array
        Linear RGB reflectance in [0, 1] (not sRGB-encoded; see
        :func:`~facecap.synth.capture_colors.capture_colors` for what a camera records).

    Raises
    ------
    InputError
        If ``points`` is not a finite (n, 3) array or ``region.labels`` has not n entries.

    Notes
    -----
    The albedo is a product of factors on a per-seed base tone ``c0``
    (:data:`BASE_SKIN_TONE` times a luminance in [0.85, 1.15] and a small
    red/yellow shift):

    .. math:: a(p) = c_0 (1 + 0.03 n_1(p)) (1 + 0.015 n_2(p) (1, -\\tfrac12, -\\tfrac12))
              (1 + 0.025 n_3(p)) (1 - f(p) t) (1 - b(p)) l(p)

    ``n_1, n_2`` are unit-variance blotch noises with wavelengths 15-40 mm
    (luminance, redness), ``n_3`` mottling at 3-8 mm; each is a sum of 192-256
    random-phase cosines ``sqrt(2/K) sum_k cos(k_k . p + phi_k)`` with
    isotropic directions and log-uniform wavelengths (band-limited, smooth,
    no lattice). ``f`` is the darkening of freckles and moles (10-30 %,
    bluish channels more: brown): balls of radius 0.8-2.5 mm centred by a 3D
    Poisson process hashed per 6 mm cube, with a volume density that puts
    about 0.6 spots per cm^2 on a surface. ``b`` darkens brow hair by 40 %
    times a fine stripe texture (0.7 mm period across the hairs); ``l``
    tints the vermilion of the lips (0.97, 0.72, 0.76).

    Examples
    --------
    >>> import numpy as np
    >>> P = np.random.default_rng(0).uniform(-50, 50, (1000, 3))
    >>> a = skin_albedo(P, seed=1)
    >>> a.shape, bool(np.all((a > 0) & (a < 1)))
    ((1000, 3), True)
    >>> bool(np.allclose(skin_albedo(P[:10], seed=1), a[:10]))
    True
    """
    return skin_albedo_layers(points, seed=seed, region=region).albedo


class SkinLayers(NamedTuple):
    """The albedo and where its marks are (:func:`skin_albedo_layers`).

    Attributes
    ----------
    albedo : (n, 3) float64 array
        Linear RGB reflectance, as :func:`skin_albedo` (with moles when asked).
    freckles : (n,) float64 array
        Fraction of light the freckles remove (before their tint), 0 off them.
    moles : (n,) float64 array
        The same for moles (all 0 without them).
    brows : (n,) bool array
        The brow hair.
    """

    albedo: FloatArray
    freckles: FloatArray
    moles: FloatArray
    brows: np.ndarray


def skin_albedo_layers(
    points: FloatArray,
    *,
    seed: int = 0,
    region: SkinRegions | None = None,
    moles: bool = False,
    pores: bool = False,
) -> SkinLayers:
    """:func:`skin_albedo`, with moles when asked, and the marks apart: where nothing deep should be read.

    Parameters
    ----------
    points, seed, region
        As :func:`skin_albedo` (the same albedo for the same arguments without moles).
    moles : bool, default False
        Add moles: the freckles' hashed field with its own constants, about 0.03 per cm^2, radius
        0.9-1.8 mm, 45-65 % darker (brown), from a stream of their own (the rest of the skin is unchanged).
    pores : bool, default False
        Add what a scanner's texture resolves at 0.1-0.5 mm a texel: pores (the same hashed field,
        0.1-0.4 mm across, about 120 per cm^2, 10-30 % darker) and a fine luminance noise (3 %,
        wavelengths 0.3-1.2 mm), from streams of their own (the rest of the skin is unchanged).
        Evaluate it where it is resolved: at 1 mm spacing it only adds noise.

    Returns
    -------
    SkinLayers
    """
    P = as_points(points, name="points")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x5C1A]))
    tone = np.array(BASE_SKIN_TONE) * rng.uniform(0.85, 1.15)
    tone *= np.array([1.0, 1.0 - 0.04 * rng.uniform(-1, 1), 1.0 - 0.08 * rng.uniform(-1, 1)])

    blotch_l = _band_noise(P, *_waves(rng, _BLOTCH[0], _BLOTCH[1]))
    blotch_r = _band_noise(P, *_waves(rng, _BLOTCH[0], _BLOTCH[1]))
    mottle = _band_noise(P, *_waves(rng, _MOTTLE[0], _MOTTLE[1]))
    a = np.broadcast_to(tone, P.shape).copy()
    a *= (1.0 + _BLOTCH[2] * blotch_l)[:, None]
    a *= 1.0 + _BLOTCH[3] * blotch_r[:, None] * np.array([1.0, -0.5, -0.5])
    a *= (1.0 + _MOTTLE[2] * mottle)[:, None]
    freckle_key = int(rng.integers(0, 2**62))
    freckles = _freckle_darkening(P, freckle_key)
    a *= 1.0 - np.clip(freckles[:, None] * _FRECKLE_TINT, 0.0, 0.9)
    mole = np.zeros(P.shape[0])
    if moles:
        mole_key = int(np.random.default_rng(np.random.SeedSequence([int(seed), 0x301E])).integers(0, 2**62))
        mole = _freckle_darkening(P, mole_key, cell=_MOLE_CELL_MM, radius_mm=_MOLE_RADIUS_MM,
                                  darkness=_MOLE_DARKNESS, per_cm2=_MOLES_PER_CM2)
        a *= 1.0 - np.clip(mole[:, None] * _MOLE_TINT, 0.0, 0.9)
    if pores:
        pore_rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x9023]))
        pore_key = int(pore_rng.integers(0, 2**62))
        a *= (1.0 - _freckle_darkening(P, pore_key, cell=_PORE_CELL_MM, radius_mm=_PORE_RADIUS_MM,
                                       darkness=_PORE_DARKNESS, per_cm2=_PORES_PER_CM2))[:, None]
        a *= (1.0 + _FINE[2] * _band_noise(P, *_waves(pore_rng, _FINE[0], _FINE[1])))[:, None]
    brow = np.zeros(P.shape[0], dtype=bool)

    if region is not None:
        labels = np.asarray(region.labels, dtype=np.int64).reshape(-1)
        if labels.shape[0] != P.shape[0]:
            raise InputError(
                f"region.labels: expected one label per point ({P.shape[0]}), got {labels.shape[0]}"
            )
        names = list(region.names)
        stripe_dir = rng.normal(size=3)
        stripe_dir /= np.linalg.norm(stripe_dir)
        if "brows" in names:
            brow = labels == names.index("brows")
            stripes = 0.5 + 0.5 * np.cos(2.0 * np.pi * (P @ stripe_dir) / _BROW_STRIPE_MM
                                         + 3.0 * mottle)
            a[brow] *= (1.0 - _BROW_DARKNESS * (0.6 + 0.4 * stripes[brow]))[:, None]
        if region.lip_outline is not None and "mouth" in names:
            outline = as_points(region.lip_outline, name="region.lip_outline")
            mouth = np.flatnonzero(labels == names.index("mouth"))
            if mouth.size and outline.shape[0] >= 3:
                w = _lip_weight(P[mouth], outline)
                a[mouth] *= 1.0 + w[:, None] * (_LIP_TINT - 1.0)
    return SkinLayers(np.clip(a, 0.0, 1.0), freckles, mole, brow)

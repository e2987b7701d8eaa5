"""Skin radiance under calibrated lights: Phong (the detail layer's model) and an independent microfacet skin.

Both take the lights of :class:`~facecap.cameras.LightSetup` (irradiance with inverse-square falloff and the
spot's cone, :meth:`~facecap.cameras.Light.arriving`), which of them each point sees (cast shadows,
:meth:`~facecap.cameras.RayCaster.lit`), and an ambient term weighted by the sky's visibility (ambient
occlusion). Radiance is linear, as a fraction of the sensor's full scale; the specular is white and depends
on the eye, so each camera gets its own (``eyes``).

``appearance='phong'`` (Lo et al., eq. 3, with an ambient term and several lights)::

    L = k_d albedo (ambient A + sum_l s_l E_l max(0, n.l)) + k_s sum_l s_l E_l [n.l > 0] max(0, r.e)^alpha

with ``r = 2 (n.l) n - l`` the mirror of the light direction, ``e`` the unit vector toward the eye,
``s_l`` 1 where light ``l`` is seen, ``E_l`` its irradiance, ``A`` the ambient occlusion.

``appearance='independent'`` (held out from the solver: not its model): a wrapped diffuse, wider in red
than in blue as subsurface scattering spreads red light furthest, ``E max(0, (n.l + w_c) / (1 + w_c))``
with ``w = (0.5, 0.3, 0.2)``, blurred over the surface (:func:`subsurface_blur`), and a Trowbridge-Reitz
(GGX) specular with Schlick's Fresnel (``F0 = 0.028``, skin's oil layer at n = 1.4) and Smith-Schlick
shadowing::

    L_s = rho_s sum_l s_l E_l D(n.h) F(e.h) G(n.l, n.e) / (4 n.e),  D = a^2 / (pi ((n.h)^2 (a^2 - 1) + 1)^2)

with ``a = roughness^2``.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..typing import FloatArray, IntArray

__all__ = ["APPEARANCES", "REGION_REFLECTANCE", "Shading", "region_reflectance", "shade_skin", "skin_radiance",
           "subsurface_blur"]

APPEARANCES = ("phong", "independent")
"""The reflectance models of the detail footage."""

REGION_REFLECTANCE: dict[str, dict[str, tuple[float, float, float]]] = {
    # Phong: (k_d scale, k_s, alpha); the T-zone oilier (higher k_s, sharper), the cheeks matte
    "phong": {"forehead": (1.0, 0.20, 32.0), "nose": (1.0, 0.26, 45.0), "cheeks": (1.0, 0.06, 10.0),
              "brows": (0.9, 0.03, 5.0), "eyes": (1.0, 0.10, 16.0), "mouth": (1.0, 0.12, 20.0),
              "chin_jaw": (1.0, 0.09, 16.0), "other": (1.0, 0.05, 8.0)},
    # independent: (k_d scale, specular scale rho_s, GGX roughness)
    "independent": {"forehead": (1.0, 1.0, 0.32), "nose": (1.0, 1.2, 0.27), "cheeks": (1.0, 0.6, 0.48),
                    "brows": (0.9, 0.3, 0.60), "eyes": (1.0, 0.8, 0.38), "mouth": (1.0, 0.9, 0.33),
                    "chin_jaw": (1.0, 0.7, 0.42), "other": (1.0, 0.5, 0.50)},
}
"""Per face region and appearance, the three reflectance numbers of each vertex (:func:`region_reflectance`)."""

_WRAP = np.array([0.5, 0.3, 0.2])
_F0 = 0.028
_BLUR_STEPS = (3, 2, 1)  # neighbour averages of the diffuse irradiance per channel (red spreads furthest)


class Shading(NamedTuple):
    """What the lights do at each vertex, before the albedo (:func:`shade_skin`).

    Attributes
    ----------
    irradiance : (n, 3) float64 array
        Diffuse irradiance per colour channel (the same in every channel for Phong).
    specular : (c, n) float64 array
        White specular radiance toward each of the ``c`` eyes.
    """

    irradiance: FloatArray
    specular: FloatArray


def region_reflectance(labels: IntArray, names: Any, *, appearance: str = "phong") -> FloatArray:
    """(n, 3) float64 reflectance numbers of each vertex from its face region (:data:`REGION_REFLECTANCE`).

    Examples
    --------
    >>> region_reflectance(np.array([0, 1]), ("forehead", "cheeks")).tolist()
    [[1.0, 0.2, 32.0], [1.0, 0.06, 10.0]]
    """
    if appearance not in REGION_REFLECTANCE:
        raise InputError(f"appearance: expected one of {list(APPEARANCES)}, got {appearance!r}")
    table = REGION_REFLECTANCE[appearance]
    rows = np.array([table.get(str(name), table["other"]) for name in names], dtype=np.float64)
    return rows[np.asarray(labels, dtype=np.int64)]


def _unit(x: FloatArray) -> FloatArray:
    return x / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-12)


def shade_skin(
    points: FloatArray,
    normals: FloatArray,
    reflectance: FloatArray,
    lights: Any,
    eyes: FloatArray,
    *,
    lit: Any = None,
    occlusion: FloatArray | None = None,
    appearance: str = "phong",
) -> Shading:
    """The diffuse irradiance and each eye's specular radiance at points of the skin.

    Parameters
    ----------
    points : (n, 3) float array, mm
        In the lights' frame (the mocap frame).
    normals : (n, 3) float array
        Unit outward normals.
    reflectance : (n, 3) float array
        :func:`region_reflectance` for ``appearance`` (the diffuse scale is applied by :func:`skin_radiance`).
    lights : LightSetup
    eyes : (c, 3) float array, mm
        Camera centres.
    lit : (k, n) bool array, optional
        Whether each point sees each of the ``k`` lights (:meth:`~facecap.cameras.RayCaster.lit`);
        default all lit.
    occlusion : (n,) float array, optional
        Ambient occlusion in [0, 1] weighting the ambient light; default 1.
    appearance : {'phong', 'independent'}, default 'phong'
        See the module's notes.

    Returns
    -------
    Shading
    """
    if appearance not in APPEARANCES:
        raise InputError(f"appearance: expected one of {list(APPEARANCES)}, got {appearance!r}")
    P = np.asarray(points, dtype=np.float64)
    N = np.asarray(normals, dtype=np.float64)
    R = np.asarray(reflectance, dtype=np.float64)
    E_eyes = np.atleast_2d(np.asarray(eyes, dtype=np.float64))
    n = P.shape[0]
    if N.shape != P.shape or R.shape != (n, 3):
        raise InputError(f"normals, reflectance: expected ({n}, 3) each, got {N.shape} and {R.shape}")
    k = len(lights.lights)
    seen = np.ones((k, n), dtype=bool) if lit is None else np.asarray(lit, dtype=bool).reshape(k, n)
    ambient = lights.ambient * (np.ones(n) if occlusion is None else np.asarray(occlusion, dtype=np.float64))
    irradiance = np.repeat(ambient[:, None], 3, axis=1)
    specular = np.zeros((E_eyes.shape[0], n))
    views = [_unit(eye - P) for eye in E_eyes]
    for light, s in zip(lights.lights, seen):
        to_light, E = light.arriving(P)
        E = np.where(s, E, 0.0)
        cos_l = np.einsum("ij,ij->i", N, to_light)
        front = cos_l > 0
        if appearance == "phong":
            irradiance += (E * np.maximum(cos_l, 0.0))[:, None]
            mirror = 2.0 * cos_l[:, None] * N - to_light
            for c, view in enumerate(views):
                cos_r = np.maximum(np.einsum("ij,ij->i", mirror, view), 0.0)
                specular[c] += np.where(front, R[:, 1] * E * cos_r ** R[:, 2], 0.0)
            continue
        irradiance += E[:, None] * np.maximum((cos_l[:, None] + _WRAP) / (1.0 + _WRAP), 0.0)
        a2 = R[:, 2] ** 4  # a = roughness^2
        k_g = R[:, 2] ** 2 / 2.0
        for c, view in enumerate(views):
            cos_v = np.einsum("ij,ij->i", N, view)
            half = _unit(to_light + view)
            cos_h = np.clip(np.einsum("ij,ij->i", N, half), 0.0, 1.0)
            D = a2 / (np.pi * (cos_h**2 * (a2 - 1.0) + 1.0) ** 2)
            F = _F0 + (1.0 - _F0) * (1.0 - np.clip(np.einsum("ij,ij->i", view, half), 0.0, 1.0)) ** 5
            cl, cv = np.maximum(cos_l, 1e-6), np.maximum(cos_v, 1e-6)
            G = cl / (cl * (1 - k_g) + k_g) * cv / (cv * (1 - k_g) + k_g)
            specular[c] += np.where(front & (cos_v > 0), R[:, 1] * E * D * F * G / (4.0 * cv), 0.0)
    return Shading(irradiance, specular)


def skin_radiance(shading: Shading, albedo: FloatArray, reflectance: FloatArray) -> FloatArray:
    """(c, n, 3) radiance toward each eye: ``k_d albedo irradiance + specular`` (linear, of full scale)."""
    diffuse = np.asarray(albedo, dtype=np.float64) * np.asarray(reflectance)[:, :1] * shading.irradiance
    return diffuse[None] + shading.specular[:, :, None]


def subsurface_blur(irradiance: FloatArray, faces: IntArray) -> FloatArray:
    """The diffuse irradiance spread over the surface as light scattered under the skin: (n, 3) -> (n, 3).

    Each channel is replaced by the mean over a vertex and its neighbours, repeated 3 (red), 2
    (green) and 1 (blue) times: red light travels furthest in skin. On the detail scan (0.3 mm edges
    at the lines) that spreads red over about 1 mm, softening the lines as real skin does.
    """
    X = np.asarray(irradiance, dtype=np.float64)
    F = np.asarray(faces, dtype=np.int64)
    n = X.shape[0]
    rows = np.concatenate([F[:, 0], F[:, 1], F[:, 2], F[:, 1], F[:, 2], F[:, 0], np.arange(n)])
    cols = np.concatenate([F[:, 1], F[:, 2], F[:, 0], F[:, 0], F[:, 1], F[:, 2], np.arange(n)])
    A = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    A.data[:] = 1.0  # duplicates (an edge seen from both triangles) count once
    A = sp.diags(1.0 / np.asarray(A.sum(axis=1)).ravel()) @ A
    out = X.copy()
    for channel, steps in enumerate(_BLUR_STEPS):
        for _ in range(steps):
            out[:, channel] = A @ out[:, channel]
    return out

"""Phong's reflection at each surface sample (Lo et al., eq. 3), with its derivative along the normal.

``Syn = a (ambient + sum_l s_l E_l max(0, n.l_l)) + k_s sum_l s_l E_l max(0, r_l.e)^alpha [n.l_l > 0]``

with ``a`` the diffuse albedo (``k_d`` of the paper, per sample or per region),
``E_l`` the irradiance light ``l`` sends to a surface facing it (its direction and
inverse-square falloff: :meth:`facecap.cameras.Light.arriving`), ``s_l`` 1 where
the light is not blocked (:meth:`facecap.cameras.RayCaster.lit`), ``l_l`` the
unit direction toward it, ``r_l = 2 (n.l_l) n - l_l`` its mirror direction,
``e`` the unit direction toward the camera and ``alpha`` the Phong exponent. The
paper's eq. 3 has one light and no ambient; the sum and the ambient are the
stage's other lights and the room.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..typing import FloatArray

__all__ = ["PhongShading", "phong_shading"]


class PhongShading(NamedTuple):
    """Radiance and its parts at each sample.

    Attributes
    ----------
    radiance : (...) float64 array
        ``albedo * diffuse + k_s * specular``.
    diffuse : (...) float64 array
        ``ambient + sum_l s_l E_l max(0, n.l)``: what the albedo multiplies.
    specular : (...) float64 array
        ``sum_l s_l E_l max(0, r.e)^alpha``: what ``k_s`` multiplies.
    d_normal : (..., 3) float64 array or None
        ``d radiance / d n``, the normal taken as a free vector (project it onto the
        tangent plane of the unit normal for the derivative along the sphere).
    """

    radiance: FloatArray
    diffuse: FloatArray
    specular: FloatArray
    d_normal: FloatArray | None


def phong_shading(normals: FloatArray, to_light: FloatArray, irradiance: FloatArray, to_eye: FloatArray, *,
                  albedo: FloatArray | float = 1.0, k_s: FloatArray | float = 0.0, alpha: FloatArray | float = 10.0,
                  ambient: float = 0.0, gradient: bool = False) -> PhongShading:
    """Phong's radiance toward the camera at each sample.

    Parameters
    ----------
    normals : (..., 3) float array
        Unit surface normals.
    to_light : (L, ..., 3) float array
        Unit directions toward each light.
    irradiance : (L, ...) float array
        Irradiance each light sends to a surface facing it, shadows included (0 where blocked).
    to_eye : (..., 3) float array
        Unit directions toward the camera.
    albedo, k_s, alpha : float or (...) float arrays
        Diffuse albedo, specular coefficient and Phong exponent (> 0).
    ambient : float, default 0
        Irradiance from everywhere (the albedo reflects it).
    gradient : bool, default False
        Also return ``d radiance / d n``.

    Returns
    -------
    PhongShading

    Examples
    --------
    >>> import numpy as np
    >>> n = np.array([[0.0, 0.0, 1.0]]); l = np.array([[[0.0, 0.6, 0.8]]])
    >>> out = phong_shading(n, l, np.array([[2.0]]), np.array([[0.0, -0.6, 0.8]]), albedo=0.5, k_s=0.1, alpha=4)
    >>> round(float(out.diffuse[0]), 12), round(float(out.specular[0]), 12), round(float(out.radiance[0]), 12)
    (1.6, 2.0, 1.0)
    """
    n = np.asarray(normals, dtype=np.float64)
    L = np.asarray(to_light, dtype=np.float64)
    E = np.asarray(irradiance, dtype=np.float64)
    e = np.asarray(to_eye, dtype=np.float64)
    a = np.asarray(albedo, dtype=np.float64)
    ks = np.asarray(k_s, dtype=np.float64)
    al = np.asarray(alpha, dtype=np.float64)
    nl = np.einsum("...k,...k->...", n[None], L)  # (L, ...)
    facing = nl > 0
    diffuse = float(ambient) + np.sum(E * np.where(facing, nl, 0.0), axis=0)
    ne = np.einsum("...k,...k->...", n, e)
    le = np.einsum("...k,...k->...", L, e[None])
    re = 2.0 * nl * ne[None] - le  # r.e with r = 2 (n.l) n - l
    lobe_on = facing & (re > 0)
    base = np.where(lobe_on, re, 1.0)
    lobe = np.where(lobe_on, base ** al, 0.0)
    specular = np.sum(E * lobe, axis=0)
    radiance = a * diffuse + ks * specular
    d_normal = None
    if gradient:
        # d(n.l)/dn = l; d(r.e)/dn = 2 (n.e) l + 2 (n.l) e
        d_diffuse = np.sum((E * facing)[..., None] * L, axis=0)
        slope = np.where(lobe_on, al * base ** (al - 1.0), 0.0) * E
        d_re = 2.0 * ne[None, ..., None] * L + 2.0 * nl[..., None] * e[None]
        d_specular = np.sum(slope[..., None] * d_re, axis=0)
        d_normal = a[..., None] * d_diffuse + ks[..., None] * d_specular
    return PhongShading(radiance, diffuse, specular, d_normal)

"""Render a chrome sphere as calibrated cameras see it, lit by one light: the footage ``facecap calibrate-light`` reads.

Every sub-pixel sample's ray (:meth:`facecap.cameras.Camera.pixel_rays`, so the
lens distortion is the camera's own model) is intersected with the sphere
exactly; where it hits, the mirror reflection

.. math:: \\mathbf{r} = \\mathbf{d} - 2 (\\mathbf{d} \\cdot \\mathbf{n}) \\mathbf{n}

is followed to the light's emitter (a spherical bulb of radius ``bulb_radius_mm``
for a point light, the front glass of a spot, a disc of ``sun_radius_deg`` for a
directional light) or else to a dim room (a smooth function of the direction,
brighter above). The camera sees a dark backdrop where its rays miss the sphere.
Each pixel is the mean of ``supersample x supersample`` samples (a box filter,
what a sensor's pixel integrates), blurred by the lens's point spread
(``blur_px``), then optional shot and read noise
(:func:`~facecap.synth.sensor_noise`) and 8-bit sRGB or 16-bit linear codes.

Simplifications, said once: the bulb seen directly (not in the sphere) is not
drawn; the sphere does not reflect itself or the cameras; the backdrop is not
what the sphere's rim reflects (a real rim reflects what is behind it, which
can darken its outermost pixel: see ``docs/cameras.md``, "Lights").
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..cameras.image_to_float import linear_to_srgb
from ..errors import InputError
from ..typing import FloatArray
from .render_footage import quantize, sensor_noise

__all__ = ["render_mirror_sphere", "MIRROR_SPHERE_DEFAULTS"]

MIRROR_SPHERE_DEFAULTS = {
    "reflectance": 0.6,  # polished chrome reflects about 60 % of visible light at normal incidence
    "environment": 0.35,  # the room's radiance seen in the sphere, as a fraction of full scale
    "background": 0.04,  # the dark backdrop around the sphere
    "bulb_radiance": 50.0,  # the emitter, far above full scale: its reflection saturates, as on a real stage
}
"""Radiances (fractions of the sensor's full scale, linear) and the chrome's reflectance."""

_TINT = np.array([1.0, 0.95, 0.85])  # a warm room: the channels differ a little, as real footage does


def _environment(directions: FloatArray, level: float) -> FloatArray:
    """A dim room: brighter above (+y), a gentle variation round the vertical; (..., 3) directions to (...) radiance."""
    up = directions[..., 1]
    azimuth = np.arctan2(directions[..., 0], directions[..., 2])
    return level * (0.75 + 0.25 * up) * (1.0 + 0.1 * np.sin(3.0 * azimuth))


def _emitter_hit(origins: FloatArray, directions: FloatArray, light: Any, bulb_radius_mm: float,
                 sun_radius_deg: float) -> np.ndarray:
    """Whether each reflected ray (origins on the sphere, unit directions) reaches the light's emitter."""
    if light.kind == "directional":
        return directions @ (-light.direction) >= np.cos(np.radians(sun_radius_deg))
    offset = light.position - origins
    if light.kind == "point":  # a spherical bulb: the ray passes within its radius, ahead of the origin
        along = np.einsum("ij,ij->i", offset, directions)
        miss2 = np.einsum("ij,ij->i", offset, offset) - along ** 2
        return (along > 0) & (miss2 <= bulb_radius_mm ** 2)
    # a spot's front glass: a disc of the bulb's radius facing along the spot's axis, lit within its cone
    axis = light.direction
    facing = directions @ axis
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (offset @ axis) / facing
    hit = origins + t[:, None] * directions
    on_disc = np.linalg.norm(hit - light.position, axis=1) <= bulb_radius_mm
    inside_cone = -facing >= np.cos(np.radians(light.cone_deg))
    return (t > 0) & on_disc & inside_cone


def _sphere_box(camera: Any, centre: FloatArray, radius: float, *, pad_px: int) -> tuple[int, int, int, int] | None:
    """The pixel box (u0, v0, u1, v1), inclusive, that holds the sphere's image, padded; None if unseen."""
    k = np.arange(4000) + 0.5  # Fibonacci points on the sphere: its image's extent to well under a pixel
    z = 1 - 2 * k / 4000
    phi = np.pi * (1 + 5 ** 0.5) * k
    ring = np.sqrt(1 - z * z)
    points = centre + radius * 1.0005 * np.stack([ring * np.cos(phi), ring * np.sin(phi), z], axis=1)
    seen = camera.project(points)
    if not np.all(seen.in_front):
        raise InputError(f"camera {camera.name!r}: the sphere is not wholly in front of the camera")
    u0, v0 = np.floor(seen.pixels.min(axis=0)).astype(int) - pad_px
    u1, v1 = np.ceil(seen.pixels.max(axis=0)).astype(int) + pad_px
    u0, v0 = max(u0, 0), max(v0, 0)
    u1, v1 = min(u1, camera.width - 1), min(v1, camera.height - 1)
    if u0 > u1 or v0 > v1:
        return None
    return int(u0), int(v0), int(u1), int(v1)


def render_mirror_sphere(
    cameras: Sequence[Any],
    centre_mm: Any,
    radius_mm: float,
    light: Any,
    *,
    bulb_radius_mm: float = 30.0,
    sun_radius_deg: float = 0.5,
    reflectance: float = MIRROR_SPHERE_DEFAULTS["reflectance"],
    environment: float = MIRROR_SPHERE_DEFAULTS["environment"],
    background: float = MIRROR_SPHERE_DEFAULTS["background"],
    bulb_radiance: float = MIRROR_SPHERE_DEFAULTS["bulb_radiance"],
    supersample: int = 4,
    blur_px: float = 0.7,
    rng: np.random.Generator | None = None,
    bits: int = 8,
) -> list[np.ndarray]:
    """Each camera's image of a chrome sphere reflecting one light and a dim room.

    Parameters
    ----------
    cameras : sequence of Camera
        :class:`facecap.cameras.Camera`, mocap frame, mm.
    centre_mm : (3,) array, mm
        The sphere's centre.
    radius_mm : float, mm
        The sphere's radius (> 0).
    light : Light
        :class:`facecap.cameras.Light`; a ``'point'`` light is a bulb of
        ``bulb_radius_mm``, a ``'spot'`` a front glass of that radius facing its
        axis (seen only within its cone), a ``'directional'`` one a disc of
        ``sun_radius_deg``.
    bulb_radius_mm : float, default 30
    sun_radius_deg : float, default 0.5
    reflectance, environment, background, bulb_radiance : float
        The chrome's reflectance and the linear radiances (fractions of full
        scale) of the room, the backdrop and the emitter
        (:data:`MIRROR_SPHERE_DEFAULTS`).
    supersample : int, default 4
        Samples per pixel along each axis (box filter); >= 1.
    blur_px : float, default 0.7
        The lens's point spread, a Gaussian's standard deviation in px, applied to
        the radiance before the pixels integrate it and the sensor clips it (a
        saturated highlight keeps an unsaturated skirt, as through a real lens); 0 for none.
    rng : numpy.random.Generator or None, default None
        Sensor noise (:func:`~facecap.synth.sensor_noise`) when given; none otherwise.
    bits : {8, 16}, default 8
        8: sRGB-encoded ``uint8`` (PNG, ordinary video); 16: linear ``uint16``.

    Returns
    -------
    list of (H, W, 3) uint8 or uint16 arrays
        One RGB image per camera, at its calibrated size.

    Raises
    ------
    InputError
        A non-positive radius or supersampling, ``bits`` not 8 or 16, a sphere
        not wholly in front of a camera.

    Examples
    --------
    >>> from facecap.cameras import Camera, Light
    >>> cam = Camera.look_at("c", [0, 0, 700], [0, 0, 0], focal_px=800, width=96, height=72)
    >>> image, = render_mirror_sphere([cam], [0, 0, 0], 25.0, Light("point", position=[300, 500, 900]))
    >>> image.shape, image.dtype, int(image[36, 48, 0]) > int(image[2, 2, 0])
    ((72, 96, 3), dtype('uint8'), True)
    """
    centre = np.asarray(centre_mm, dtype=np.float64).reshape(3)
    radius = float(radius_mm)
    if not radius > 0 or not np.all(np.isfinite(centre)):
        raise InputError(f"radius_mm: expected a positive radius and a finite centre, got {radius_mm!r}, {centre_mm!r}")
    if int(supersample) < 1:
        raise InputError(f"supersample: expected >= 1, got {supersample!r}")
    if bits not in (8, 16):
        raise InputError(f"bits: expected 8 or 16, got {bits!r}")
    import cv2

    s = int(supersample)
    offsets = (np.arange(s) + 0.5) / s - 0.5  # sub-pixel sample positions about the pixel centre
    images = []
    for camera in cameras:
        linear = np.empty((camera.height, camera.width, 3))
        linear[:] = background * _TINT
        box = _sphere_box(camera, centre, radius, pad_px=2 + int(np.ceil(4 * max(blur_px, 0.0))))
        if box is not None:
            u0, v0, u1, v1 = box
            u = (np.arange(u0, u1 + 1)[:, None] + offsets[None, :]).ravel()
            v = (np.arange(v0, v1 + 1)[:, None] + offsets[None, :]).ravel()
            uu, vv = np.meshgrid(u, v)
            origins, d = camera.pixel_rays(np.stack([uu.ravel(), vv.ravel()], axis=1))
            # |o + t d - c|^2 = r^2 with |d| = 1: t = -b - sqrt(b^2 - c), b = d.(o - c), c = |o - c|^2 - r^2
            oc = origins - centre
            b = np.einsum("ij,ij->i", d, oc)
            disc = b * b - (np.einsum("ij,ij->i", oc, oc) - radius * radius)
            hit = disc >= 0
            value = np.broadcast_to(background * _TINT, (d.shape[0], 3)).copy()
            t = -b[hit] - np.sqrt(disc[hit])
            P = origins[hit] + t[:, None] * d[hit]
            n = (P - centre) / radius
            r = d[hit] - 2 * np.einsum("ij,ij->i", d[hit], n)[:, None] * n
            seen = _environment(r, environment)[:, None] * _TINT
            seen[_emitter_hit(P, r, light, bulb_radius_mm, sun_radius_deg)] = bulb_radiance
            value[hit] = reflectance * seen
            h, w = v1 - v0 + 1, u1 - u0 + 1
            value = value.reshape(h * s, w * s, 3)
            if blur_px > 0:  # the lens's spread comes before the pixel's area: a spot's sub-pixel place survives
                value = cv2.GaussianBlur(value, (0, 0), float(blur_px) * s, borderType=cv2.BORDER_REPLICATE)
            value = value.reshape(h, s, w, s, 3).mean(axis=(1, 3))
            linear[v0:v1 + 1, u0:u1 + 1] = value
        if rng is not None:
            linear = sensor_noise(linear, rng=rng)
        linear = np.clip(linear, 0.0, 1.0)
        images.append(quantize(linear_to_srgb(linear), bits=8) if bits == 8 else quantize(linear, bits=16))
    return images

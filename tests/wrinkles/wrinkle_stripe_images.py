"""Analytic painted-stripe images for the tracking tests: known centre curves, anti-aliased edges, sensor noise."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

SKIN = np.array([0.62, 0.45, 0.38])
BLUE = np.array([0.10, 0.22, 0.62])
GREEN = np.array([0.12, 0.50, 0.18])


def centre_curve(u0: float, u1: float, v0: float, slope: float, bend: float, n: int = 2000) -> np.ndarray:
    """A parabolic centre line ``v = v0 + slope (u - u0) + bend (u - u0)^2`` for u in [u0, u1]: (n, 2) px."""
    u = np.linspace(u0, u1, n)
    return np.stack([u, v0 + slope * (u - u0) + bend * (u - u0) ** 2], axis=1)


def polyline_distance(points: np.ndarray, polyline: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance of each point to a polyline, and whether its nearest point is interior (not an end)."""
    A, B = polyline[:-1], polyline[1:]
    AB = B - A
    t = np.einsum("pkd,kd->pk", points[:, None] - A[None], AB) / np.einsum("kd,kd->k", AB, AB)
    t = np.clip(t, 0.0, 1.0)
    d = np.linalg.norm(points[:, None] - (A[None] + t[..., None] * AB[None]), axis=2)
    k = d.argmin(axis=1)
    tk = t[np.arange(len(points)), k]
    interior = ~(((k == 0) & (tk <= 0.0)) | ((k == len(A) - 1) & (tk >= 1.0)))
    return d[np.arange(len(points)), k], interior


def render_stripes(size: tuple[int, int], stripes: list[tuple[np.ndarray, float, np.ndarray]], *, seed: int = 0,
                   noise: float = 0.01, supersample: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Paint stripes (centre polyline, half-width px, RGB) on skin: the uint8 RGB image and the label mask.

    A pixel's colour mixes paint and skin by the fraction of its area within ``half_width`` of the centre
    line (``supersample^2`` points per pixel); the mask labels the pixels more than half covered
    (``1 + i`` for stripe ``i``).
    """
    W, H = size
    s = supersample
    offsets = (np.arange(s) + 0.5) / s - 0.5
    sub = np.stack([(np.arange(W * s) // s + offsets[np.arange(W * s) % s])[None].repeat(H * s, 0).ravel(),
                    (np.arange(H * s) // s + offsets[np.arange(H * s) % s])[:, None].repeat(W * s, 1).ravel()], axis=1)
    image = np.broadcast_to(SKIN, (H, W, 3)).copy()
    mask = np.zeros((H, W), dtype=np.uint8)
    for i, (curve, half_width, color) in enumerate(stripes):
        dist, _ = cKDTree(curve).query(sub, distance_upper_bound=half_width + 2)
        inside = (dist <= half_width).reshape(H, s, W, s).mean(axis=(1, 3))
        image = image * (1 - inside[..., None]) + color * inside[..., None]
        mask[inside > 0.5] = i + 1
    rng = np.random.default_rng(seed)
    image = image + rng.normal(0.0, noise, image.shape)
    return np.clip(np.round(image * 255), 0, 255).astype(np.uint8), mask


def two_stripes(shift: tuple[float, float] = (0.0, 0.0), seed: int = 0) -> tuple[np.ndarray, np.ndarray, list]:
    """Two blue stripes and a green one between them on a 320 x 240 image: (image, paint labels 0/1/2, centre curves)."""
    du, dv = shift
    curves = [centre_curve(40.0 + du, 260.0 + du, 60.0 + dv, 0.15, 0.0008),  # blue, upper
              centre_curve(60.0 + du, 250.0 + du, 150.0 + dv, -0.1, 0.001),  # blue, lower: same paint
              centre_curve(80.0 + du, 200.0 + du, 105.0 + dv, 0.0, 0.0005)]  # green, between
    image, mask = render_stripes((320, 240), [(curves[0], 6.0, BLUE), (curves[1], 6.0, BLUE), (curves[2], 5.0, GREEN)],
                                 seed=seed)
    labels = np.where(mask == 2, 1, np.where(mask == 3, 2, mask))  # paint labels: blue 1, green 2
    return image, labels, curves

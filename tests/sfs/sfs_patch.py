"""A patch of skin with known fine lines, lit and seen as the detail layer's model says: for round trips."""

import numpy as np

from facecap.cameras import Light
from facecap.mesh.vertex_normals import vertex_normals
from facecap.sfs.solve_heights import ShadedFrame, shade_frame
from facecap.sfs.vertex_gradient import vertex_gradient


def dome_patch(nx=80, ny=64, step=0.25, radius=80.0):
    x, y = np.meshgrid(np.arange(nx) * step, np.arange(ny) * step)
    V = np.c_[x.ravel(), y.ravel(), np.zeros(nx * ny)]
    V[:, 2] = -((V[:, 0] - nx * step / 2) ** 2 + (V[:, 1] - ny * step / 2) ** 2) / (2 * radius)
    idx = np.arange(nx * ny).reshape(ny, nx)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    return V, np.r_[np.c_[a, b, d], np.c_[a, d, c]].astype(np.int64)


def valley(distance, width, depth):
    return -depth * np.exp(-0.5 * (distance / width) ** 2)


def lined_frames(V, F, truth, *, albedo, k_s=0.05, alpha=12.0, ambient=0.05, noise=0.01, seed=0,
                 light=None, cameras=((150.0, 0.0, 700.0), (-150.0, 0.0, 700.0))):
    """ShadedFrames whose intensities are the model's rendering of ``truth`` (T, n) heights, with relative noise."""
    light = light or Light("point", position=[-300.0, 600.0, 900.0])
    n = V.shape[0]
    N = vertex_normals(V, F, np.arange(n))
    G = vertex_gradient(V, F)
    to_light, E = light.arriving(V)
    to_eye = np.stack([(np.asarray(c) - V) / np.linalg.norm(np.asarray(c) - V, axis=1, keepdims=True)
                       for c in cameras])
    rng = np.random.default_rng(seed)
    frames = []
    for h in truth:
        f = ShadedFrame(N, G, to_light[None], E[None], to_eye, np.zeros((len(cameras), n)), np.ones((len(cameras), n)))
        I, _, _ = shade_frame(f, h, albedo, k_s, alpha, ambient)
        frames.append(f._replace(intensity=I * (1 + noise * rng.normal(size=I.shape))))
    return frames

"""Small analytic meshes for the anatomy tests: a flat grid of right triangles and a box of tetrahedra."""

from __future__ import annotations

import numpy as np

from facecap.anatomy import tet_volumes


def grid_mesh(n: int = 21, size: float = 100.0) -> tuple[np.ndarray, np.ndarray]:
    u = np.linspace(0.0, size, n)
    X, Y = np.meshgrid(u, u, indexing="ij")
    V = np.stack([X.ravel(), Y.ravel(), np.zeros(n * n)], axis=1)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return V, F


def box_tets(nx: int, ny: int, nz: int, h: float, origin: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """A box of cubes, each split into 6 positively oriented tetrahedra (Kuhn / Freudenthal)."""
    g = np.stack(np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), np.arange(nz + 1), indexing="ij"), -1).reshape(-1, 3)
    X = g * h + np.asarray(origin)
    node = lambda i, j, k: (i * (ny + 1) + j) * (nz + 1) + k
    I, J, K = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    I, J, K = I.ravel(), J.ravel(), K.ravel()
    corners = {(a, b, c): node(I + a, J + b, K + c) for a in (0, 1) for b in (0, 1) for c in (0, 1)}
    tets = []
    for perm in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)):
        path = [(0, 0, 0)]
        for axis in perm:
            step = list(path[-1])
            step[axis] = 1
            path.append(tuple(step))
        tets.append(np.stack([corners[p] for p in path], axis=1))
    T = np.concatenate(tets).astype(np.int64)
    vol = tet_volumes(X, T)
    T[vol < 0] = T[vol < 0][:, [0, 2, 1, 3]]
    return X.astype(np.float64), T

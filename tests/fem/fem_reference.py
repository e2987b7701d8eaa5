"""Reference pieces for the finite element tests: a structured tetrahedral box, a linear FE stiffness."""

from __future__ import annotations

import numpy as np

# Kuhn's subdivision of the unit cube along its main diagonal 0-7 (corner c = x + 2 y + 4 z):
# six tetrahedra, all positively oriented, conforming between neighbouring cubes.
_KUHN = np.array([[0, 1, 3, 7], [0, 3, 2, 7], [0, 2, 6, 7], [0, 6, 4, 7], [0, 4, 5, 7], [0, 5, 1, 7]])


def box_tets(counts: tuple[int, int, int], size: tuple[float, float, float], *,
             mirrored: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Nodes (n, 3) mm and tetrahedra (m, 4) of a box ``[0, size]`` split into ``counts`` cubes.

    ``mirrored``: each cube's subdivision is reflected along every axis whose cube index is
    odd, which keeps the mesh conforming and makes it symmetric under reflections of the
    box (the plain one leans along its cubes' common diagonal).
    """
    nx, ny, nz = counts
    axes = [np.linspace(0.0, s, c + 1) for s, c in zip(size, counts)]
    X = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    node = np.arange(X.shape[0]).reshape(nx + 1, ny + 1, nz + 1)
    i, j, k = (a.reshape(-1) for a in np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"))
    flip = np.stack([i % 2, j % 2, k % 2], axis=1) if mirrored else np.zeros((i.size, 3), dtype=np.int64)
    # local corner c = (cx, cy, cz) of the reference cube sits at global offset cx ^ flip_x, ...
    corners = np.stack([node[i + ((c & 1) ^ flip[:, 0]), j + (((c >> 1) & 1) ^ flip[:, 1]),
                             k + (((c >> 2) & 1) ^ flip[:, 2])] for c in range(8)], axis=1)
    T = corners[:, _KUHN]  # (cubes, 6, 4)
    odd = flip.sum(axis=1) % 2 == 1  # an odd number of reflections turns the tetrahedra inside out
    T[odd] = T[odd][:, :, [1, 0, 2, 3]]
    return X, T.reshape(-1, 4).astype(np.int64)


def linear_elastic_stiffness(X: np.ndarray, T: np.ndarray, lame_lambda: float, shear_modulus: float) -> np.ndarray:
    """Dense small-strain stiffness, element by element (the textbook B^T D B V), as a reference.

    Written independently of facecap.fem: strain-displacement matrix B (6 x 12) in Voigt
    order (xx, yy, zz, yz, xz, xy) with engineering shear strains, isotropic D.
    """
    n = X.shape[0]
    lam, mu = lame_lambda, shear_modulus
    D = np.zeros((6, 6))
    D[:3, :3] = lam
    D[:3, :3] += 2 * mu * np.eye(3)
    D[3:, 3:] = mu * np.eye(3)
    K = np.zeros((3 * n, 3 * n))
    for tet in T:
        # Gradients of the linear hat functions: solve [1 x y z] coefficients.
        M = np.hstack([np.ones((4, 1)), X[tet]])
        grads = np.linalg.inv(M)[1:].T  # (4, 3): grad of hat function of each corner
        volume = abs(np.linalg.det(M)) / 6.0
        B = np.zeros((6, 12))
        for a in range(4):
            gx, gy, gz = grads[a]
            B[:, 3 * a:3 * a + 3] = [[gx, 0, 0], [0, gy, 0], [0, 0, gz], [0, gz, gy], [gz, 0, gx], [gy, gx, 0]]
        dofs = (3 * tet[:, None] + np.arange(3)).reshape(-1)
        K[np.ix_(dofs, dofs)] += volume * B.T @ D @ B
    return K

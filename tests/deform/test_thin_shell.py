import igl
import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from facecap.deform.thin_shell import ThinShellSolver, thin_shell_deform
from facecap.errors import CorrespondenceError, FacecapWarning, InputError
from facecap.mesh.laplacian import laplace_operators


def _curved_grid(n=24, size=100.0, offset=(0.0, 0.0, 0.0)):
    u, v = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    x, y = u.ravel() * size, v.ravel() * size
    V = np.stack([x, y, 0.004 * (x - size / 2) ** 2 + 0.002 * (y - size / 2) ** 2], axis=1)
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + n], 1), np.stack([a + 1, a + n + 1, a + n], 1)])
    return V + offset, F


def _markers(n_vertices, k, seed):
    return np.random.default_rng(seed).choice(n_vertices, k, replace=False)


def test_pure_bending_matches_libigl_biharmonic():
    V, F = _curved_grid()
    c = _markers(len(V), 25, 0)
    d = np.random.default_rng(1).normal(size=(25, 3))
    solver = ThinShellSolver(V, F, c, ks=0.0, kb=1.0)
    np.testing.assert_allclose(solver.displacements(d), igl.harmonic(V, F, c, d, 2), atol=1e-5)


def test_matches_a_direct_sparse_solve_of_eq4():
    V, F = _curved_grid(20)
    c = _markers(len(V), 15, 2)
    d = np.random.default_rng(3).normal(size=(15, 3))
    ks, kb = 1.0, 100.0
    # reference: the full system of eq. 4 with constraint rows replaced by identity rows
    ops = laplace_operators(V, F)
    A = (ks * ops.L + kb * ops.L @ sp.diags(1 / ops.mass) @ ops.L).tolil()
    rhs = np.zeros((len(V), 3))
    for i, vi in enumerate(c):
        A[vi, :] = 0
        A[vi, vi] = 1
        rhs[vi] = d[i]
    expected = spsolve(A.tocsc(), rhs)
    solver = ThinShellSolver(V, F, c, ks=ks, kb=kb, keep_factor=True)
    np.testing.assert_allclose(solver.displacements(d), expected, atol=2e-5)
    np.testing.assert_allclose(solver.solve_direct(d), expected, atol=1e-9)


def test_batched_frames_equal_single_frames():
    V, F = _curved_grid(16)
    c = _markers(len(V), 10, 4)
    D = np.random.default_rng(5).normal(size=(7, 10, 3))
    solver = ThinShellSolver(V, F, c)
    batch = solver.displacements(D)
    for t in range(7):
        np.testing.assert_allclose(batch[t], solver.displacements(D[t]), atol=1e-6)


def test_markers_are_interpolated_and_translation_reproduced():
    V, F = _curved_grid(16)
    c = _markers(len(V), 12, 6)
    d = np.random.default_rng(7).normal(size=(12, 3))
    out = thin_shell_deform(V, F, c, d)
    np.testing.assert_allclose(out[c], V[c] + d, atol=1e-5)
    moved = thin_shell_deform(V, F, c, np.tile([3.0, -2.0, 1.0], (12, 1)))
    np.testing.assert_allclose(moved, V + [3.0, -2.0, 1.0], atol=1e-4)


def test_units_do_not_change_the_shape_of_the_deformation():
    # the same scan in cm (scaled by 0.1) with kb scaled by 0.01 (kb is a squared length)
    V, F = _curved_grid(16)
    c = _markers(len(V), 12, 8)
    d = np.random.default_rng(9).normal(size=(12, 3))
    mm = ThinShellSolver(V, F, c, ks=1.0, kb=100.0).displacements(d)
    cm = ThinShellSolver(V * 0.1, F, c, ks=1.0, kb=1.0).displacements(d * 0.1)
    np.testing.assert_allclose(cm * 10, mm, atol=1e-4)


def test_uv_seam_duplicates_are_welded():
    V, F = _curved_grid(12)
    c = _markers(len(V), 8, 10)
    c = c[(c % 12) != 6]  # keep markers off the seam column
    d = np.random.default_rng(11).normal(size=(len(c), 3))
    whole = ThinShellSolver(V, F, c).displacements(d)
    # split the mesh along the column x == 6 by duplicating those vertices for faces on one side
    seam = np.flatnonzero(np.arange(len(V)) % 12 == 6)
    copy = {int(s): len(V) + i for i, s in enumerate(seam)}
    V2 = np.vstack([V, V[seam]])
    right = np.all((F % 12) >= 6, axis=1)
    F2 = F.copy()
    F2[right] = np.vectorize(lambda i: copy.get(int(i), int(i)))(F[right])
    split = ThinShellSolver(V2, F2, c).displacements(d)
    np.testing.assert_allclose(split[: len(V)], whole, atol=1e-5)
    np.testing.assert_allclose(split[len(V):], whole[seam], atol=1e-5)


@pytest.mark.parametrize("policy", ["carry", "rigid"])
def test_pieces_without_markers_never_make_the_system_singular(policy):
    V, F = _curved_grid(12)
    eye_V, eye_F = _curved_grid(4, size=10.0, offset=(45.0, 45.0, 30.0))
    V2 = np.vstack([V, eye_V])
    F2 = np.vstack([F, eye_F + len(V)])
    c = _markers(len(V), 10, 12)
    d = np.tile([0.0, 0.0, 2.0], (10, 1))
    with pytest.warns(FacecapWarning, match="carry no marker"):
        solver = ThinShellSolver(V2, F2, c, unmarked_pieces=policy)
    out = solver.displacements(d)
    eye = out[len(V):]
    expected = 2.0 if policy == "carry" else 0.0
    np.testing.assert_allclose(eye[:, 2], expected, atol=1e-4)  # a rigid move of the whole skin carries the eye
    assert solver.pieces.unmarked_pieces and solver.pieces.n_pieces == 2
    # the reference per-frame sparse solve follows the same rule for the unmarked piece
    with pytest.warns(FacecapWarning, match="carry no marker"):
        kept = ThinShellSolver(V2, F2, c, unmarked_pieces=policy, keep_factor=True)
    d_random = np.random.default_rng(13).normal(size=(10, 3))
    np.testing.assert_allclose(kept.solve_direct(d_random), kept.displacements(d_random), atol=1e-5)


def test_degenerate_faces_are_left_out():
    V, F = _curved_grid(12)
    c = _markers(len(V), 8, 13)
    d = np.random.default_rng(14).normal(size=(8, 3))
    clean = ThinShellSolver(V, F, c).displacements(d)
    V_bad = np.vstack([V, (V[0] + V[1]) / 2])  # a midpoint: the triangle (0, 1, mid) has zero area
    F_bad = np.vstack([F, [[0, 0, 1]], [[0, 1, len(V)]]])  # repeated index, and collinear
    bad = ThinShellSolver(V_bad, F_bad, c)
    assert bad.pieces.degenerate_faces == 2
    np.testing.assert_allclose(bad.displacements(d)[: len(V)], clean, atol=1e-6)


def test_bad_constraints_are_clear_errors():
    V, F = _curved_grid(8)
    with pytest.raises(CorrespondenceError, match="out of range"):
        ThinShellSolver(V, F, np.array([0, 1000]))
    with pytest.raises(CorrespondenceError, match="same scan vertex"):
        ThinShellSolver(V, F, np.array([3, 3, 5]))
    with pytest.raises(InputError):
        ThinShellSolver(V, F, np.array([1, 2]), ks=0, kb=0)
    with pytest.raises(InputError):
        ThinShellSolver(V, F, np.array([1, 2])).displacements(np.zeros((3, 3)))

import numpy as np
import pytest

from facecap.deform.triharmonic_warp import TriharmonicWarp
from facecap.errors import MarkerError


def _reference_warp(sources, targets, queries):
    """Slow, obvious reference: the dense r^3 + quadratic system of Carr et al. 2001."""
    k = len(sources)
    phi = np.linalg.norm(sources[:, None] - sources[None], axis=2) ** 3

    def poly(X):
        x, y, z = X.T
        return np.stack([np.ones_like(x), x, y, z, x * x, y * y, z * z, x * y, x * z, y * z], axis=1)

    P = poly(sources)
    A = np.block([[phi, P], [P.T, np.zeros((10, 10))]])
    rhs = np.vstack([targets, np.zeros((10, 3))])
    coef = np.linalg.solve(A, rhs)
    phi_q = np.linalg.norm(queries[:, None] - sources[None], axis=2) ** 3
    return phi_q @ coef[:k] + poly(queries) @ coef[k:]


def _markers(rng, k=40):
    return rng.normal(size=(k, 3)) * [60.0, 80.0, 40.0]


def test_interpolates_and_matches_dense_reference():
    rng = np.random.default_rng(1)
    m = _markers(rng)
    f = m + 3.0 * np.sin(m / 30.0)  # non-polynomial: the RBF part matters
    warp = TriharmonicWarp(m, f)
    np.testing.assert_allclose(warp(m), f, atol=1e-8)
    q = _markers(rng, 25)
    np.testing.assert_allclose(warp(q), _reference_warp(m, f, q), atol=1e-6)


def test_reproduces_quadratic_maps_exactly():
    rng = np.random.default_rng(2)
    m = _markers(rng)
    A = rng.normal(size=(3, 3))
    quad = lambda X: X @ A.T + [4.0, -2.0, 7.0] + 1e-3 * X[:, [0]] * X[:, [1]]  # noqa: E731
    warp = TriharmonicWarp(m, quad(m))
    q = _markers(rng, 30)
    np.testing.assert_allclose(warp(q), quad(q), atol=1e-8)


def test_rigid_motion_is_reproduced_with_few_markers():
    rng = np.random.default_rng(3)
    m = _markers(rng, 6)  # < 10: affine polynomial
    from scipy.spatial.transform import Rotation

    R = Rotation.from_rotvec([0.1, -0.3, 0.2]).as_matrix()
    warp = TriharmonicWarp(m, m @ R.T + [1.0, 2.0, 3.0])
    assert warp.degree == 1
    q = _markers(rng, 10)
    np.testing.assert_allclose(warp(q), q @ R.T + [1.0, 2.0, 3.0], atol=1e-8)


def test_nan_points_stay_nan():
    rng = np.random.default_rng(4)
    m = _markers(rng, 20)
    warp = TriharmonicWarp(m, m + 1.0)
    q = _markers(rng, 3)
    q[1] = np.nan
    out = warp(q)
    assert np.isnan(out[1]).all() and np.isfinite(out[[0, 2]]).all()


def test_leave_one_out_flags_a_mispicked_vertex():
    # markers spread over a face-like curved patch, as on a real face
    u, v = np.meshgrid(np.linspace(-60, 60, 8), np.linspace(-80, 80, 9))
    m = np.stack([u.ravel(), v.ravel(), 0.004 * (u.ravel() ** 2 + v.ravel() ** 2)], axis=1)
    f = m + 2.0 * np.sin(m / 40.0)
    bad = 30  # an interior marker
    f[bad] += [5.0, -4.0, 3.0]  # its vertex picked 7 mm off
    loo = TriharmonicWarp(m, f).leave_one_out_residuals()
    assert int(np.argmax(loo)) == bad
    assert loo[bad] > 3 * np.median(loo)


def test_too_few_or_coplanar_markers_are_rejected():
    rng = np.random.default_rng(6)
    m = _markers(rng, 3)
    with pytest.raises(MarkerError, match="at least 4"):
        TriharmonicWarp(m, m)
    flat = _markers(rng, 12)
    flat[:, 2] = 0.0
    with pytest.raises(MarkerError, match="coplanar"):
        TriharmonicWarp(flat, flat)


def test_markers_on_a_quadric_fall_back_to_affine_and_stay_exact():
    # a sheet of markers exactly on a paraboloid leaves the quadratic term undetermined
    rng = np.random.default_rng(7)
    xy = rng.uniform(-60, 60, size=(40, 2))
    m = np.column_stack([xy, -0.006 * xy[:, 0] ** 2 - 0.003 * xy[:, 1] ** 2])
    from scipy.spatial.transform import Rotation

    R = Rotation.from_rotvec([0.2, -0.4, 0.1]).as_matrix()
    warp = TriharmonicWarp(m @ R.T + [100.0, 1400.0, -30.0], m)
    assert warp.degree == 1
    off_surface = m + rng.normal(scale=5.0, size=m.shape)
    np.testing.assert_allclose(warp(off_surface @ R.T + [100.0, 1400.0, -30.0]), off_surface, atol=1e-6)

"""The sphere's penalty contact, and the quasistatic solver's external-energy hook it plugs into."""

import numpy as np
import pytest
import scipy.sparse as sp
from fem_reference import box_tets

from facecap.errors import InputError
from facecap.fem import ExternalResponse, FleshModel, QuasistaticSolver, SphereContact


def _embedded_points(rng, n_nodes, n_points):
    """Random points as weights over 4 random nodes each (rows summing to 1), plus two plain nodes."""
    rows, cols, vals = [], [], []
    for i in range(n_points):
        nodes = rng.choice(n_nodes, 4, replace=False)
        w = rng.uniform(0.1, 1.0, 4)
        rows += [i] * 4
        cols += nodes.tolist()
        vals += (w / w.sum()).tolist()
    rows += [n_points, n_points + 1]
    cols += [0, 1]
    vals += [1.0, 1.0]
    return sp.csr_matrix((vals, (rows, cols)), shape=(n_points + 2, n_nodes))


def test_energy_forces_and_stiffness_against_finite_differences_and_the_exact_hessian():
    rng = np.random.default_rng(3)
    n = 12
    x = rng.normal(0.0, 3.0, (n, 3))
    W = _embedded_points(rng, n, 8)
    points = W @ x
    centre, radius = points.mean(axis=0), np.percentile(np.linalg.norm(points - points.mean(axis=0), axis=1), 60)
    contact = SphereContact(W, centre, radius, stiffness=40.0)
    inside = contact.penetration(x) > 0
    assert 0 < inside.sum() < W.shape[0]  # some points in, some out: both branches
    response = contact.evaluate(x)
    # forces = -dE/dx by central differences
    h = 1e-6
    fd = np.zeros((n, 3))
    for i in range(n):
        for c in range(3):
            e = np.zeros((n, 3))
            e[i, c] = h
            fd[i, c] = -(contact.evaluate(x + e, stiffness=False).energy
                         - contact.evaluate(x - e, stiffness=False).energy) / (2 * h)
    np.testing.assert_allclose(response.forces, fd, atol=1e-6 * np.abs(fd).max())
    # the exact Hessian (central differences of the forces) is the stiffness plus the negative
    # tangential term -k phi/d (I - n n^T) of each inside point, computed here point by point
    H_fd = np.zeros((3 * n, 3 * n))
    for j in range(3 * n):
        e = np.zeros(3 * n)
        e[j] = h
        H_fd[:, j] = -(contact.evaluate(x + e.reshape(n, 3), stiffness=False).forces
                       - contact.evaluate(x - e.reshape(n, 3), stiffness=False).forces).reshape(-1) / (2 * h)
    tangential = np.zeros((3 * n, 3 * n))
    Wd = np.kron(W.toarray(), np.eye(3))
    for p in np.flatnonzero(inside):
        offset = points[p] - centre
        d = np.linalg.norm(offset)
        normal = offset / d
        block = -40.0 * (radius - d) / d * (np.eye(3) - np.outer(normal, normal))
        tangential += Wd[3 * p:3 * p + 3].T @ block @ Wd[3 * p:3 * p + 3]
    K = response.stiffness.toarray()
    np.testing.assert_allclose(K + tangential, H_fd, atol=1e-5 * np.abs(H_fd).max())
    np.testing.assert_allclose(K, K.T, atol=1e-12 * np.abs(K).max())
    assert np.linalg.eigvalsh(K).min() > -1e-9 * np.abs(K).max()
    # the total force is the points' forces, each along its outward normal
    np.testing.assert_allclose(response.forces.sum(axis=0), contact.point_forces(x).sum(axis=0), rtol=1e-12)
    outside = SphereContact(W, centre + 1e3, radius, stiffness=40.0).evaluate(x)
    assert outside.energy == 0.0 and not outside.forces.any() and outside.stiffness.nnz == 0


def _slab():
    X, T = box_tets((4, 4, 2), (24.0, 24.0, 8.0), mirrored=True)
    bottom = np.flatnonzero(X[:, 2] == 0.0)
    return FleshModel(X, T, None, None, bottom), X, bottom


def test_a_sphere_pressed_into_a_slab_balances_the_bone_reaction_and_stays_out():
    model, X, bottom = _slab()
    top = np.flatnonzero(X[:, 2] == 8.0)
    W = sp.csr_matrix((np.ones(top.size), (np.arange(top.size), top)), shape=(top.size, X.shape[0]))
    centre, radius = np.array([12.0, 12.0, 8.0 + 10.0 - 1.5]), 10.0  # 1.5 mm into the top face's centre
    depths, forces = [], []
    for k in [1e4, 1e5, 1e6]:
        contact = SphereContact(W, centre, radius, stiffness=k)
        solver = QuasistaticSolver(model, max_iterations=60)
        result = solver.solve(np.zeros(0), X[bottom], external=contact)
        assert result.converged and result.inverted_tets == 0
        x = result.positions
        f_contact = contact.evaluate(x, stiffness=False).forces
        f_elastic = model.forces(x, np.zeros(0))
        # equilibrium: what the sphere pushes, the bone (the Dirichlet nodes) holds
        reaction = -(f_elastic[bottom] + f_contact[bottom]).sum(axis=0)
        total = f_contact.sum(axis=0)
        np.testing.assert_allclose(reaction, -total, atol=1e-6 * np.abs(total).max() + top.size * solver.force_tolerance_mn)
        assert total[2] < 0 and abs(total[0]) < 1e-6 * -total[2] and abs(total[1]) < 1e-6 * -total[2]  # straight down
        depths.append(contact.penetration(x).max())
        forces.append(-total[2])
        # the centre node is pushed down most of the way
        middle = top[np.argmin(np.linalg.norm(X[top, :2] - 12.0, axis=1))]
        assert X[middle, 2] - x[middle, 2] > 1.5 - depths[-1] - 1e-9
    # penetration ~ force per point / k: tenfold stiffer, about tenfold shallower, force converging
    assert depths[0] > depths[1] > depths[2] > 0 and depths[1] / depths[2] > 5
    assert abs(forces[2] - forces[1]) < 0.2 * abs(forces[1] - forces[0])


class _Spring:
    """``k/2 |x_i - x_j|^2``: a zero-length spring between two nodes (exact, quadratic)."""

    def __init__(self, i, j, n, k):
        self.i, self.j, self.n, self.k = i, j, n, k

    def evaluate(self, x, *, stiffness=True):
        d = x[self.i] - x[self.j]
        f = np.zeros((self.n, 3))
        f[self.i], f[self.j] = -self.k * d, self.k * d
        K = None
        if stiffness:
            K = sp.lil_matrix((3 * self.n, 3 * self.n))
            for a, b, s in ((self.i, self.i, 1), (self.j, self.j, 1), (self.i, self.j, -1), (self.j, self.i, -1)):
                for c in range(3):
                    K[3 * a + c, 3 * b + c] = s * self.k
        return ExternalResponse(0.5 * self.k * float(d @ d), f, None if K is None else K.tocsr())


def test_the_external_hook_enters_the_equilibrium_and_its_jacobians():
    model, X, bottom = _slab()
    corner = int(np.flatnonzero((X[:, 2] == 8.0) & (X[:, 0] == 24.0) & (X[:, 1] == 24.0))[0])
    anchor = int(bottom[np.argmin(np.linalg.norm(X[bottom] - [24.0, 24.0, 0.0], axis=1))])
    spring = _Spring(corner, anchor, X.shape[0], 50.0)
    solver = QuasistaticSolver(model, tolerance=1e-11)
    base_bones = X[bottom] + [1.0, 0.0, 0.0]  # the base sheared sideways: the spring pulls the corner back
    plain = solver.solve(np.zeros(0), base_bones).positions
    result = solver.solve(np.zeros(0), base_bones, external=spring)
    x = result.positions
    assert result.converged
    # the free nodes are in equilibrium with the spring's force, and the spring changed the face
    residual = (model.forces(x, np.zeros(0)) + spring.evaluate(x).forces)[model.free_nodes]
    assert np.abs(residual).max() < 1e-9 and np.abs(x - plain).max() > 0.1
    assert result.energy == pytest.approx(model.energy(x, np.zeros(0)) + spring.evaluate(x).energy, rel=1e-12)
    # eq. 6 with the external term: the boundary Jacobian against re-solved equilibria (the spring couples a
    # free node to a moved one, so its off-diagonal stiffness enters the right-hand side)
    velocity = np.zeros((bottom.size, 3))
    velocity[:, 2] = X[bottom, 0] / 24.0
    jacobian = solver.boundary_jacobian(velocity)
    h = 1e-4
    up = QuasistaticSolver(model, tolerance=1e-11).solve(np.zeros(0), base_bones + h * velocity, x0=x,
                                                        external=spring).positions
    down = QuasistaticSolver(model, tolerance=1e-11).solve(np.zeros(0), base_bones - h * velocity, x0=x,
                                                          external=spring).positions
    fd = (up - down) / (2 * h)
    np.testing.assert_allclose(jacobian, fd, atol=1e-5 * np.abs(fd).max())
    # the next solve without it is the plain one again, to the last bit
    again = solver.solve(np.zeros(0), base_bones).positions
    assert np.array_equal(again, plain)


def test_bad_input():
    W = sp.identity(3, format="csr")
    with pytest.raises(InputError, match="radius"):
        SphereContact(W, [0, 0, 0], 0.0, stiffness=1.0)
    with pytest.raises(InputError, match="stiffness"):
        SphereContact(W, [0, 0, 0], 1.0, stiffness=-1.0)
    with pytest.raises(InputError, match="centre"):
        SphereContact(W, [0, 0], 1.0, stiffness=1.0)
    with pytest.raises(InputError, match="x: expected"):
        SphereContact(W, [0, 0, 0], 1.0, stiffness=1.0).evaluate(np.zeros((4, 3)))

import igl
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facecap.errors import InputError
from facecap.registration.refine_registration import refine_registration
from facecap.structures import Mesh

SIZE = 80.0  # mm, the side of the synthetic skin patch


def _grid(n, size):
    u = np.linspace(-size / 2, size / 2, n)
    x, y = np.meshgrid(u, u)
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + n], 1), np.stack([a + 1, a + n + 1, a + n], 1)])
    return np.stack([x.ravel(), y.ravel()], 1), F


class SkinCase:
    """K rigidly moved copies of a bumpy patch (the scans) and registrations slid along them.

    The patch is the height field ``z = h(x, y)`` of 40 Gaussian bumps; scan ``k`` is it
    moved by a known rigid motion, so the material point of any surface point is its
    (x, y) after undoing that motion. Registration ``k`` puts template vertex ``j`` at
    material point ``P_j + slide_k(P_j)``, a smooth tangential misregistration.
    """

    def __init__(self, K=4, n=41, slide_mm=1.5, seed=0):
        rng = np.random.default_rng(seed)
        self.centres = rng.uniform(-0.45 * SIZE, 0.45 * SIZE, (40, 2))
        self.amp = rng.uniform(0.8, 1.6, 40) * rng.choice([-1, 1], 40)
        self.sigma = rng.uniform(2.5, 4.0, 40)
        self.P, self.F = _grid(n, SIZE)
        Ps, Fs = _grid(121, SIZE + 4)
        self.motions = [(Rotation.from_rotvec([0.03 * k, -0.05 * k, 0.02 * k]).as_matrix(),
                         np.array([1.0, -2.0, 0.5]) * k) for k in range(K)]
        self.scans, registered = [], []
        for k, (R, t) in enumerate(self.motions):
            S = self._embed(Ps) @ R.T + t
            self.scans.append(Mesh(S, Fs))
            phase = rng.uniform(0, 2 * np.pi, 4)
            x, y = self.P[:, 0], self.P[:, 1]
            slide = slide_mm * np.stack([np.sin(y / 15 + phase[0]) * np.cos(x / 20 + phase[1]),
                                         np.cos(x / 17 + phase[2]) * np.sin(y / 22 + phase[3])], 1)
            X = self._embed(self.P + slide) @ R.T + t
            registered.append(igl.point_mesh_squared_distance(X, S, Fs)[2])  # exactly on the scan
        self.registered = np.stack(registered)
        self.interior = np.all(np.abs(self.P) < 30, axis=1)
        near = np.linalg.norm(self.P[:, None] - self.centres[None], axis=2) < 1.5 * self.sigma[None]
        self.detailed = self.interior & near.any(axis=1)

    def _embed(self, Q):
        d2 = ((Q[:, None, :] - self.centres[None]) ** 2).sum(2)
        return np.c_[Q, (self.amp[None] * np.exp(-d2 / (2 * self.sigma[None] ** 2))).sum(1)]

    def material(self, D):
        """(K, n, 2) material coordinates of registered vertices."""
        return np.stack([((D[k] - t) @ R)[:, :2] for k, (R, t) in enumerate(self.motions)])

    def correspondence_error(self, D, mask):
        """Mean distance (mm) between the material points of vertex j in two meshes, over pairs and mask."""
        M = self.material(D)
        K = M.shape[0]
        return float(np.mean([np.linalg.norm(M[a, mask] - M[b, mask], axis=1).mean()
                              for a in range(K) for b in range(a + 1, K)]))


def _flipped(V0, V1, F):
    n0 = np.cross(V0[F[:, 1]] - V0[F[:, 0]], V0[F[:, 2]] - V0[F[:, 0]])
    n1 = np.cross(V1[F[:, 1]] - V1[F[:, 0]], V1[F[:, 2]] - V1[F[:, 0]])
    return int(np.sum(np.einsum("ij,ij->i", n0, n1) < 0))


@pytest.fixture(scope="module")
def misaligned():
    case = SkinCase()
    return case, refine_registration(case.registered, case.F, case.scans, backend="scipy")


def test_reduces_the_correspondence_error_against_the_truth(misaligned):
    case, result = misaligned
    before_detail = case.correspondence_error(case.registered, case.detailed)
    after_detail = case.correspondence_error(result.vertices, case.detailed)
    before_all = case.correspondence_error(case.registered, case.interior)
    after_all = case.correspondence_error(result.vertices, case.interior)
    assert before_detail > 1.2
    assert after_detail < 0.3 * before_detail  # measured: 1.35 -> 0.32 mm where there is detail
    assert after_all < 0.5 * before_all  # and 1.35 -> 0.45 mm over the whole interior
    assert np.all(result.misalignment_after < 0.8 * result.misalignment_before)


def test_refined_vertices_stay_on_their_scans_without_flips(misaligned):
    case, result = misaligned
    assert result.vertices.shape == case.registered.shape
    for k, scan in enumerate(case.scans):
        d = np.sqrt(igl.point_mesh_squared_distance(result.vertices[k], scan.vertices, scan.faces)[0])
        assert d.max() < 0.05
        np.testing.assert_allclose(result.distance_to_scan_mm[k], d, atol=1e-9)
        assert _flipped(case.registered[k], result.vertices[k], case.F) == 0


def test_neighbours_regions_and_flags(misaligned):
    case, result = misaligned
    K = case.registered.shape[0]
    assert result.neighbours.shape == (K, 8, 3)
    for i in range(K):
        assert i not in result.neighbours[i]  # a mesh is never its own neighbour
    counts = np.bincount(result.region_labels, minlength=8)
    assert counts.size == 8 and counts.min() > 0.8 * counts.mean()  # 2 x 4 grid at the quantiles
    for i in range(K):  # the M others with the smallest mean vertex distance over each region
        for r in range(8):
            vr = result.region_labels == r
            dist = [np.linalg.norm(case.registered[k, vr] - case.registered[i, vr], axis=1).mean() if k != i else np.inf
                    for k in range(K)]
            assert set(result.neighbours[i, r]) == set(np.argsort(dist)[:3])
    np.testing.assert_array_equal(result.flagged, result.misalignment_after > 2 * np.median(result.misalignment_after))


@pytest.mark.parametrize("options", [dict(flow="farneback"), dict(average="images", confidence_floor=None)])
def test_other_flows_and_averaging_also_align(options):
    case = SkinCase(K=3, seed=1)
    result = refine_registration(case.registered, case.F, case.scans, iterations=2, backend="scipy", **options)
    before = case.correspondence_error(case.registered, case.detailed)
    assert case.correspondence_error(result.vertices, case.detailed) < 0.5 * before


def test_correct_registrations_stay_put():
    case = SkinCase(K=3, slide_mm=0.0)
    # between the misalignment of aligned meshes (~1e-11 /mm) and of meshes slid 1.5 mm (~2e-3 /mm)
    result = refine_registration(case.registered, case.F, case.scans, iterations=2, backend="scipy",
                                 error_threshold=1e-4)
    assert np.abs(result.vertices - case.registered).max() < 0.05
    assert case.correspondence_error(result.vertices, case.interior) < 0.02
    assert result.misalignment_after.max() < 1e-6
    assert not result.flagged.any()


def test_user_correspondence_pins_a_vertex():
    case = SkinCase(K=2, n=31)
    j = int(np.argmin(np.linalg.norm(case.P - [5.0, -3.0], axis=1)))
    R, t = case.motions[1]
    target = case._embed(case.P[j][None] + [1.0, 0.5])[0] @ R.T + t  # a material point 1.1 mm away
    result = refine_registration(case.registered, case.F, case.scans, iterations=1, backend="scipy",
                                 user_correspondences=[(0, j, 1, target)], constraint_weight=1e4)
    assert np.linalg.norm(result.vertices[1, j] - target) < 0.1
    assert np.linalg.norm(result.vertices[0, j] - case.registered[0, j]) < 0.1


def test_seam_duplicates_stay_together_and_labels_are_kept():
    case = SkinCase(K=2, n=21)
    n = case.P.shape[0]
    # split the mesh along x = 0: the right half's seam vertices get copies
    seam = np.flatnonzero(np.abs(case.P[:, 0]) < 1e-9)
    copy_of = {int(v): n + i for i, v in enumerate(seam)}
    F = case.F.copy()
    right = case.P[F].mean(axis=1)[:, 0] > 0
    F[right] = np.vectorize(lambda v: copy_of.get(int(v), int(v)))(F[right])
    D = np.concatenate([case.registered, case.registered[:, seam]], axis=1)
    labels = (np.r_[case.P[:, 0], case.P[seam, 0]] > 0).astype(np.int64) * 7  # two regions, labelled 0 and 7
    result = refine_registration(D, F, case.scans, region_labels=labels, iterations=1, backend="scipy")
    assert result.vertices.shape == (2, n + seam.size, 3)
    np.testing.assert_array_equal(result.vertices[:, seam], result.vertices[:, n:])
    np.testing.assert_array_equal(result.region_labels, labels // 7)
    assert result.neighbours.shape == (2, 2, 1)


@pytest.fixture(scope="module")
def tiny_case():
    return SkinCase(K=2, n=11)


@pytest.mark.parametrize(
    "change",
    [
        dict(registered="one mesh"),
        dict(scans="one fewer"),
        dict(region_labels=np.zeros(5, dtype=np.int64)),
        dict(flow="lucas-kanade"),
        dict(average="median"),
        dict(error_threshold=-0.1),
        dict(neighbours=0),
        dict(alpha=-1.0),
        dict(confidence_floor=2.0),
        dict(user_correspondences=[(0, 10**6, 1, np.zeros(3))]),
        dict(user_correspondences=[(0, 0, 5, np.zeros(3))]),
        dict(user_correspondences=[(0, 0, 1, np.full(3, np.nan))]),
    ],
)
def test_rejects_bad_input(change, tiny_case):
    case = tiny_case
    args = dict(registered=case.registered, scans=case.scans)
    if change.get("registered") == "one mesh":
        args["registered"] = case.registered[:1]
        args["scans"] = case.scans[:1]
        change = {}
    elif change.get("scans") == "one fewer":
        args["scans"] = case.scans[:1]
        change = {}
    with pytest.raises(InputError):
        refine_registration(args["registered"], case.F, args["scans"], backend="scipy", **change)

import igl
import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, dijkstra

from facecap.errors import InputError
from facecap.registration.register_scans import DEFAULT_REST_WEIGHT
from facecap.registration.register_template_to_scan import (MAX_NORMAL_ANGLE_DEG, register_template_to_scan,
                                                              register_template_to_scans)
from facecap.synth import generate_performance
from facecap.synth.scan_expression import scan_expression


@pytest.fixture(scope="module")
def setup():
    case = generate_performance(n_frames=90, seed=2, n_markers=70)
    frame = int(np.argmax(np.abs(case.truth_vertices - case.truth_vertices[0]).mean(axis=(1, 2))))
    truth = case.truth_vertices[frame].astype(np.float64)
    scanned = scan_expression(truth, case.scan.faces, seed=1, target_vertices=15000, scanner_from_face=np.eye(4))
    mv = case.marker_vertices
    return case, truth, scanned.mesh, np.stack([mv] * 3, 1), np.tile([1.0, 0.0, 0.0], (mv.size, 1))


def test_template_lands_on_the_scan_and_nearer_the_truth(setup):
    case, truth, scan, idx, w = setup
    result = register_template_to_scan(case.scan, idx, w, scan, truth[idx[:, 0]])
    assert result.mean_distance_mm < 0.2  # the bar: registration residual to the scan surface
    assert result.matched.mean() > 0.4  # the scanner sees the front of the face, not the ears and neck
    assert result.marker_residual_mm.max() < 0.05
    before = np.linalg.norm(case.scan.vertices - truth, axis=1).mean()
    after = np.linalg.norm(result.vertices - truth, axis=1).mean()
    assert after < 0.4 * before
    assert not result.flipped_scan_normals


def test_flipped_scan_normals_are_detected_and_handled(setup):
    case, truth, scan, idx, w = setup
    flipped = scan.with_vertices(scan.vertices)
    object.__setattr__(flipped, "faces", np.ascontiguousarray(scan.faces[:, ::-1]))
    result = register_template_to_scan(case.scan, idx, w, flipped, truth[idx[:, 0]])
    assert result.flipped_scan_normals
    assert result.mean_distance_mm < 0.2



def test_several_scans_at_once_give_what_each_gives_alone(setup):
    # what the scans share (the template's system, the markers-only factor, the rounds' analysis) is built
    # once; each result must be the one-scan registration's, whichever markers each scan sees
    case, truth, scan, idx, w = setup
    flipped = scan.with_vertices(scan.vertices)
    object.__setattr__(flipped, "faces", np.ascontiguousarray(scan.faces[:, ::-1]))
    targets = truth[idx[:, 0]]
    fewer = targets.copy()
    fewer[:5] = np.nan  # another set of markers seen: its own marker system
    scans, markers = [scan, flipped, scan], [targets, targets, fewer]
    together = register_template_to_scans(case.scan, idx, w, scans, markers)
    for one, s, m in zip(together, scans, markers):
        alone = register_template_to_scan(case.scan, idx, w, s, m)
        np.testing.assert_allclose(one.vertices, alone.vertices, atol=1e-7)
        np.testing.assert_array_equal(one.matched, alone.matched)
        assert one.flipped_scan_normals == alone.flipped_scan_normals
    assert [r.flipped_scan_normals for r in together] == [False, True, False]
    assert np.isnan(together[2].marker_residual_mm[:5]).all() and np.isfinite(together[2].marker_residual_mm[5:]).all()


def test_too_few_visible_markers(setup):
    case, truth, scan, idx, w = setup
    targets = np.full((idx.shape[0], 3), np.nan)
    targets[:2] = truth[idx[:2, 0]]
    with pytest.raises(InputError, match="at least 3"):
        register_template_to_scan(case.scan, idx, w, scan, targets)


def test_rest_weight_keeps_what_the_scan_does_not_see_near_the_truth(setup):
    # Without it the Laplacian term extrapolates the face's displacement linearly into the neck,
    # ears and the inside of the mouth, which the scanner never sees; there the truth moves less
    # than that extrapolation (measured: unseen error 0.64 mm free, 0.41 held, 0.57 at 1e-3).
    case, truth, scan, idx, w = setup
    free = register_template_to_scan(case.scan, idx, w, scan, truth[idx[:, 0]])
    held = register_template_to_scan(case.scan, idx, w, scan, truth[idx[:, 0]], rest_weight=DEFAULT_REST_WEIGHT)
    unseen = ~free.matched
    error_free = np.linalg.norm(free.vertices - truth, axis=1)
    error_held = np.linalg.norm(held.vertices - truth, axis=1)
    assert error_held[unseen].mean() < 0.8 * error_free[unseen].mean()
    assert error_held[~unseen].mean() <= error_free[~unseen].mean()  # and no worse where it sees
    assert held.mean_distance_mm <= free.mean_distance_mm + 0.005  # still on the scan
    with pytest.raises(InputError, match="non-negative"):
        register_template_to_scan(case.scan, idx, w, scan, truth[idx[:, 0]], rest_weight=-1.0)


def _inner_lips(V: np.ndarray, F: np.ndarray, rings: int) -> np.ndarray:
    """Vertices within ``rings`` edges of the mouth opening (the front boundary loop lowest on the face)."""
    edges = igl.boundary_facets(F)[0]
    graph = sp.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(len(V),) * 2)
    _, loop = connected_components(graph, directed=False)
    on_loop = np.unique(edges)
    loops = [on_loop[loop[on_loop] == k] for k in np.unique(loop[on_loop])]
    front = [vs for vs in loops if V[vs, 2].mean() > 50.0]  # the neck's opening is at the back
    mouth = min(front, key=lambda vs: V[vs, 1].mean())  # below the eyes
    hops = dijkstra(igl.adjacency_matrix(F), indices=mouth, min_only=True, unweighted=True)
    return np.flatnonzero(hops <= rings)


def test_inner_lips_are_not_pulled_onto_the_outer_lips(setup):
    """The inner lips face into the mouth and no scan sees them. At the loose limit of 60 degrees
    the closest points pull the first rings of them onto the lips' visible side."""
    case = setup[0]
    motion = np.abs(case.truth_vertices - case.truth_vertices[0]).mean(axis=(1, 2))
    frame = int(np.argsort(motion)[motion.size // 2])  # an everyday expression, mouth nearly closed
    truth = case.truth_vertices[frame].astype(np.float64)
    scan = scan_expression(truth, case.scan.faces, seed=1, target_vertices=15000, scanner_from_face=np.eye(4)).mesh
    idx, w = setup[3], setup[4]
    lips = _inner_lips(case.scan.vertices, case.scan.faces, rings=3)
    assert 200 < lips.size < 400

    def lip_error(angle: float) -> float:
        result = register_template_to_scan(case.scan, idx, w, scan, truth[idx[:, 0]], max_normal_angle_deg=angle,
                                           rest_weight=DEFAULT_REST_WEIGHT)
        return float(np.linalg.norm(result.vertices[lips] - truth[lips], axis=1).mean())

    assert lip_error(MAX_NORMAL_ANGLE_DEG) < 0.8 * lip_error(60.0)

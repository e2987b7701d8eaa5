"""Tests for facecap.registration.find_marker_map: markers placed on a scan with no hand-picked points.

Round trips on generated takes whose true places are known (``marker_map_cases``: a resting expression,
a head band, an upside-down mocap frame, the scan in a turned scanner frame), and analytic surfaces for
what the generator cannot show exactly: a second sheet of skin under a marker, a scan cut short.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facecap.errors import InputError, MarkerError
from facecap.registration import MarkerMap, find_marker_map, rest_markers_of
from marker_map_cases import MapCase, map_case

OFFSET = 1.5


@pytest.fixture(scope="module")
def mapped() -> tuple[MapCase, np.ndarray, np.ndarray, MarkerMap]:
    mc = map_case(seed=3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rest, motion = rest_markers_of(mc.case.markers, 0)
    return mc, rest, motion, find_marker_map(rest, mc.scan.vertices, mc.scan.faces, motion=motion)


def _errors(mc: MapCase, found: MarkerMap) -> np.ndarray:
    M = mc.case.n_face_markers
    return np.linalg.norm(found.surface_points[:M] - mc.true_places, axis=1)


def test_markers_land_on_their_true_places(mapped) -> None:
    mc, _, _, found = mapped
    M = mc.case.n_face_markers
    error = _errors(mc, found)
    assert found.placed[:M].all()
    assert np.mean(error <= 1.5) >= 0.95
    reported = found.uncertain | found.ambiguous
    assert not np.any((error > 1.5) & ~reported[:M]), "a marker more than 1.5 mm off was not reported"
    assert np.median(error) < 0.5


def test_markers_the_resting_expression_moved_along_the_skin_are_flagged_with_how_far() -> None:
    # seed 2 rests with lowered brows, squinted eyes and a shrugged upper lip: two markers land 1.8-1.9 mm
    # from their true places, sitting only 0.4 mm off the marker offset after the fit
    mc = map_case(seed=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rest, motion = rest_markers_of(mc.case.markers, 0)
    found = find_marker_map(rest, mc.scan.vertices, mc.scan.faces, motion=motion)
    M = mc.case.n_face_markers
    error = _errors(mc, found)
    flagged = (found.uncertain | found.ambiguous)[:M]
    off = error > 1.5
    assert off.sum() >= 2 and flagged[off].all()
    assert flagged.sum() <= 0.15 * M  # not crying wolf: most markers are placed without a flag
    estimate = found.may_be_off_mm[:M]
    assert np.isfinite(estimate).all() and np.isnan(found.may_be_off_mm[~found.placed]).all()
    assert np.array_equal(found.uncertain, found.placed & (found.may_be_off_mm > 1.0))
    assert np.mean(error <= estimate) >= 0.75  # an estimate, not a bound: 9 in 10 on the benchmark's takes
    assert estimate[off].min() > np.median(estimate)


def test_the_head_band_is_found_off_the_skin_and_left_out(mapped) -> None:
    mc, _, _, found = mapped
    M = mc.case.n_face_markers
    band = slice(M, None)
    assert found.off_skin[band].all() and not found.placed[band].any()
    assert np.isnan(found.surface_points[band]).all() and (found.face_indices[band] == -1).all()
    assert (found.heights[band] > 10.0).all()  # 15 mm off the forehead in the generator


def test_the_pose_is_the_true_one_and_the_search_is_sure(mapped) -> None:
    mc, _, _, found = mapped
    angle = np.degrees(Rotation.from_matrix(found.rotation @ mc.mocap_to_scanner[:3, :3].T).magnitude())
    assert angle < 1.0
    assert found.sure and found.second_score_mm > 4.0 * found.score_mm


def test_placed_markers_sit_the_offset_above_their_skin_points(mapped) -> None:
    mc, _, _, found = mapped
    rows = found.placed & ~found.uncertain
    assert np.allclose(found.heights[rows], OFFSET, atol=0.5)
    lifted = np.linalg.norm(found.markers_on_scan[rows] - found.surface_points[rows], axis=1)
    assert np.allclose(lifted, found.heights[rows])
    F, V = mc.scan.faces, mc.scan.vertices
    corners = V[F[found.face_indices[rows]]]
    assert np.allclose(np.einsum("kc,kcd->kd", found.barycentric[rows], corners), found.surface_points[rows],
                       atol=1e-6)


def test_a_start_pose_gives_the_same_places_without_a_search(mapped) -> None:
    mc, rest, motion, found = mapped
    nudge = np.eye(4)  # 8 degrees about the face's centre and 8 mm aside
    nudge[:3, :3] = Rotation.from_rotvec([0.08, -0.05, 0.1]).as_matrix()
    centre = mc.true_places.mean(axis=0)
    nudge[:3, 3] = centre - nudge[:3, :3] @ centre + [6.0, -4.0, 3.0]
    start = nudge @ mc.mocap_to_scanner
    again = find_marker_map(rest, mc.scan.vertices, mc.scan.faces, motion=motion, start=start)
    assert np.isnan(again.second_score_mm) and again.sure
    rows = found.placed & again.placed
    assert np.allclose(again.surface_points[rows], found.surface_points[rows], atol=0.05)


def test_markers_past_the_scans_rim_are_not_placed(mapped) -> None:
    mc, rest, motion, found = mapped
    # cut the scan across the face: keep what lies below a plane through the middle of the face markers
    up = mc.scanner_from_face[:3, 1]  # the generator's +y (up the face) in the scanner frame
    level = float(np.median(mc.true_places @ up))
    V, F = mc.scan.vertices, mc.scan.faces
    keep = (V[F] @ up).max(axis=1) < level
    cut = find_marker_map(rest, V, F[keep], motion=motion, start=found.matrix)
    M = mc.case.n_face_markers
    height = mc.true_places @ up
    above, below = height > level + 8.0, height < level - 8.0
    assert not cut.placed[:M][above].any()
    assert cut.past_rim[:M][above].all() and not cut.off_skin[:M].any()
    assert cut.placed[:M][below].mean() > 0.9


def _elliptic_cap(n: int = 61, half_mm: float = 60.0) -> tuple[np.ndarray, np.ndarray]:
    """A face-like cap: z = -(x^2 / 160 + y^2 / 280) mm over a square, triangles facing +z (out)."""
    u = np.linspace(-half_mm, half_mm, n)
    x, y = np.meshgrid(u, u)
    V = np.stack([x.ravel(), y.ravel(), -(x.ravel() ** 2 / 160.0 + y.ravel() ** 2 / 280.0)], axis=1)
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + n + 1], 1), np.stack([a, a + n + 1, a + n], 1)])
    return V, F


def _normals(P: np.ndarray) -> np.ndarray:
    n = np.stack([P[:, 0] / 80.0, P[:, 1] / 140.0, np.ones(len(P))], axis=1)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def test_a_second_sheet_close_under_a_marker_makes_it_ambiguous() -> None:
    V, F = _elliptic_cap()
    # a lip: a piece of the same surface 1.5 mm below it, 24 x 8 mm, not joined to the skin above
    lip = (np.abs(V[:, 0] - 10.0) <= 12.0) & (np.abs(V[:, 1] + 20.0) <= 4.0)
    inner = np.flatnonzero(lip)
    index = np.full(V.shape[0], -1)
    index[inner] = V.shape[0] + np.arange(inner.size)
    lip_faces = index[F[lip[F].all(axis=1)]][:, ::-1]  # facing down, as the other lip faces
    V2 = np.concatenate([V, V[inner] - [0.0, 0.0, 1.5]])
    F2 = np.concatenate([F, lip_faces])
    g = np.linspace(-40.0, 40.0, 9)
    gx, gy = np.meshgrid(g, g)
    on_skin = np.stack([gx.ravel(), gy.ravel(), -(gx.ravel() ** 2 / 160.0 + gy.ravel() ** 2 / 280.0)], axis=1)
    markers = on_skin + OFFSET * _normals(on_skin)
    found = find_marker_map(markers, V2, F2, start=np.eye(4))
    assert found.placed.all()
    over_lip = (np.abs(on_skin[:, 0] - 10.0) <= 11.0) & (np.abs(on_skin[:, 1] + 20.0) <= 3.0)
    clear = (np.abs(on_skin[:, 0] - 10.0) > 17.0) | (np.abs(on_skin[:, 1] + 20.0) > 9.0)
    assert over_lip.sum() == 3 and clear.sum() == len(markers) - 3
    assert found.ambiguous[over_lip].all() and not found.ambiguous[clear].any()
    # the lip's sheet lies 1.5 mm straight down: 1.5 n_z along the normal, to within the cap's curvature
    expected = OFFSET + 1.5 * _normals(on_skin[over_lip])[:, 2]
    assert np.allclose(found.second_sheet_mm[over_lip], expected, atol=0.02)
    assert np.isinf(found.second_sheet_mm[clear]).all()
    assert np.allclose(found.surface_points, on_skin, atol=0.02)


def test_too_few_markers_at_the_rest_frame_are_refused() -> None:
    V, F = _elliptic_cap(n=11)
    markers = np.full((6, 3), np.nan)
    markers[:3] = V[:3]
    with pytest.raises(MarkerError, match="at least 4 markers"):
        find_marker_map(markers, V, F)


def test_bad_options_are_refused() -> None:
    V, F = _elliptic_cap(n=11)
    markers = V[::7] + [0.0, 0.0, OFFSET]
    with pytest.raises(MarkerError, match="motion"):
        find_marker_map(markers, V, F, motion=np.zeros((5, markers.shape[0] + 1, 3)), start=np.eye(4))
    with pytest.raises(InputError, match="marker_offset_mm"):
        find_marker_map(markers, V, F, marker_offset_mm=-1.0)
    with pytest.raises(InputError, match="start"):
        find_marker_map(markers, V, F, start=np.eye(3))

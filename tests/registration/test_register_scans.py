"""Tests for facecap.registration.register_scans: every scan of a plan in one topology, against generator truth."""

from __future__ import annotations

import numpy as np

from facecap._threads import available_cores
from facecap.registration import register_scans
from facecap.synth import generate_performance, scan_expression
from facecap.io.ict_sample import load_ict_sample


def test_markers_beyond_the_scan_still_place_the_skin_and_quality_is_reported():
    # A surprise with the jaw open, scanned from the front: markers on the sides of the face fall
    # outside the scan. Their skin is still where the frame's markers say (less their height), so
    # the registered surface must agree with every frame marker before the section-7 fit forces it;
    # without them eq. 7 extrapolated the sides from the scan edge (2.1 mm off here, 11-17 mm on studio takes).
    names = load_ict_sample().expression_names
    weights = np.zeros((2, len(names)))
    for n, w in (("browInnerUp_L", 0.8), ("browInnerUp_R", 0.8), ("browOuterUp_L", 0.7), ("browOuterUp_R", 0.7),
                 ("eyeWide_L", 0.6), ("eyeWide_R", 0.6), ("jawOpen", 0.45)):
        weights[1, names.index(n)] = w
    case = generate_performance(curves=weights, seed=11, n_markers=60, noise_mm=0.0, gap_fraction=0.0,
                                head_rotation_deg=0.0, head_translation_mm=0.0, headband_markers=0)
    scan = scan_expression(case.truth_vertices[1], case.scan.faces, seed=4, target_vertices=20000).mesh
    frame = case.markers.positions[[1]]
    result = register_scans([scan], frame, template=case.scan, template_markers=case.markers.positions[0],
                            progress=False)
    quality = result.report["scans"][0]["quality"]
    assert quality["marker_residual_mm"]["max"] < 1.0, quality  # measured 0.53 mm; 2.1 mm without their targets
    # and the basis sits at its frame's truth (pose included) far better than the neutral does
    A = result.output_from_mocap
    basis = result.bases[0] @ A[:3, :3].T + A[:3, 3]
    truth = case.truth_vertices[1].astype(np.float64)
    error = np.linalg.norm(basis - truth, axis=1).mean()
    assert error < 0.3 * np.linalg.norm(case.scan.vertices - truth, axis=1).mean()
    assert quality["tangential_motion_mm"] > 0.5 and quality["normal_motion_mm"] > 0.2  # a real expression


def test_worker_processes_give_the_bases_one_process_gives():
    names = load_ict_sample().expression_names
    weights = np.zeros((3, len(names)))
    weights[1, names.index("jawOpen")] = 0.4
    weights[2, [names.index("browInnerUp_L"), names.index("browInnerUp_R")]] = 0.8
    case = generate_performance(curves=weights, seed=5, n_markers=60, noise_mm=0.0, gap_fraction=0.0,
                                head_rotation_deg=0.0, head_translation_mm=0.0, headband_markers=0)
    scans = [scan_expression(case.truth_vertices[t], case.scan.faces, seed=t, target_vertices=6000).mesh for t in (1, 2)]
    common = dict(template=case.scan, template_markers=case.markers.positions[0], progress=False)
    frames = case.markers.positions[[1, 2]]
    alone = register_scans(scans, frames, workers=1, **common)
    side_by_side = register_scans(scans, frames, workers=2, **common)
    assert side_by_side.report["workers"] == min(2, available_cores())  # two processes where there are two cores
    np.testing.assert_allclose(side_by_side.bases, alone.bases, atol=1e-6)
    np.testing.assert_allclose(side_by_side.registration_mm, alone.registration_mm, atol=1e-9)

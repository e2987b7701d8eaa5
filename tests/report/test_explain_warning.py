"""Tests for facecap.report.explain_warning: warnings as facecap writes them get the advice for their kind."""

from __future__ import annotations

import pytest

from facecap.report import explain_warning

# Messages as the code writes them (numbers, files and labels filled in), with a phrase that only the
# advice written for that kind of warning holds: a message caught by another kind's pattern fails.
KNOWN = [
    ("4 take marker(s) are not in the marker map, so they do not drive the face (they may still give the head's motion): ['HB0', 'HB1', 'HB2', 'HB3']",
     "head-band"),
    ("take.c3d: 2 duplicate marker label(s) renamed (Chin -> Chin~1)", "same label"),
    ("markers Leye_Up, Reye_Up land off the model /data/model (outside the meshed face: ears, scalp, neck, eyes, "
     "inner lips): left out of the solve", "no flesh"),
    ("the take's rest frame does not fit the scan rigidly (a marker 13.5 mm from its map point, more than 5): "
     "mapped onto it by the triharmonic warp, as animate does (--retarget)", "more than a rigid move"),
    ("take.c3d: no head motion beyond what the expressions move the most rigid markers by; the take is left "
     "unstabilised (name the stable markers to force it)", "no head motion to remove"),
    ("stabilize_head: stable markers ['Chin_R2', 'NoseTop'] are missing at rest_frame 0 and are not used",
     "not seen at the rest frame"),
    ("stabilize_head: 3 frame(s) have fewer than 3 stable markers visible (first: frame 12); they are left NaN",
     "fewer than three"),
    ("the rigid set for the head motion holds Chin_R2, a marker on the jaw", "jaw or lips"),
    ("bilateral_filter: 2 marker(s) not visible within 30 frames of rest_frame 0 (columns [4, 7]...); they are "
     "filtered in time only", "in time only"),
    ("scan.obj: the scan is 2.5 across but the markers span 180 mm (0.0139 times as large read as mm), which no "
     "length unit explains; check --scan-units and the take's unit", "no change of unit"),
    ("scan.obj: the scan is 25.1 across but the markers span 180 mm: read as centimetres", "makes the two match"),
    ("2 piece(s) of the scan carry no marker (1200 vertices); they are carried by the nearest marked surface",
     "eyes, teeth"),
    ("pypardiso (MKL PARDISO) is not available; using SciPy's SuperLU, which is much slower and uses more memory "
     "on large scans", "pip install pypardiso"),
    ("the stiffness at the solution is not positive definite (an unstable equilibrium, or inverted tetrahedra); "
     "the Jacobians use the projected stiffness and are approximate", "unstable equilibrium"),
    ("recomputing a damaged chunk: chunk 3 is truncated", "computed again"),
    ("select_scan_frames: no further frame lowers the error; stopped at 6 frames with 0.41 mm RMS above the "
     "tolerance 0.3 mm", "tolerance"),
    ("blend: no correspondence.npz (2 markers seen at the rest frame, or a frame's pose not finite): facecap "
     "wrinkles cannot use this result", "wrinkles cannot use it"),
    ("frame 4 (camera cam_left): wrinkle 2 (paint 3) was not found; it is left out until it reappears where it "
     "was last seen", "not found in this video frame"),
    ("camera 'cam_right': only 40% of the painted wrinkles it tracks at video frame 0 land on the face; its "
     "calibration may not match the footage (wrinkles that miss the face are left out)", "calibration"),
]


@pytest.mark.parametrize("message, phrase", KNOWN)
def test_each_kind_of_warning_gets_its_own_advice(message: str, phrase: str) -> None:
    advice = explain_warning(message)
    assert advice.known
    assert phrase in advice.meaning + " " + advice.action
    assert advice.meaning.endswith(".") and advice.action.endswith(".")


def test_the_rest_pose_warning_points_to_the_rest_pose_figures() -> None:
    advice = explain_warning("rest frame 0 holds a resting expression (1.2 mm RMS from the scan, noise 0.1 mm): "
                             "kept as motion")
    assert advice.known and "rest-pose figures" in advice.action


def test_an_unknown_warning_gets_the_general_advice() -> None:
    advice = explain_warning("something facecap has never said before")
    assert not advice.known
    assert advice.meaning and advice.action

"""Generated takes for the tests of ``facecap map`` (find_marker_map, map_markers, check_marker_map, the CLI).

Importable as ``marker_map_cases`` (``tests/`` is on the path). A take is seen in a mocap frame turned
upside down and the scan is moved into another frame, so nothing lines up by accident; the actor rests
with an expression of their own, and a head band rides on the head.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation

from facecap.structures import Mesh
from facecap.synth import SyntheticCase, generate_performance, random_identity, random_rest_expression

HEADBAND = 4


class MapCase(NamedTuple):
    """A generated take and its scan moved into a scanner frame, with the truth in that frame."""

    case: SyntheticCase
    scan: Mesh
    """The neutral scan in the scanner frame (mm)."""
    scanner_from_face: np.ndarray
    """(4, 4): the generator's scan frame to the scanner frame."""
    true_places: np.ndarray
    """(M, 3) mm: each face marker's true place on the skin, in the scanner frame."""
    mocap_to_scanner: np.ndarray
    """(4, 4): the true rigid pose from the take's frame to the scan's."""


def map_case(seed: int = 3, *, n_frames: int = 180, n_markers: int = 60, headband: int = HEADBAND) -> MapCase:
    """A take with a resting expression in an upside-down mocap frame, and its scan in a turned scanner frame."""
    mocap = np.eye(4)
    mocap[:3, :3] = Rotation.from_euler("xyz", [180.0, 25.0, -70.0], degrees=True).as_matrix()  # upside down
    mocap[:3, 3] = [400.0, -250.0, 1600.0]
    case = generate_performance(n_frames=n_frames, n_markers=n_markers, identity=random_identity(seed),
                                rest_expression=random_rest_expression(seed), headband_markers=headband,
                                mocap_frame=mocap, seed=seed)
    scanner = np.eye(4)
    scanner[:3, :3] = Rotation.from_rotvec([0.4, -1.9, 0.7]).as_matrix()
    scanner[:3, 3] = [-120.0, 35.0, 260.0]
    V = case.scan.vertices @ scanner[:3, :3].T + scanner[:3, 3]
    scan = Mesh(V, case.scan.faces)
    return MapCase(case, scan, scanner, V[case.marker_vertices], scanner @ np.linalg.inv(case.mocap_from_scan))

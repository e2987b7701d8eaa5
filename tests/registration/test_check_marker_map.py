"""Tests for facecap.registration.check_marker_map: a hand-made map checked against its take.

The generator's own map (the true vertices) must pass; the same map with entries broken the ways a
hand-made map breaks (two labels swapped, one vertex picked on the wrong feature) must have exactly
those entries flagged.
"""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import CorrespondenceError
from facecap.structures import Correspondence
from facecap.registration import MAP_CHECK_MM, check_marker_map
from marker_map_cases import HEADBAND, map_case


@pytest.fixture(scope="module")
def case():
    return map_case(seed=5, n_frames=150)


def _map(case, entries: dict[str, int]) -> Correspondence:
    labels = tuple(entries)
    vertices = np.array([entries[s] for s in labels])
    return Correspondence(labels, np.repeat(vertices[:, None], 3, axis=1), np.eye(3)[np.zeros(len(labels), int)],
                          source_path="map.json")


def test_the_true_map_passes(case) -> None:
    report = check_marker_map(case.scan, case.case.markers, _map(case, case.case.correspondence))
    assert report["flagged"] == []
    assert report["not_in_map"] == [f"HB{i}" for i in range(HEADBAND)]
    assert report["fit_rms_mm"] < 1.0
    found = np.array([row["found_vs_mapped_mm"] for row in report["markers"]])
    assert np.median(found) < 0.5 and found.max() < MAP_CHECK_MM
    assert "flagged       none" in "\n".join(report["summary"])


def test_broken_entries_are_flagged(case) -> None:
    entries = dict(case.case.correspondence)
    V = case.scan.vertices
    entries["M010"], entries["M020"] = entries["M020"], entries["M010"]  # two labels swapped
    far = np.linalg.norm(V - V[entries["M033"]], axis=1)
    entries["M033"] = int(np.argmin(np.abs(far - 25.0)))  # picked 25 mm away
    report = check_marker_map(case.scan, case.case.markers, _map(case, entries))
    assert set(report["flagged"]) == {"M010", "M020", "M033"}
    rows = {row["label"]: row for row in report["markers"]}
    assert rows["M033"]["found_vs_mapped_mm"] == pytest.approx(25.0, abs=3.0)
    assert not any(row["flagged"] for label, row in rows.items() if label not in report["flagged"])
    assert sum(line.startswith("    M0") for line in report["summary"]) == 3


def test_a_map_naming_markers_the_take_lacks_is_refused(case) -> None:
    entries = dict(case.case.correspondence)
    entries["Nose"] = 12
    with pytest.raises(CorrespondenceError, match="Nose"):
        check_marker_map(case.scan, case.case.markers, _map(case, entries))

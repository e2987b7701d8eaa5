"""Tests for facecap.registration.rest_markers_of: the rest frame averaged and filled, on a take as a studio holds it."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from facecap.io import read_markers
from facecap.registration import rest_markers_of
from facecap.synth import write_synthetic_case
from marker_map_cases import map_case


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    mc = map_case(seed=3, n_frames=150)
    folder = tmp_path_factory.mktemp("case")
    written = write_synthetic_case(mc.case, folder, scan_unit="cm")
    return mc, written


def test_the_rest_frame_is_averaged_and_a_gap_there_is_filled(files) -> None:
    mc, written = files
    take = read_markers(written.markers)
    positions = take.positions.copy()
    positions[0, 7] = np.nan  # a marker missing at the rest frame
    gappy = type(take)(positions, take.labels, rate=take.rate, source_unit=take.source_unit)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rest, motion = rest_markers_of(gappy, 0)
    noiseless = mc.case.noiseless_markers[0]
    assert np.isfinite(rest).all() and motion.shape[1:] == positions.shape[1:]
    assert np.linalg.norm(rest[7] - noiseless[7]) < 1.0
    # the average over the frames round the rest frame takes out most of the 0.2 mm noise
    seen = np.arange(len(take.labels)) != 7
    averaged = np.sqrt(np.mean((rest[seen] - noiseless[seen]) ** 2))
    assert averaged < 0.6 * np.sqrt(np.mean((take.positions[0, seen] - noiseless[seen]) ** 2))

"""read_markers on real vendor C3D files (tests/io/data/c3d_corpus, see its README.md).

The independent truth is ezc3d's own reading of each file, with facecap's documented
handling applied to ezc3d's raw arrays here (unit scale from POINT:UNITS, a gap where
the residual is negative or x, y, z are all zero, Subject: prefixes split off when the
labels stay unique). Big-endian (SGI) files, which ezc3d refuses, are checked against
the Intel copy of the same take that c3d.org publishes beside them.
"""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import ezc3d
import numpy as np
import pytest

from facecap.errors import FacecapWarning
from facecap.io.read_markers import read_markers
from facecap.units import mm_per_unit

CORPUS = Path(__file__).parent / "data" / "c3d_corpus"
FILES = sorted(p.name for p in CORPUS.glob("*.c3d"))

# File -> (frames ezc3d returns, frames facecap returns, why they differ).
FRAME_FIXES = {
    # POINT:USED says 12 markers, the header 11; only 11 fit the file's data for the
    # 152 frames both counts state: ezc3d reads 145 misaligned frames of 12 markers.
    "kyowadengyo.c3d": (145, 152, "POINT:USED"),
}
# Files ezc3d refuses (processor type 86) -> their Intel (PC) copy in the corpus.
BIG_ENDIAN = {
    "c3dorg_s01_Eb015si.c3d": "c3dorg_s01_Eb015pi.c3d",
    "c3dorg_s02_sgi_int.c3d": "c3dorg_s02_pc_int.c3d",
    "c3dorg_s02_sgi_real.c3d": "c3dorg_s02_pc_real.c3d",
    "motionanalysis_MACsample_sgi.c3d": None,  # no PC copy published
}
# Files read with a FacecapWarning, and what it says.
WARNS = {
    "motionanalysis_Walk1.c3d": "duplicate marker label",
    "motionanalysis_MACsample_sgi.c3d": "duplicate marker label",
    "c3dorg_s28_dynamic.c3d": "duplicate marker label",
}
UNIT_WORDS = {"mm": "mm", "cm": "cm", "m": "m", "": "mm"}


def _read(name):
    path = CORPUS / name
    if name in WARNS:
        with pytest.warns(FacecapWarning, match=WARNS[name]):
            return read_markers(path)
    return read_markers(path)


def _ezc3d_truth(path):
    """What facecap should return, from ezc3d's raw arrays and facecap's documented rules."""
    c = ezc3d.c3d(str(path))
    P = np.asarray(c["data"]["points"], dtype=np.float64)[:3].transpose(2, 1, 0)
    R = np.asarray(c["data"]["meta_points"]["residuals"], dtype=np.float64)[0].T
    point = c["parameters"]["POINT"]
    units = [u.strip() for u in point["UNITS"]["value"] if u.strip()] if "UNITS" in point else []
    scale = mm_per_unit(UNIT_WORDS.get(units[0] if units else "", units[0] if units else "mm"))
    gaps = (R < 0) | (P == 0).all(axis=2)
    labels = []
    k = 1
    while ("LABELS" if k == 1 else f"LABELS{k}") in point:
        labels += [s.strip() for s in point["LABELS" if k == 1 else f"LABELS{k}"]["value"]]
        k += 1
    labels = labels[: P.shape[1]]
    return P * scale, R * scale, gaps, labels, float(point["RATE"]["value"][0])


@pytest.mark.parametrize("name", [n for n in FILES if n not in BIG_ENDIAN])
def test_corpus_file_reads_as_ezc3d_reads_it(name):
    path = CORPUS / name
    take = _read(name)
    P, R, gaps, raw_labels, rate = _ezc3d_truth(path)
    if name in FRAME_FIXES:
        ez_frames, fc_frames, _ = FRAME_FIXES[name]
        assert P.shape[0] == ez_frames and take.n_frames == fc_frames
        return
    assert take.n_frames == P.shape[0] and take.n_markers == P.shape[1]
    assert take.rate == pytest.approx(rate, rel=1e-12)
    np.testing.assert_array_equal(take.gap_mask, gaps)
    np.testing.assert_allclose(take.positions[~gaps], P[~gaps], rtol=1e-6, atol=0)
    np.testing.assert_allclose(take.residuals[~gaps], R[~gaps], rtol=1e-6, atol=0)
    assert np.isnan(take.residuals[gaps]).all()
    # Labels: the file's, with a Subject: prefix split off into take.subjects, and
    # duplicates made unique by a suffix (first occurrence unchanged).
    if take.subjects is not None:
        rebuilt = [f"{s}:{m}" if s else m for s, m in zip(take.subjects, take.labels)]
    else:
        rebuilt = list(take.labels)
    assert len(set(take.labels)) == len(take.labels)
    for got, want in zip(rebuilt, raw_labels):
        assert got == want or (want and got.startswith(want + "_") and got[len(want) + 1 :].isdigit()) or (
            not want and got.startswith("unlabeled_point_")
        )


@pytest.mark.parametrize("name", sorted(BIG_ENDIAN))
def test_big_endian_file_agrees_with_its_pc_copy(name):
    with pytest.raises(Exception, match="MIPS"):
        ezc3d.c3d(str(CORPUS / name))  # why facecap converts it first
    take = _read(name)
    assert take.n_frames > 0 and np.isfinite(take.positions).any()
    pc_name = BIG_ENDIAN[name]
    if pc_name is None:
        return
    pc = _read(pc_name)
    assert take.labels == pc.labels and take.rate == pc.rate and take.first_frame == pc.first_frame
    np.testing.assert_array_equal(take.gap_mask, pc.gap_mask)
    np.testing.assert_array_equal(take.positions, pc.positions)
    np.testing.assert_array_equal(take.residuals, pc.residuals)


def test_dec_files_agree_with_their_pc_copies():
    for dec, pc, tolerance in [
        ("c3dorg_s01_Eb015vi.c3d", "c3dorg_s01_Eb015pi.c3d", 0.0),
        ("c3dorg_s02_dec_real.c3d", "c3dorg_s02_pc_real.c3d", 0.0),
        # c3d.org's DEC integer copy differs from the PC one by one count (POINT:SCALE,
        # 0.28 mm) in 59 of 9612 samples: a rounding in their conversion, seen by ezc3d too.
        ("c3dorg_s02_dec_int.c3d", "c3dorg_s02_pc_int.c3d", 0.2812),
    ]:
        a, b = read_markers(CORPUS / dec), read_markers(CORPUS / pc)
        assert a.labels == b.labels and a.rate == b.rate
        np.testing.assert_array_equal(a.gap_mask, b.gap_mask)
        np.testing.assert_allclose(a.positions, b.positions, rtol=0, atol=tolerance)


def test_kyowadengyo_reads_the_header_marker_count_the_data_fit():
    take = read_markers(CORPUS / "kyowadengyo.c3d")
    assert take.n_markers == 11 and take.n_frames == 152
    # Misaligned frames would jump by metres between frames; the real take moves smoothly.
    steps = np.abs(np.diff(take.positions, axis=0))
    assert np.nanmax(steps) < 100.0


def test_vicon_subject_prefix_is_split_off():
    take = read_markers(CORPUS / "vicon_gait-pig.c3d")
    assert take.subjects is not None and set(take.subjects) == {"A22"}
    assert "RKNE" in take.labels and not any(":" in s for s in take.labels)
    sub = take.select(["LKNE", "RKNE"])
    assert sub.subjects == ("A22", "A22")


def test_facecap_info_succeeds_on_every_corpus_file():
    from facecap.report.describe import describe_file

    paths = [CORPUS / n for n in FILES]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FacecapWarning)
        for path in paths:
            info = describe_file(path)
            take = read_markers(path)
            assert info["frames"] == take.n_frames and info["labels"] == list(take.labels)
    # and through the command line itself, on a big-endian file
    cli = subprocess.run(
        [sys.executable, "-W", "ignore", "-m", "facecap.cli", "info", str(CORPUS / "c3dorg_s02_sgi_real.c3d")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert cli.returncode == 0 and "89" in cli.stdout, cli.stderr[-2000:]

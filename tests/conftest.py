"""Shared fixtures: a small analytic capture case independent of the ICT generator, and the small anatomical
model of the bundled ICT face that the anatomy, muscle and muscle CLI tests share (built once a session)."""

from __future__ import annotations

import os

if os.environ.get("PYTEST_XDIST_WORKER"):
    # The suite runs on one worker process per core (pyproject's addopts): a BLAS thread pool per worker
    # as wide as the machine would only fight the other worker for its core. Set before numpy loads (the same
    # choice as the package's own worker processes, facecap._processes, which cannot be imported before numpy).
    for _variable in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ.setdefault(_variable, "1")

from pathlib import Path

import pytest

from analytic_case import CaptureCase

SMALL_MODEL_TETS = 2000  # fTetWild lands at about 3,900 tetrahedra, 1,300 nodes, 36 muscles


@pytest.fixture
def capture_case(tmp_path: Path) -> CaptureCase:
    return CaptureCase(tmp_path)


@pytest.fixture
def capture_case_head_motion(tmp_path: Path) -> CaptureCase:
    return CaptureCase(tmp_path, head_motion=True)


@pytest.fixture(scope="session")
def anatomy():
    """The bundled ICT face's anatomy at ``SMALL_MODEL_TETS`` (about 8 s to build; tests must not change it)."""
    from facecap.anatomy import build_anatomy
    from facecap.io.ict_sample import load_ict_sample

    return build_anatomy(load_ict_sample().mesh, n_tets=SMALL_MODEL_TETS, progress=False)

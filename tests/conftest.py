"""Shared fixtures: a small analytic capture case independent of the ICT generator."""

from __future__ import annotations

from pathlib import Path

import pytest

from analytic_case import CaptureCase


@pytest.fixture
def capture_case(tmp_path: Path) -> CaptureCase:
    return CaptureCase(tmp_path)


@pytest.fixture
def capture_case_head_motion(tmp_path: Path) -> CaptureCase:
    return CaptureCase(tmp_path, head_motion=True)

"""Shared fixture of the anatomy tests: the soft-tissue shell of the bundled ICT face, built once a session
(the shell's own tests and the mesher's tests share it)."""

from __future__ import annotations

import pytest

from facecap.anatomy import anatomy_landmarks, soft_tissue_shell
from facecap.io.ict_sample import load_ict_sample


@pytest.fixture(scope="session")
def shell():
    """The closed soft-tissue surface of the bundled ICT face (tests must not change it)."""
    mesh = load_ict_sample().mesh
    return soft_tissue_shell(mesh, anatomy_landmarks(mesh))

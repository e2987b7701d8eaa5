"""tetrahedralize_shell, tet_volumes and tet_quality: a regular tetrahedron by hand, and one valid fTetWild mesh of the
bundled ICT face's soft tissue (the shell fixture is in conftest.py)."""

from __future__ import annotations

import os

import numpy as np
import pytest
import trimesh

from facecap.anatomy import PART_BONE, tet_quality, tet_volumes, tetrahedralize_shell
from facecap.anatomy.tetrahedralize_shell import ENVELOPE_MM
from facecap.errors import InputError

TEST_TETS = 2000


@pytest.fixture(scope="module")
def tets(shell, tmp_path_factory):
    """The coarse mesh, made from an empty working folder (fTetWild itself writes files into it)."""
    folder = tmp_path_factory.mktemp("cwd")
    previous = os.getcwd()
    os.chdir(folder)
    try:
        mesh = tetrahedralize_shell(shell.V, shell.F, n_tets=TEST_TETS)
    finally:
        os.chdir(previous)
    return mesh, folder


def test_quality_of_a_regular_tetrahedron() -> None:
    a = 10.0
    X = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=np.float64) * a / (2 * np.sqrt(2))
    T = np.array([[0, 1, 2, 3]])
    if tet_volumes(X, T)[0] < 0:
        T = T[:, [0, 2, 1, 3]]
    q = tet_quality(X, T)
    assert q.min_volume_mm3 == pytest.approx(a**3 / (6 * np.sqrt(2)), rel=1e-12)
    assert q.min_dihedral_deg == pytest.approx(np.degrees(np.arccos(1 / 3)), abs=1e-9)
    assert q.max_dihedral_deg == pytest.approx(np.degrees(np.arccos(1 / 3)), abs=1e-9)
    assert q.n_inverted == 0
    assert tet_quality(X, T[:, [0, 2, 1, 3]]).n_inverted == 1


def test_the_mesher_leaves_no_files_behind(tets) -> None:
    _, folder = tets
    assert list(folder.iterdir()) == []


def test_tetrahedra_are_positive_and_fill_the_meshed_volume(shell, tets) -> None:
    tets, _ = tets
    X, T = tets.X, tets.T
    assert X.dtype == np.float64 and T.dtype == np.int64 and T.shape[1] == 4
    vol = tet_volumes(X, T)
    assert vol.min() > 0
    q = tet_quality(X, T)
    assert q.n_inverted == 0 and q.min_dihedral_deg > 1.0
    assert 0.5 * TEST_TETS < T.shape[0] < 3 * TEST_TETS
    meshed = trimesh.Trimesh(tets.surface_V, tets.surface_F, process=False)
    assert meshed.is_watertight
    # fTetWild keeps the boundary within its envelope of the surface: the volumes differ by at most
    # area x envelope (a shell of that thickness round the surface)
    assert abs(vol.sum() - meshed.volume) <= meshed.area * ENVELOPE_MM
    # measured: within 0.3 % (the bound above allows 11 %)
    assert abs(vol.sum() - meshed.volume) < 0.01 * meshed.volume
    # the edge-collapse decimation for a coarse mesh shrinks convex parts a little (measured 4.5 %
    # at this setting; none at the default, where the surface is meshed as it is)
    full = trimesh.Trimesh(shell.V, shell.F, process=False).volume
    assert 0.0 <= full - meshed.volume < 0.06 * full
    # every node is used and lies inside the envelope's reach of the surface
    assert np.unique(T).size == X.shape[0]
    lo, hi = shell.V.min(axis=0) - ENVELOPE_MM, shell.V.max(axis=0) + ENVELOPE_MM
    assert np.all((X >= lo) & (X <= hi))


def test_too_few_tets_or_an_open_surface_is_refused(shell) -> None:
    with pytest.raises(InputError, match="n_tets"):
        tetrahedralize_shell(shell.V, shell.F, n_tets=10)
    with pytest.raises(InputError, match="not closed"):
        tetrahedralize_shell(shell.V, shell.F[shell.part != PART_BONE], n_tets=1000)

"""One tetrahedral mesh of a closed surface with fTetWild, positively oriented, and its quality.

fTetWild (Hu et al. 2020, MPL-2.0, through the ``pytetwild`` wheel) rather
than TetGen (AGPL-3): it never fails on imperfect input and guarantees no
inverted tetrahedra. Its boundary lies within an envelope ``epsilon`` of the
input surface rather than on it, which is why the skin is embedded by
barycentric coordinates (:mod:`.skin_embedding`) instead of reusing vertices.
"""

from __future__ import annotations

import glob
import importlib.machinery
import importlib.util
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType
from typing import NamedTuple

import igl
import numpy as np
import trimesh

from ..errors import InputError, SolverError
from ..typing import FloatArray, IntArray

__all__ = ["TetMesh", "TetQuality", "tet_quality", "tet_volumes", "tetrahedralize_shell"]

ENVELOPE_MM = 0.6
"""fTetWild's envelope: the tetrahedral boundary stays within this distance of the closed surface."""
OPTIMIZE_PASSES = 40
"""fTetWild's mesh-improvement passes by default (its own default is 80; 40 reach the same quality here)."""
_TETS_PER_IDEAL = 1.25
"""Measured ratio of fTetWild's tetrahedron count to ``volume / ideal regular-tet volume`` (calibrates ``n_tets``)."""


class TetMesh(NamedTuple):
    """A tetrahedral mesh and the surface fTetWild was given.

    Attributes
    ----------
    X : (N, 3) float64 array, mm
        Nodes.
    T : (M, 4) int64 array
        Tetrahedra, positively oriented: ``det[x1-x0, x2-x0, x3-x0] > 0``.
    surface_V : (p, 3) float64 array, mm
        The closed surface meshed (the input, or its decimation).
    surface_F : (q, 3) int64 array
        Its triangles.
    """

    X: FloatArray
    T: IntArray
    surface_V: FloatArray
    surface_F: IntArray


class TetQuality(NamedTuple):
    """Quality figures of a tetrahedral mesh.

    Attributes
    ----------
    n_tets, n_nodes : int
    n_inverted : int
        Tetrahedra with volume <= 0.
    min_volume_mm3, mean_volume_mm3, total_volume_mm3 : float, mm^3
    min_dihedral_deg, max_dihedral_deg : float, degrees
        Extreme dihedral angles over all tetrahedra (a regular one has 70.5).
    """

    n_tets: int
    n_nodes: int
    n_inverted: int
    min_volume_mm3: float
    mean_volume_mm3: float
    total_volume_mm3: float
    min_dihedral_deg: float
    max_dihedral_deg: float


def _ftetwild() -> ModuleType:
    """fTetWild's compiled wrapper, loaded without ``pytetwild/__init__``.

    pytetwild 0.4's package ``__init__`` imports PyVista (about 150 MB with
    VTK) only to register an accessor; the extension itself needs only numpy,
    so it is loaded from its file directly.
    """
    spec = importlib.util.find_spec("pytetwild")
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("fTetWild is missing: pip install pytetwild (a facecap dependency)")
    folder = spec.submodule_search_locations[0]
    found = [p for suffix in importlib.machinery.EXTENSION_SUFFIXES
             for p in glob.glob(os.path.join(folder, "PyfTetWildWrapper*" + suffix))]
    if not found:
        raise ImportError("pytetwild is installed without its compiled PyfTetWildWrapper; reinstall pytetwild")
    name = "pytetwild.PyfTetWildWrapper"
    loader = importlib.machinery.ExtensionFileLoader(name, found[0])
    module_spec = importlib.util.spec_from_file_location(name, found[0], loader=loader)
    if module_spec is None:  # pragma: no cover - spec_from_file_location with a loader returns one
        raise ImportError(f"cannot load fTetWild from {found[0]}")
    module = importlib.util.module_from_spec(module_spec)
    loader.exec_module(module)
    return module


def tet_volumes(X: FloatArray, T: IntArray) -> FloatArray:
    """Signed volume of each tetrahedron.

    Parameters
    ----------
    X : (N, 3) float64 array, mm
        Nodes.
    T : (M, 4) int64 array
        Tetrahedra.

    Returns
    -------
    (M,) float64 array, mm^3
        ``det[x1 - x0, x2 - x0, x3 - x0] / 6``: positive for the orientation
        used here.
    """
    D = X[T[:, 1:]] - X[T[:, :1]]
    return np.linalg.det(D) / 6.0


def tet_quality(X: FloatArray, T: IntArray) -> TetQuality:
    """Volumes and dihedral angles of a tetrahedral mesh.

    Parameters
    ----------
    X : (N, 3) float64 array, mm
    T : (M, 4) int64 array

    Returns
    -------
    TetQuality

    Notes
    -----
    The dihedral angle at the edge shared by faces i and j is
    ``pi - angle(n_i, n_j)`` with ``n_i`` the outward normal of the face
    opposite vertex i.
    """
    vol = tet_volumes(X, T)
    P = X[T]
    faces = ((1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1))  # face opposite vertex i, outward for positive tets
    normals = []
    for a, b, c in faces:
        n = np.cross(P[:, b] - P[:, a], P[:, c] - P[:, a])
        normals.append(n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300))
    angles = []
    for i in range(4):
        for j in range(i + 1, 4):
            cos = np.clip(np.einsum("ij,ij->i", normals[i], normals[j]), -1.0, 1.0)
            angles.append(np.pi - np.arccos(cos))
    A = np.degrees(np.stack(angles, axis=1))
    return TetQuality(
        n_tets=int(T.shape[0]), n_nodes=int(X.shape[0]), n_inverted=int(np.sum(vol <= 0)),
        min_volume_mm3=float(vol.min()), mean_volume_mm3=float(vol.mean()), total_volume_mm3=float(vol.sum()),
        min_dihedral_deg=float(A.min()), max_dihedral_deg=float(A.max()),
    )


@contextmanager
def _in_scratch_folder() -> Iterator[None]:
    """Run the block in a temporary working folder, deleted afterwards.

    fTetWild writes ``__tracked_surface.stl`` into the current folder on every
    run (whatever its log level); this keeps it out of the user's folder. It
    changes the process's working folder for the duration, so do not mesh
    from several threads at once.
    """
    previous = os.getcwd()
    with tempfile.TemporaryDirectory(prefix="facecap-ftetwild-") as scratch:
        os.chdir(scratch)
        try:
            yield
        finally:
            os.chdir(previous)


def _run_ftetwild(V: FloatArray, F: IntArray, edge: float, bbox: float, threads: int,
                  optimize_passes: int) -> tuple[np.ndarray, np.ndarray]:
    """One fTetWild call with this module's settings (positional: the wrapper takes no keywords)."""
    return _ftetwild().tetrahedralize_mesh(
        np.ascontiguousarray(V, dtype=np.float64), np.ascontiguousarray(F, dtype=np.uint32),
        True,  # optimize
        False,  # skip_simplify
        0.05,  # edge_length_r, ignored when the absolute length is given
        float(edge),
        float(ENVELOPE_MM / bbox),  # epsilon, relative to the bounding-box diagonal
        10.0,  # stop_energy (fTetWild's default)
        False,  # coarsen
        int(threads),
        int(optimize_passes),
        6,  # log level
        True,  # quiet
        False,  # vtk_ordering
        False,  # disable_filtering
        np.zeros((0, 3)), np.zeros((0, 4), dtype=np.int32), np.zeros(0),
    )


def tetrahedralize_shell(V: FloatArray, F: IntArray, *, n_tets: int = 100_000, threads: int = 2,
                        optimize_passes: int = OPTIMIZE_PASSES) -> TetMesh:
    """Fill a closed, outward-oriented triangle surface with about ``n_tets`` tetrahedra.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Surface vertices.
    F : (m, 3) int64 array
        Triangles, watertight, outward.
    n_tets : int, optional
        Approximate number of tetrahedra wanted, default 100,000 (fTetWild
        grades the size, so the count lands within about 30 % of it).
    threads : int, optional
        Threads fTetWild may use, default 2.
    optimize_passes : int, optional
        fTetWild's mesh-improvement passes (most of its time), default 40;
        fewer give a valid mesh sooner with a smaller minimum dihedral angle.

    Returns
    -------
    TetMesh
        Positively oriented tetrahedra (unused nodes removed) and the
        surface actually meshed.

    Raises
    ------
    InputError
        If ``n_tets`` is below 100 or the surface is not closed.
    SolverError
        If fTetWild returns an empty or inverted mesh.

    Notes
    -----
    The ideal edge length is that of a regular tetrahedron of volume
    ``volume * c / n_tets`` (``c`` = 1.25, measured on the ICT face: fTetWild adds
    tetrahedra near the surface). When the surface is much finer than that
    edge it is first decimated (libigl's shortest-edge collapse) to about two
    triangles per ideal edge squared, which fTetWild would otherwise do itself, slowly;
    the envelope of 0.6 mm bounds how far the tetrahedral boundary strays
    from the surface it meshed. The decimation shrinks convex parts a
    little (4.5 % of the volume at 2,700 triangles on the ICT face);
    QSlim keeps the volume (0.2 %) but its slivers make fTetWild
    refine to twice the tetrahedra in 1.5 times the time, so it is not used.
    """
    if int(n_tets) < 100:
        raise InputError(f"n_tets: expected at least 100 tetrahedra, got {n_tets}")
    if int(optimize_passes) < 1:
        raise InputError(f"optimize_passes: expected at least 1, got {optimize_passes}")
    surface = trimesh.Trimesh(V, F, process=False)
    if not surface.is_watertight:
        raise InputError("the surface to tetrahedralize is not closed")
    volume = float(surface.volume)
    edge = (6.0 * np.sqrt(2.0) * volume * _TETS_PER_IDEAL / int(n_tets)) ** (1.0 / 3.0)
    faces_wanted = int(2 * surface.area / (np.sqrt(3) / 4 * edge**2))
    Vin, Fin = V, F
    if faces_wanted < 0.7 * F.shape[0]:
        Vd, Fd, _, _ = igl.decimate(V, F, max(faces_wanted, 1000))
        if trimesh.Trimesh(Vd, Fd, process=False).is_watertight:
            Vin, Fin = Vd, Fd
    bbox = float(np.linalg.norm(Vin.max(axis=0) - Vin.min(axis=0)))
    with _in_scratch_folder():
        X, T = _run_ftetwild(Vin, Fin, edge, bbox, threads, optimize_passes)
    X = np.ascontiguousarray(X, dtype=np.float64)
    T = np.ascontiguousarray(T, dtype=np.int64)
    if T.shape[0] == 0:
        raise SolverError("fTetWild returned no tetrahedra")
    vol = tet_volumes(X, T)
    flip = vol < 0
    T[flip] = T[flip][:, [0, 2, 1, 3]]
    if np.any(vol == 0):
        raise SolverError("fTetWild returned degenerate tetrahedra")
    used, T = np.unique(T, return_inverse=True)
    return TetMesh(np.ascontiguousarray(X[used]), np.ascontiguousarray(T.reshape(-1, 4).astype(np.int64)),
                   np.ascontiguousarray(Vin, dtype=np.float64), np.ascontiguousarray(Fin, dtype=np.int64))

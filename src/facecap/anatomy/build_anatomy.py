"""Build the anatomical face model of a scan: bone, one tetrahedral soft-tissue mesh, muscles, skin."""

from __future__ import annotations

import os
import time
from importlib import metadata
from typing import Any

import igl
import numpy as np
from tqdm.auto import tqdm

from ..errors import InputError
from ..structures import Mesh
from .anatomy_landmarks import AnatomyLandmarks, anatomy_landmarks
from .face_anatomy import FaceAnatomy
from .facial_muscles import facial_muscles
from .jaw_joint import JAW_GAP_MM, in_jaw_gap, is_mandible, jaw_joint
from .skin_embedding import embed_points
from .soft_tissue_shell import PART_BONE, PART_RIM, soft_tissue_shell
from .tetrahedralize_shell import ENVELOPE_MM, tet_quality, tetrahedralize_shell

__all__ = ["build_anatomy"]

TISSUE_DEPTH_SOURCE = (
    "Rhine & Campbell 1980 (American White males, normal build), as reproduced in the forensic "
    "facial-reconstruction literature; see docs/anatomy.md"
)


def boundary_nodes(T: np.ndarray) -> np.ndarray:
    """Nodes of a tetrahedral mesh ``T`` (m, 4) on its surface: on faces that belong to one tetrahedron only."""
    faces = np.concatenate([T[:, [1, 2, 3]], T[:, [0, 3, 2]], T[:, [0, 1, 3]], T[:, [0, 2, 1]]])
    key = np.sort(faces, axis=1)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return np.unique(faces[cnt[inv.ravel()] == 1])


def build_anatomy(scan_mesh: Mesh, landmarks: Any = None, n_tets: int = 100_000, progress: bool = True) -> FaceAnatomy:
    """Build the soft-tissue model of a face scan (Sifakis et al. 2005, sec. 3).

    Parameters
    ----------
    scan_mesh : Mesh
        The neutral skin, mm, outward normals; a face region (open surface)
        or a head.
    landmarks : str, path-like, dict, AnatomyLandmarks or None, optional
        Landmark JSON (see :func:`~facecap.anatomy.read_landmarks`); None
        (default) for scans in the ICT-FaceKit topology, whose landmarks the
        package knows.
    n_tets : int, optional
        Approximate number of tetrahedra, default 100,000 (the count lands
        within about 30 %; about 5,000 is enough for tests).
    progress : bool, optional
        Show a tqdm progress bar over the stages, default True.

    Returns
    -------
    FaceAnatomy

    Raises
    ------
    InputError
        If the landmarks are missing or bad, the scan has no usable face
        region, or ``n_tets`` is below 100.

    Notes
    -----
    Stages: landmarks; the closed skin-bone surface
    (:func:`~facecap.anatomy.soft_tissue_shell`); fTetWild
    (:func:`~facecap.anatomy.tetrahedralize_shell`); Dirichlet nodes (the
    mesh's boundary nodes nearest the bone surface, split by the jaw cut of
    :func:`~facecap.anatomy.jaw_joint`); the skin embedding
    (:func:`~facecap.anatomy.embed_points`); the muscles
    (:func:`~facecap.anatomy.facial_muscles`). The seconds each took are in
    ``provenance['seconds']``.
    """
    if not isinstance(scan_mesh, Mesh):
        raise InputError(f"scan_mesh: expected a facecap Mesh, got {type(scan_mesh).__name__}")
    if int(n_tets) < 100:
        raise InputError(f"n_tets: expected at least 100 tetrahedra, got {n_tets}")
    seconds: dict[str, float] = {}
    bar = tqdm(total=6, desc="build anatomy", unit="stage", disable=not progress)

    def stage(name: str, t0: float) -> float:
        seconds[name] = round(time.perf_counter() - t0, 3)
        bar.update(1)
        bar.set_postfix_str(name)
        return time.perf_counter()

    try:
        t = time.perf_counter()
        lm = anatomy_landmarks(scan_mesh, landmarks)
        t = stage("landmarks", t)
        shell = soft_tissue_shell(scan_mesh, lm)
        t = stage("bone and closed surface", t)
        mesh = tetrahedralize_shell(shell.V, shell.F, n_tets=int(n_tets))
        X, T = mesh.X, mesh.T
        t = stage("tetrahedra", t)

        boundary = boundary_nodes(T)
        parts = np.unique(shell.part)
        dist = np.full((boundary.size, parts.max() + 1), np.inf)
        for p in parts:
            d2, _, _ = igl.point_mesh_squared_distance(X[boundary], shell.V, shell.F[shell.part == p])
            dist[:, p] = d2
        nearest = np.argmin(dist, axis=1)
        bone_nodes = boundary[nearest == PART_BONE]
        joint = jaw_joint(lm)
        # the bone along the cut holds to neither jaw (jaw_joint.JAW_GAP_MM)
        bone_nodes = bone_nodes[~in_jaw_gap(X[bone_nodes], joint)]
        jaw = is_mandible(X[bone_nodes], joint)
        t = stage("bone nodes", t)

        embedding = embed_points(X, T, scan_mesh.vertices)
        t = stage("skin embedding", t)

        S = scan_mesh.vertices[shell.skin_vertices]
        depth = np.maximum(np.einsum("ij,ij->i", S - shell.bone, shell.normals), 1.0)
        muscles = facial_muscles(X, T, lm, S, shell.normals, depth)
        t = stage("muscles", t)
    finally:
        bar.close()

    quality = tet_quality(X, T)
    meshed = np.zeros(scan_mesh.n_vertices, dtype=bool)
    meshed[shell.skin_vertices] = True
    try:
        tetwild_version = metadata.version("pytetwild")
    except metadata.PackageNotFoundError:  # pragma: no cover - it is a dependency
        tetwild_version = "unknown"
    provenance = {
        "scan": scan_mesh.source_path,
        "n_tets_requested": int(n_tets),
        "mesher": f"fTetWild (pytetwild {tetwild_version}, MPL-2.0), envelope {ENVELOPE_MM} mm",
        "meshed_surface_triangles": int(mesh.surface_F.shape[0]),
        "meshed_surface_volume_mm3": float(_closed_volume(mesh.surface_V, mesh.surface_F)),
        "shell_volume_mm3": float(_closed_volume(shell.V, shell.F)),
        "tissue_depths": TISSUE_DEPTH_SOURCE,
        "jaw_gap_mm": JAW_GAP_MM,  # models built before the band have none: their flesh is glued across the cut
        "landmarks": _landmark_source(landmarks),
        "quality": quality._asdict(),
        "seconds": seconds,
        "facecap": _facecap_version(),
    }
    return FaceAnatomy(
        nodes=X, tets=T,
        muscle_names=muscles.names, muscle_fractions=muscles.fractions, muscle_fibres=muscles.fibres,
        muscle_curves=muscles.curves, muscle_rings=muscles.rings, muscle_widths_mm=muscles.widths_mm,
        muscle_thicknesses_mm=muscles.thicknesses_mm,
        cranium_nodes=np.sort(bone_nodes[~jaw]).astype(np.int64),
        mandible_nodes=np.sort(bone_nodes[jaw]).astype(np.int64),
        rim_nodes=np.sort(boundary[nearest == PART_RIM]).astype(np.int64),
        skin_tets=embedding.tet, skin_weights=embedding.weights, skin_inside=embedding.inside, skin_meshed=meshed,
        condyles=joint.condyles,
        landmark_names=lm.names, landmark_vertices=lm.vertices, landmark_points=lm.points,
        scan_vertices=np.array(scan_mesh.vertices), scan_faces=np.array(scan_mesh.faces),
        scan_polygon_sizes=scan_mesh.polygon_sizes, scan_polygon_indices=scan_mesh.polygon_indices,
        scan_uvs=scan_mesh.uvs, scan_uv_indices=scan_mesh.uv_indices,
        bone_vertices=shell.bone, bone_faces=shell.skin_faces[:, ::-1].copy(),
        tissue_thickness_mm=depth,
        provenance=provenance,
    )


def _landmark_source(landmarks: Any) -> str:
    """A short description of where the landmarks came from, for the provenance."""
    if landmarks is None:
        return "ICT-FaceKit 68 landmarks (built in)"
    if isinstance(landmarks, AnatomyLandmarks):
        return "AnatomyLandmarks given by the caller"
    if isinstance(landmarks, dict):
        return "mapping given by the caller"
    return f"file {os.fspath(landmarks)}"


def _closed_volume(V: np.ndarray, F: np.ndarray) -> float:
    """Enclosed volume of a closed outward surface, mm^3 (divergence theorem)."""
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def _facecap_version() -> str:
    from .. import __version__

    return __version__

"""Write a generated case to disk as a user would hold it: scan, take, map, ground truth."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import NamedTuple, Sequence

import numpy as np

from ..io.atomic_write import atomic_path, atomic_write_text
from ..io.write_markers import write_markers
from ..io.ict_sample import load_ict_sample
from ..io.write_mesh import write_mesh
from ..units import mm_per_unit
from .generate_performance import SyntheticCase
from .capture_colors import capture_colors
from .scan_expression import scan_expression
from .skin_albedo import SkinRegions, skin_albedo
from .skin_texture import SkinTexture

__all__ = ["write_synthetic_case", "write_planned_scans", "correspondence_json", "CaseFiles"]


class CaseFiles(NamedTuple):
    """Paths of a written case."""

    scan: Path
    markers: Path
    map: Path
    truth: Path


def correspondence_json(correspondence: dict, scale: float = 1.0) -> str:
    """``map.json``'s text for a case's correspondence: vertex indices as they are, points (mm) times ``scale``.

    ``scale`` converts mm to the unit the scan is written in (points of a map are in the scan's unit).
    """
    entries = {label: int(where) if np.ndim(where) == 0 else [float(x) * scale for x in where]
               for label, where in correspondence.items()}
    return json.dumps(entries, indent=1)


def write_synthetic_case(
    case: SyntheticCase,
    folder: str | Path,
    *,
    scan_unit: str = "mm",
    marker_format: str = "c3d",
    region_labels: np.ndarray | None = None,
    region_names: list[str] | None = None,
    colors: bool = False,
    albedo_seed: int = 0,
    capture_seed: int = 0,
) -> CaseFiles:
    """Write ``scan.obj``, ``take.<fmt>``, ``map.json`` and ``truth.npz`` into ``folder``.

    Parameters
    ----------
    case : SyntheticCase
        From :func:`~facecap.synth.generate_performance.generate_performance`.
    folder : str or Path
        Created if needed.
    scan_unit : {'mm', 'cm', 'm', 'in'}, default 'mm'
        Unit to store the scan (and the truth) in, to exercise unit handling.
    marker_format : {'c3d', 'trc', 'csv'}, default 'c3d'
    region_labels : (n,) int array, optional
        Face region of each vertex, stored with the truth for per-region errors.
    region_names : list of str, optional
    colors : bool, default False
        Give the scan vertex colours, as a colour scanner would:
        ``capture_colors(skin_albedo(case.scan.vertices, seed=albedo_seed,
        region=...), case.scan.vertices, seed=capture_seed)`` (brows from
        ``region_labels``/``region_names`` when given). Default False: the
        files are what they were without this option.
    albedo_seed : int, default 0
        Seed of the skin; use the same in :func:`write_planned_scans`.
    capture_seed : int, default 0
        Seed of this capture's exposure, shading and sensor noise.

    Returns
    -------
    CaseFiles

    Notes
    -----
    ``truth.npz`` holds ``vertices`` (T, n, 3) float32 in ``units``,
    ``head_pose`` (T, 4, 4) (translation in ``units``), ``units``, ``rate``,
    and the region arrays when given; read it with
    :func:`facecap.report.evaluate_result.read_truth`.
    """
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    scale = 1.0 / mm_per_unit(scan_unit)
    scan_path = out / "scan.obj"
    scan_mesh = case.scan
    if colors:
        region = None
        if region_labels is not None and region_names is not None:
            region = SkinRegions(np.asarray(region_labels), tuple(region_names))
        albedo = skin_albedo(case.scan.vertices, seed=albedo_seed, region=region)
        scan_mesh = replace(case.scan, vertex_colors=capture_colors(
            albedo, case.scan.vertices, seed=capture_seed))
    write_mesh(scan_mesh, scan_path, unit=scan_unit)
    markers_path = out / f"take.{marker_format}"
    write_markers(case.markers, markers_path)
    map_path = out / "map.json"
    atomic_write_text(map_path, correspondence_json(case.correspondence, scale))
    truth_path = out / "truth.npz"
    pose = np.array(case.head_pose, dtype=np.float64)
    pose[:, :3, 3] *= scale
    arrays = {
        "vertices": (np.asarray(case.truth_vertices, dtype=np.float32) * np.float32(scale)),
        "head_pose": pose,
        "units": np.array(scan_unit),
        "rate": np.array(case.markers.rate),
    }
    if region_labels is not None:
        arrays["region_labels"] = np.asarray(region_labels)
        arrays["region_names"] = np.array(region_names or [])
    with atomic_path(truth_path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
    return CaseFiles(scan_path, markers_path, map_path, truth_path)


def write_planned_scans(
    case: SyntheticCase,
    frames: Sequence[int],
    folder: str | Path,
    *,
    target_vertices: int | None = None,
    first_seed: int = 0,
    file_format: str = "obj",
    colors: bool = False,
    albedo_seed: int = 0,
    skin_regions: SkinRegions | None = None,
    skin_texture: SkinTexture | None = None,
    reperformance: float = 0.0,
) -> list[Path]:
    """Scan the true expression of each planned frame and write it, as a scanning session of the plan would.

    Scan ``i`` is :func:`~facecap.synth.scan_expression.scan_expression` of
    ``case.truth_vertices[frames[i]]`` with seed ``first_seed + i`` (its own
    sampling, noise, holes and scanner frame), written to
    ``scan_{i:02d}_frame_{frame:04d}.{file_format}``, in the plan's order, as
    ``facecap register-scans --scans`` takes them.

    With ``colors=True`` each scan carries vertex colours (written as
    ``v x y z r g b`` in OBJ, ``uchar red, green, blue`` in PLY): the skin of
    :func:`~facecap.synth.skin_albedo.skin_albedo` (seed ``albedo_seed``,
    ``skin_regions`` labelled per vertex of ``case.scan``) at each scan
    vertex's material point on the rest surface ``case.scan.vertices``, as
    :func:`~facecap.synth.scan_expression.scan_expression` makes it with
    ``material_points``; each scan has its own exposure, shading and noise.
    Default False: the scans are what they were without this option.

    With ``skin_texture`` (the identity's albedo baked on ``case.scan`` by
    :func:`~facecap.synth.skin_texture.bake_skin_albedo`) each scan carries a colour texture
    instead, at 0.25 mm a texel in an atlas of its own (its range image), written beside it
    (``<name>_color.png``, and ``<name>.mtl`` for OBJ), as scanners deliver it.

    ``reperformance`` > 0 scans what an actor gives when asked to hold the frame's expression
    again, not the frame itself (Huang et al.'s premise, and the reason for their section 7): each
    blendshape weight ``w`` of the frame becomes ``w + reperformance * (w n1 + 0.1 n2)`` (``n1, n2``
    standard normal per shape and scan, from the scan's seed), clipped to [0, 1], added through the
    ICT expression shapes. 0 (default): the frame's own expression.

    Returns
    -------
    list of Path
    """
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, f in enumerate(frames):
        extra: dict = dict(material_points=case.scan.vertices, albedo_seed=albedo_seed,
                           skin_regions=skin_regions) if colors else {}
        if skin_texture is not None:
            extra = dict(skin_texture=skin_texture)
        expression = case.truth_vertices[int(f)].astype(np.float64)
        if reperformance > 0:
            rng = np.random.default_rng(np.random.SeedSequence([first_seed + i, 0x2E9F]))
            w = case.weights[int(f)]
            again = np.clip(w + reperformance * (w * rng.normal(size=w.shape) + 0.1 * rng.normal(size=w.shape)), 0, 1)
            expression = expression + np.tensordot(again - w, load_ict_sample().expression_deltas, axes=1)
        scanned = scan_expression(expression, case.scan.faces, seed=first_seed + i,
                                  target_vertices=target_vertices, **extra)
        paths.append(out / f"scan_{i:02d}_frame_{int(f):04d}.{file_format}")
        write_mesh(scanned.mesh, paths[-1])
    return paths

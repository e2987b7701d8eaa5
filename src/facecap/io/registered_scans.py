"""The bases folder ``facecap register-scans`` writes and ``facecap blend`` reads."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FileFormatError
from ..structures import ConditionedTake, Mesh
from .atomic_write import atomic_folder
from .conditioned_take import write_conditioned_take
from .read_mesh import read_mesh
from .write_mesh import write_mesh

__all__ = ["write_registered_scans", "read_registered_scans", "BASES_MARKER_FILE", "CONDITIONED_TAKE_FILE"]

BASES_MARKER_FILE = "bases.json"
CONDITIONED_TAKE_FILE = "conditioned_take.npz"
"""The plan's conditioned take, kept with the bases so ``blend`` sees the markers the bases were fitted to."""


def write_registered_scans(
    out_dir: str | Path,
    *,
    template: Mesh,
    bases: np.ndarray,
    basis_markers: np.ndarray,
    marker_labels: list[str],
    output_from_mocap: np.ndarray,
    plan: dict[str, Any],
    report: dict[str, Any],
    conditioned: ConditionedTake | None = None,
    rate: float | None = None,
    overwrite: bool = False,
) -> Path:
    """Write the registered bases folder atomically.

    Layout: ``template.obj`` (topology, UVs, in the template's unit),
    ``bases.npy`` (K, n, 3) float32 mm in the stabilised mocap frame,
    ``basis_markers.npy`` (K, M, 3) mm, ``output_from_mocap.npy`` (4, 4),
    ``bases.json`` (marker labels, template unit, the plan and its
    conditioning, the registration report) and, when given, the conditioned
    take (``conditioned_take.npz``, see :mod:`facecap.io.conditioned_take`;
    ``rate`` is then required). An earlier bases folder in ``out_dir`` is
    replaced only with ``overwrite`` (:func:`facecap.io.atomic_write.atomic_folder`).
    """
    with atomic_folder(out_dir, marker_file=BASES_MARKER_FILE, overwrite=overwrite) as stage:
        write_mesh(template, stage / "template.obj")
        np.save(stage / "bases.npy", np.asarray(bases, dtype=np.float32))
        np.save(stage / "basis_markers.npy", np.asarray(basis_markers, dtype=np.float64))
        np.save(stage / "output_from_mocap.npy", np.asarray(output_from_mocap, dtype=np.float64))
        info = {
            "format": "facecap-bases",
            "version": 1,
            "template_unit": template.source_unit,
            "marker_labels": list(marker_labels),
            "plan": plan,
            "report": report,
        }
        if conditioned is not None:
            conditioning = plan.get("conditioning", {})
            write_conditioned_take(stage / CONDITIONED_TAKE_FILE, conditioned, labels=list(marker_labels),
                                   rate=float(rate), settings=conditioning,
                                   source_sha256=conditioning.get("source_sha256"))
        (stage / BASES_MARKER_FILE).write_text(json.dumps(info, indent=1, default=float))
    return Path(out_dir)


def read_registered_scans(folder: str | Path) -> dict[str, Any]:
    """Read a bases folder; returns ``template`` (Mesh), arrays and the ``bases.json`` content.

    Raises
    ------
    FileFormatError
        If the folder is not a finished ``register-scans`` result.
    """
    p = Path(folder)
    info_path = p / BASES_MARKER_FILE
    if not info_path.is_file():
        raise FileFormatError("is not a facecap bases folder (no bases.json)", path=str(p))
    try:
        info = json.loads(info_path.read_text())
        bases = np.load(p / "bases.npy")
        basis_markers = np.load(p / "basis_markers.npy")
        output_from_mocap = np.load(p / "output_from_mocap.npy")
    except (OSError, ValueError, json.JSONDecodeError) as exc:
        raise FileFormatError(f"damaged bases folder ({exc})", path=str(p)) from None
    template = read_mesh(p / "template.obj", unit=info.get("template_unit", "mm"))
    if bases.shape[1] != template.n_vertices or basis_markers.shape[0] != bases.shape[0]:
        raise FileFormatError("bases.npy does not match template.obj or basis_markers.npy", path=str(p))
    return {
        "template": template,
        "bases": bases,
        "basis_markers": basis_markers,
        "output_from_mocap": output_from_mocap,
        "marker_labels": info["marker_labels"],
        "plan": info["plan"],
        "report": info.get("report", {}),
    }

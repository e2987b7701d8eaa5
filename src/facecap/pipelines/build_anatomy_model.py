"""``facecap build-anatomy``'s job: an anatomy model folder built inside a neutral scan (Sifakis et al. 2005, sec. 3).

The destination checked first (an earlier model is replaced only with ``overwrite``), the scan read, the
model built (:func:`~facecap.anatomy.build_anatomy`: bone, a tetrahedral soft-tissue mesh and the muscles),
and the folder written: ``anatomy.npz``, ``anatomy.json`` (the model, :meth:`FaceAnatomy.save`) and
``layout.png`` (:func:`~facecap.anatomy.render_anatomy_layout`), appearing together or not at all.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..anatomy import FaceAnatomy, build_anatomy, render_anatomy_layout
from ..io.atomic_write import atomic_folder, check_folder_destination
from ..io.read_mesh import read_mesh

__all__ = ["build_anatomy_model"]

_MODEL_FILE = "anatomy.json"  # what makes a folder a model, replaced only with overwrite


def build_anatomy_model(scan_path: str | Path, out_dir: str | Path, *, scan_unit: str = "mm", landmarks: Any = None,
                        n_tets: int = 100_000, progress: bool = True, overwrite: bool = False) -> FaceAnatomy:
    """Build the anatomy model of a neutral scan and write its folder.

    Parameters
    ----------
    scan_path : str or Path
        The neutral scan (a mesh file :func:`~facecap.io.read_mesh` reads).
    out_dir : str or Path
        The model folder to write.
    scan_unit : str, default 'mm'
        Length unit of the scan file.
    landmarks : str, path-like, dict or None, optional
        Landmarks, as :func:`~facecap.anatomy.build_anatomy` takes them; None for scans in the ICT
        topology.
    n_tets : int, default 100000
        Tetrahedra to aim for.
    progress : bool, default True
        Progress bars.
    overwrite : bool, default False
        Replace an earlier model in ``out_dir`` (else refused before the scan is read).

    Returns
    -------
    FaceAnatomy
        The model written.
    """
    check_folder_destination(out_dir, marker_file=_MODEL_FILE, overwrite=overwrite)  # before the build
    scan = read_mesh(scan_path, unit=scan_unit)
    anatomy = build_anatomy(scan, landmarks=landmarks, n_tets=n_tets, progress=progress)
    # the model and its picture appear together or not at all
    with atomic_folder(out_dir, marker_file=_MODEL_FILE, overwrite=overwrite) as stage:
        render_anatomy_layout(anatomy, Path(stage) / "layout.png")
        anatomy.save(stage)
    return anatomy

"""``facecap remove-wrinkles``' job: a neutral scan's wrinkles smoothed out in a region, written as a new scan.

The destination checked first (an existing file is replaced only with ``overwrite``), the scan and its
region read (:func:`~facecap.io.read_region_mask`), the wrinkles removed with the fine detail kept
(:func:`~facecap.wrinkles.remove_wrinkles`, Bickel et al. 2007, section 5.4), the scan written.
"""

from __future__ import annotations

from pathlib import Path

from ..io.atomic_write import check_file_destination
from ..io.read_mesh import read_mesh
from ..io.read_region_mask import read_region_mask
from ..io.write_mesh import write_mesh
from ..typing import BoolArray
from ..wrinkles import remove_wrinkles

__all__ = ["remove_scan_wrinkles"]


def remove_scan_wrinkles(scan_path: str | Path, region_path: str | Path, out_path: str | Path, *,
                         scan_unit: str = "mm", overwrite: bool = False) -> BoolArray:
    """Smooth the wrinkles out of a neutral scan in a region, keeping its fine detail, and write the scan.

    Parameters
    ----------
    scan_path : str or Path
        The neutral scan (a mesh file :func:`~facecap.io.read_mesh` reads).
    region_path : str or Path
        The wrinkle region: a JSON list of vertex indices or a ``.npy`` bool mask per vertex
        (:func:`~facecap.io.read_region_mask`).
    out_path : str or Path
        The scan without its wrinkles (``.obj`` or ``.ply``).
    scan_unit : str, default 'mm'
        Length unit of the scan file.
    overwrite : bool, default False
        Replace an existing ``out_path`` (else refused before anything is read).

    Returns
    -------
    (n,) bool array
        The region: True on the scan's vertices that were smoothed.
    """
    check_file_destination(out_path, overwrite=overwrite)
    scan = read_mesh(scan_path, unit=scan_unit)
    mask = read_region_mask(region_path, scan.n_vertices)
    write_mesh(remove_wrinkles(scan, mask), out_path)
    return mask

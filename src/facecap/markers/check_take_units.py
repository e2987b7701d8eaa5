""":func:`~facecap.markers.check_scan_units` for a scan, a take and the map between them (``facecap animate``)."""

from __future__ import annotations

from ..structures import Correspondence, MarkerSequence, Mesh
from ..units import MIN_SIZE_POINTS
from .check_scan_units import check_scan_units

__all__ = ["check_take_units"]


def check_take_units(
    scan: Mesh,
    markers: MarkerSequence,
    correspondence: Correspondence,
    *,
    rest_frame: int = 0,
    convert: bool = False,
    option: str = "--scan-units",
) -> Mesh:
    """:func:`check_scan_units` for a scan, a take and the map between them (paired, at the rest frame).

    Parameters
    ----------
    scan : Mesh
        The scan the map refers to.
    markers : MarkerSequence
        The take.
    correspondence : Correspondence
        Marker label -> scan point; markers in only one of map and take are left out.
    rest_frame : int, default 0
        Frame of the take whose expression matches the scan. Out of range:
        nothing is checked (the pipeline names the bad frame).
    convert, option
        As for :func:`check_scan_units`.

    Returns
    -------
    Mesh
        ``scan``, or with ``convert=True`` a copy in the likely unit.

    Raises
    ------
    MeshError
        As :func:`check_scan_units`.
    """
    if not isinstance(correspondence, Correspondence) or not isinstance(markers, MarkerSequence):
        return scan  # the pipeline's own validation names the bad argument
    if not (0 <= rest_frame < markers.n_frames):
        return scan
    column = {label: i for i, label in enumerate(markers.labels)}
    shared = [label for label in correspondence.labels if label in column]
    if len(shared) < MIN_SIZE_POINTS:
        return scan
    on_scan = correspondence.select(shared).points(scan.vertices)
    in_take = markers.positions[rest_frame, [column[label] for label in shared]]
    return check_scan_units(scan, in_take, scan_points=on_scan, convert=convert, option=option)

"""Whether a scan's length unit agrees with the markers' size, and the scan converted when asked.

Mesh files do not state a unit, so a scan stored in metres and read as mm (the
default) would animate 1000 times too small without a word.
:func:`check_scan_units` compares the scan's size with the markers' and stops
with an error naming the likely unit, or converts to it on request (what
``--scan-units auto`` does).
"""

from __future__ import annotations

import warnings
from dataclasses import replace
from typing import Any

import numpy as np

from ..errors import FacecapWarning, InputError, MeshError
from ..structures import Mesh
from ..units import LENGTH_UNITS_MM, MIN_SIZE_POINTS, UNIT_NAMES, mm_per_unit, normalize_unit, units_that_fit

__all__ = ["check_scan_units"]


# Accepted ratio of the scan's size to the markers' (both in mm as read), and the
# ratio expected. Paired: the same markers on the scan and in the take, so ~1;
# every unit factor (2.54 and up) falls outside. Unpaired: the whole scan against
# the marker cloud; a head scan is 1-4x the face's markers (1.3 on the bundled
# ICT face), a face-only scan a little smaller than markers with a head band.
# Factors of 10 and more fall outside; centimetres and inches (2.54x apart) can
# both fit, and then the one nearer the expected ratio is named, the other beside it.
_PAIRED_BAND = (0.67, 1.5, 1.0)
_UNPAIRED_BAND = (0.6, 4.0, 1.5)


def _finite_rows(X: np.ndarray) -> np.ndarray:
    return X[np.isfinite(X).all(axis=1)]


def _robust_span(X: np.ndarray) -> float:
    """Bounding-box diagonal of the points, ignoring strays beyond 3x the median distance to the median."""
    X = _finite_rows(X)
    if len(X) < MIN_SIZE_POINTS:
        return float("nan")
    d = np.linalg.norm(X - np.median(X, axis=0), axis=1)
    med = float(np.median(d))
    if med > 0:
        X = X[d <= 3.0 * med]
    return float(np.linalg.norm(X.max(axis=0) - X.min(axis=0)))


def _paired_ratio(A: np.ndarray, B: np.ndarray) -> float:
    """Median ratio of pairwise distances |A_i - A_j| / |B_i - B_j| (robust to a few wrong pairs)."""
    ok = np.isfinite(A).all(axis=1) & np.isfinite(B).all(axis=1)
    A, B = A[ok], B[ok]
    if len(A) < MIN_SIZE_POINTS:
        return float("nan")
    i, j = np.triu_indices(len(A), k=1)
    da, db = np.linalg.norm(A[i] - A[j], axis=1), np.linalg.norm(B[i] - B[j], axis=1)
    keep = db > 0
    return float(np.median(da[keep] / db[keep])) if keep.any() else float("nan")


def check_scan_units(
    scan: Mesh,
    marker_points: Any,
    *,
    scan_points: Any = None,
    convert: bool = False,
    option: str = "--scan-units",
) -> Mesh:
    """Check that a scan's unit agrees with the markers' size; convert it if asked.

    Compares a robust size of the scan with that of the markers: with
    ``scan_points``, the ratio of the markers' mutual distances on the scan to
    those in the take (the same markers, so about 1); otherwise the bounding-box
    diagonal of the whole scan to that of the marker cloud (1 to 3 for a head
    scan and face markers). Stray points (beyond 3 times the median distance to
    the median) and NaN gaps are ignored. When the ratio is off and another
    length unit in :data:`LENGTH_UNITS_MM` explains it, the scan's unit was
    given wrongly.

    Parameters
    ----------
    scan : Mesh
        The scan as read, vertices in mm according to ``scan.source_unit``.
    marker_points : (M, 3) float64 array, mm
        The markers at the frame the scan shows (NaN for gaps).
    scan_points : (M, 3) float64 array, mm, optional
        Where the same markers sit on the scan (row for row); gives the
        tighter, paired comparison.
    convert : bool, default False
        False: raise when another unit explains the sizes. True: return the
        scan re-read in that unit, with a notice.
    option : str, default '--scan-units'
        How the unit was given, for the message.

    Returns
    -------
    Mesh
        ``scan`` itself when the sizes agree (or cannot be compared: fewer
        than 3 markers); with ``convert=True``, a copy in the likely unit
        (``source_unit`` set to it, so exports keep the file's numbers).

    Raises
    ------
    MeshError
        With ``path`` set to the scan's file, naming the likely unit, when
        ``convert`` is False and another unit explains the sizes.

    Warns
    -----
    FacecapWarning
        When converting, and when the sizes disagree but no unit explains it.

    Examples
    --------
    >>> V = np.array([[0.0, 0, 0], [0.2, 0, 0], [0, 0.2, 0], [0, 0, 0.1]])  # a scan in metres
    >>> scan = Mesh(V, [[0, 1, 2], [0, 2, 3]], source_unit="mm", source_path="scan.obj")
    >>> markers = V * 1000 + 5.0
    >>> check_scan_units(scan, markers)
    Traceback (most recent call last):
    ...
    facecap.errors.MeshError: scan.obj: the scan is 0.3 across but the markers span 300 mm: it looks like metres; pass --scan-units m
    >>> import warnings
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore")
    ...     fixed = check_scan_units(scan, markers, convert=True)
    >>> fixed.source_unit, float(fixed.vertices.max())
    ('m', 200.0)
    """
    given = normalize_unit(scan.source_unit, name="scan.source_unit")
    markers = np.asarray(marker_points, dtype=np.float64).reshape(-1, 3)
    marker_mm = _robust_span(markers)
    if scan_points is not None:
        on_scan = np.asarray(scan_points, dtype=np.float64).reshape(-1, 3)
        if on_scan.shape != markers.shape:
            raise InputError(f"scan_points: expected shape {markers.shape}, got {on_scan.shape}")
        ratio = _paired_ratio(on_scan, markers)
        ok = np.isfinite(on_scan).all(axis=1) & np.isfinite(markers).all(axis=1)
        scan_mm, marker_mm = _robust_span(on_scan[ok]), _robust_span(markers[ok])
        low, high, centre = _PAIRED_BAND
    else:
        scan_mm = _robust_span(scan.vertices)
        ratio = scan_mm / marker_mm if marker_mm > 0 else float("nan")
        low, high, centre = _UNPAIRED_BAND
    if not np.isfinite(ratio) or ratio <= 0 or low <= ratio <= high:
        return scan

    scale = {u: mm_per_unit(u) / mm_per_unit(given) for u in LENGTH_UNITS_MM if u != given}
    likely = units_that_fit(ratio, scale, low, high, centre)
    in_file = scan_mm / mm_per_unit(given)
    if scan_points is not None:
        sizes = f"the mapped markers span {in_file:.3g} on the scan but {marker_mm:.3g} mm in the take"
    else:
        sizes = f"the scan is {in_file:.3g} across but the markers span {marker_mm:.3g} mm"
    if not likely:
        warnings.warn(
            f"{scan.source_path or 'scan'}: {sizes} ({ratio:.3g} times as large read as {given}), "
            f"which no length unit explains; check {option} and the take's unit",
            FacecapWarning, stacklevel=2,
        )
        return scan
    unit = likely[0]
    other = f" (or {UNIT_NAMES[likely[1]]}, {option} {likely[1]})" if len(likely) > 1 else ""
    if not convert:
        raise MeshError(f"{sizes}: it looks like {UNIT_NAMES[unit]}{other}; pass {option} {unit}",
                        path=scan.source_path)
    warnings.warn(
        f"{scan.source_path or 'scan'}: {sizes}: read as {UNIT_NAMES[unit]}{other}", FacecapWarning, stacklevel=2
    )
    return replace(scan, vertices=scan.vertices * scale[unit], source_unit=unit)

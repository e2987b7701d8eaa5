"""Length units: facecap works in millimetres inside and converts at the boundary.

Mesh files do not state a unit, so a scan stored in metres and read as mm (the
default) would animate 1000 times too small without a word.
:func:`check_scan_units` compares the scan's size with the markers' and stops
with an error naming the likely unit, or converts to it on request (what
``--scan-units auto`` does); :func:`check_take_units` is the same check for a
scan, a take and the map between them (``facecap animate``).
"""

from __future__ import annotations

import warnings
from dataclasses import replace
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from .errors import FacecapWarning, InputError, MeshError

if TYPE_CHECKING:  # structures imports this module
    from .io.read_correspondence import Correspondence
    from .structures import MarkerSequence, Mesh

__all__ = [
    "LENGTH_UNITS_MM", "normalize_unit", "mm_per_unit", "check_scan_units", "check_take_units",
    "FACE_SIZE_MM", "FACE_MARKERS_SIZE_MM", "FaceSize", "check_face_size",
]

LENGTH_UNITS_MM: dict[str, float] = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}
"""Millimetres per unit for the length units facecap reads and writes."""

_ALIASES = {
    "mm": "mm", "millimeter": "mm", "millimeters": "mm", "millimetre": "mm", "millimetres": "mm",
    "cm": "cm", "centimeter": "cm", "centimeters": "cm", "centimetre": "cm", "centimetres": "cm",
    "m": "m", "meter": "m", "meters": "m", "metre": "m", "metres": "m",
    "in": "in", "inch": "in", "inches": "in",
}


def normalize_unit(unit: str, *, name: str = "unit") -> str:
    """Return the canonical short name (``'mm'``, ``'cm'``, ``'m'``, ``'in'``) of a length unit.

    Raises
    ------
    InputError
        If the unit is not a length unit facecap knows.

    Examples
    --------
    >>> normalize_unit("Millimeters")
    'mm'
    """
    key = str(unit).strip().lower()
    if key not in _ALIASES:
        raise InputError(
            f"{name}: expected one of {sorted(LENGTH_UNITS_MM)}, got {unit!r}"
        )
    return _ALIASES[key]


def mm_per_unit(unit: str) -> float:
    """Millimetres in one ``unit``.

    Examples
    --------
    >>> mm_per_unit("cm")
    10.0
    """
    return LENGTH_UNITS_MM[normalize_unit(unit)]


UNIT_NAMES = {"mm": "millimetres", "cm": "centimetres", "m": "metres", "in": "inches"}

# Accepted ratio of the scan's size to the markers' (both in mm as read), and the
# ratio expected. Paired: the same markers on the scan and in the take, so ~1;
# every unit factor (2.54 and up) falls outside. Unpaired: the whole scan against
# the marker cloud; a head scan is 1-4x the face's markers (1.3 on the bundled
# ICT face), a face-only scan a little smaller than markers with a head band.
# Factors of 10 and more fall outside; centimetres and inches (2.54x apart) can
# both fit, and then the one nearer the expected ratio is named, the other beside it.
_PAIRED_BAND = (0.67, 1.5, 1.0)
_UNPAIRED_BAND = (0.6, 4.0, 1.5)
_MIN_POINTS = 3


def _finite_rows(X: np.ndarray) -> np.ndarray:
    return X[np.isfinite(X).all(axis=1)]


def _robust_span(X: np.ndarray) -> float:
    """Bounding-box diagonal of the points, ignoring strays beyond 3x the median distance to the median."""
    X = _finite_rows(X)
    if len(X) < _MIN_POINTS:
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
    if len(A) < _MIN_POINTS:
        return float("nan")
    i, j = np.triu_indices(len(A), k=1)
    da, db = np.linalg.norm(A[i] - A[j], axis=1), np.linalg.norm(B[i] - B[j], axis=1)
    keep = db > 0
    return float(np.median(da[keep] / db[keep])) if keep.any() else float("nan")


def _units_that_fit(value: float, scale: dict[str, float], low: float, high: float, centre: float) -> list[str]:
    """The units ``u`` with ``low <= value * scale[u] <= high``, the one nearest ``centre`` (in ratio) first."""
    return sorted((u for u in scale if low <= value * scale[u] <= high),
                  key=lambda u: abs(np.log(value * scale[u] / centre)))


def check_scan_units(
    scan: "Mesh",
    marker_points: Any,
    *,
    scan_points: Any = None,
    convert: bool = False,
    option: str = "--scan-units",
) -> "Mesh":
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
    >>> from facecap import Mesh
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
    likely = _units_that_fit(ratio, scale, low, high, centre)
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


def check_take_units(
    scan: "Mesh",
    markers: "MarkerSequence",
    correspondence: "Correspondence",
    *,
    rest_frame: int = 0,
    convert: bool = False,
    option: str = "--scan-units",
) -> "Mesh":
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
    from .io.read_correspondence import Correspondence
    from .structures import MarkerSequence

    if not isinstance(correspondence, Correspondence) or not isinstance(markers, MarkerSequence):
        return scan  # the pipeline's own validation names the bad argument
    if not (0 <= rest_frame < markers.n_frames):
        return scan
    column = {label: i for i, label in enumerate(markers.labels)}
    shared = [label for label in correspondence.labels if label in column]
    if len(shared) < _MIN_POINTS:
        return scan
    on_scan = correspondence.select(shared).points(scan.vertices)
    in_take = markers.positions[rest_frame, [column[label] for label in shared]]
    return check_scan_units(scan, in_take, scan_points=on_scan, convert=convert, option=option)


FACE_SIZE_MM: tuple[float, float] = (120.0, 300.0)
"""Sizes of a face or head scan, mm, as :func:`check_face_size` measures them (the
middle one of the three sides of its bounding box): about 120 for a face alone to
300 for a large head with its neck. The ICT head measures 248, facecap's synthetic
face scan 184."""

FACE_MARKERS_SIZE_MM: tuple[float, float] = (60.0, 300.0)
"""The same measure for the markers of a facial take in one frame, mm (the bundled
real take 134, a synthetic take 157); a body take measures 500 and more."""


class FaceSize(NamedTuple):
    """What :func:`check_face_size` found.

    Attributes
    ----------
    across_mm : float
        The measure as read: the middle side of the bounding box, mm (NaN with
        fewer than 3 finite points).
    unit : str
        The unit the file was read in.
    expected_mm : (float, float)
        The sizes a face has in this measure, mm.
    across_as_mm : dict of str to float
        The measure, mm, had the file been read in each unit of
        :data:`LENGTH_UNITS_MM` (``across_as_mm[unit] == across_mm``).
    likely_units : tuple of str
        When the size as read is no face's, the units that make it one, the
        one nearest the middle of ``expected_mm`` first; empty otherwise, and
        when no unit does.
    """

    across_mm: float
    unit: str
    expected_mm: tuple[float, float]
    across_as_mm: dict[str, float]
    likely_units: tuple[str, ...]

    @property
    def fits(self) -> bool:
        """True when the size as read is a face's, or cannot be measured."""
        low, high = self.expected_mm
        return not np.isfinite(self.across_mm) or low <= self.across_mm <= high

    def note(self, what: str = "the mesh", option: str = "--units") -> str | None:
        """One line saying the size is no face's, which unit makes it one and how to pass it; None if it fits.

        Examples
        --------
        >>> V = np.array([[0.0, 0, 0], [24.8, 33.8, 22.3], [12.0, 5.0, 3.0]])  # a head in cm, read as mm
        >>> print(check_face_size(V, unit="mm").note())
        the mesh: 24.8 mm across read as millimetres, smaller than a face (120-300 mm); as centimetres it is \
248 mm, a face's size: pass --units cm (as metres 24,800 mm, as inches 630 mm)
        """
        if self.fits:
            return None
        low, high = self.expected_mm
        size = "smaller" if self.across_mm < low else "larger"
        line = (f"{what}: {_figure(self.across_mm)} mm across read as {UNIT_NAMES[self.unit]}, {size} than a face "
                f"({low:g}-{high:g} mm)")
        others = ", ".join(f"as {UNIT_NAMES[u]} {_figure(self.across_as_mm[u])} mm"
                           for u in self.across_as_mm if u != self.unit and u not in self.likely_units[:1])
        if not self.likely_units:
            return f"{line}, and no length unit makes it one ({others})"
        unit = self.likely_units[0]
        return (f"{line}; as {UNIT_NAMES[unit]} it is {_figure(self.across_as_mm[unit])} mm, a face's size: "
                f"pass {option} {unit} ({others})")


def _figure(x: float) -> str:
    """Three significant figures, thousands separated: 24.8, 248, 24,800, 0.248."""
    if not np.isfinite(x):
        return "nan"
    if abs(x) >= 100:
        return f"{float(f'{x:.3g}'):,.0f}"
    return f"{x:.3g}"


def check_face_size(points: Any, *, unit: str = "mm", expected_mm: tuple[float, float] = FACE_SIZE_MM) -> FaceSize:
    """Whether points read in ``unit`` have the size of a face, and if not, which length unit gives them one.

    Mesh files state no unit, and a take may state a wrong one; a head stored in
    centimetres and read as mm is 10 times too small. The size measured is the
    middle one of the three sides of the points' bounding box (the width of a
    face, whose height may include a neck, and whose depth a face-only scan
    lacks); for a take, each side is the median over frames of that frame's
    side, so that head motion does not count.

    Parameters
    ----------
    points : (n, 3) or (T, M, 3) float64 array, mm
        Vertices of a mesh, or a take's marker positions (NaN for gaps), in mm
        as read in ``unit``.
    unit : {'mm', 'cm', 'm', 'in'}, default 'mm'
        The unit the file was read in.
    expected_mm : (float, float), default :data:`FACE_SIZE_MM`
        The sizes a face has in this measure, mm; :data:`FACE_MARKERS_SIZE_MM`
        for a facial take's markers.

    Returns
    -------
    FaceSize
        The size, the size in each unit and the units that make it a face's.

    Raises
    ------
    InputError
        If ``unit`` is not a length unit facecap knows.

    Examples
    --------
    >>> V = np.array([[0.0, 0, 0], [0.25, 0.34, 0.22], [0.1, 0.1, 0.1]])  # a head in metres, read as mm
    >>> found = check_face_size(V)
    >>> found.fits, found.likely_units, round(found.across_as_mm["m"])
    (False, ('m',), 250)
    """
    given = normalize_unit(unit)
    X = np.asarray(points, dtype=np.float64)
    frames = X.reshape(1, -1, 3) if X.ndim == 2 else X.reshape(X.shape[0], -1, 3)
    seen = np.isfinite(frames).all(axis=2)
    across = float("nan")
    counted = seen.sum(axis=1) >= _MIN_POINTS
    if counted.any():
        box = np.where(seen[counted][..., None], frames[counted], np.nan)
        sides = np.median(np.nanmax(box, axis=1) - np.nanmin(box, axis=1), axis=0)
        across = float(np.sort(sides)[1])
    scale = {u: mm_per_unit(u) / mm_per_unit(given) for u in LENGTH_UNITS_MM}
    low, high = float(expected_mm[0]), float(expected_mm[1])
    fits = not np.isfinite(across) or low <= across <= high
    likely = () if fits else tuple(_units_that_fit(across, scale, low, high, float(np.sqrt(low * high))))
    return FaceSize(across, given, (low, high), {u: across * s for u, s in scale.items()}, likely)

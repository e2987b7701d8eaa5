"""Length units: facecap works in millimetres inside and converts at the boundary.

Mesh files do not state a unit, so a scan stored in metres and read as mm (the
default) would animate 1000 times too small without a word.
:func:`check_face_size` says whether points have a face's size and which unit
gives them one; the checks of a scan against a take's markers, which know the
records, are :func:`facecap.markers.check_scan_units` and
:func:`facecap.markers.check_take_units`.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from .errors import InputError

__all__ = [
    "LENGTH_UNITS_MM", "UNIT_NAMES", "normalize_unit", "mm_per_unit", "units_that_fit", "MIN_SIZE_POINTS",
    "FACE_SIZE_MM", "FACE_MARKERS_SIZE_MM", "FaceSize", "check_face_size", "three_figures",
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

MIN_SIZE_POINTS = 3
"""Fewest finite points a size is measured from (fewer: NaN, nothing is checked)."""


def units_that_fit(value: float, scale: dict[str, float], low: float, high: float, centre: float) -> list[str]:
    """The units ``u`` with ``low <= value * scale[u] <= high``, the one nearest ``centre`` (in ratio) first."""
    return sorted((u for u in scale if low <= value * scale[u] <= high),
                  key=lambda u: abs(np.log(value * scale[u] / centre)))


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
        line = (f"{what}: {three_figures(self.across_mm)} mm across read as {UNIT_NAMES[self.unit]}, "
                f"{size} than a face "
                f"({low:g}-{high:g} mm)")
        others = ", ".join(f"as {UNIT_NAMES[u]} {three_figures(self.across_as_mm[u])} mm"
                           for u in self.across_as_mm if u != self.unit and u not in self.likely_units[:1])
        if not self.likely_units:
            return f"{line}, and no length unit makes it one ({others})"
        unit = self.likely_units[0]
        return (f"{line}; as {UNIT_NAMES[unit]} it is {three_figures(self.across_as_mm[unit])} mm, a face's size: "
                f"pass {option} {unit} ({others})")


def three_figures(x: float) -> str:
    """Three significant figures, thousands separated: 24.8, 248, 24,800, 0.248 (how the size checks write lengths).

    Examples
    --------
    >>> three_figures(24813.0), three_figures(0.24813)
    ('24,800', '0.248')
    """
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
    counted = seen.sum(axis=1) >= MIN_SIZE_POINTS
    if counted.any():
        box = np.where(seen[counted][..., None], frames[counted], np.nan)
        sides = np.median(np.nanmax(box, axis=1) - np.nanmin(box, axis=1), axis=0)
        across = float(np.sort(sides)[1])
    scale = {u: mm_per_unit(u) / mm_per_unit(given) for u in LENGTH_UNITS_MM}
    low, high = float(expected_mm[0]), float(expected_mm[1])
    fits = not np.isfinite(across) or low <= across <= high
    likely = () if fits else tuple(units_that_fit(across, scale, low, high, float(np.sqrt(low * high))))
    return FaceSize(across, given, (low, high), {u: across * s for u, s in scale.items()}, likely)

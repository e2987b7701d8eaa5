"""Length units: facecap works in millimetres inside and converts at the boundary."""

from __future__ import annotations

from .errors import InputError

__all__ = ["LENGTH_UNITS_MM", "normalize_unit", "mm_per_unit"]

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

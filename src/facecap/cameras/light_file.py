"""``lights.json``: the calibrated lights of a capture stage, in the cameras' world frame (the mocap frame).

Schema (``docs/cameras.md``, "Lights", has a full example)::

    {
      "units": "mm",                  # length unit of every position ("mm", "cm", "m", "in")
      "lights": [
        {"type": "point", "position": [x, y, z], "intensity": 1.0},
        {"type": "spot", "position": [x, y, z], "direction": [dx, dy, dz],
         "cone_deg": 25, "penumbra_deg": 5, "intensity": 2.0},
        {"type": "directional", "direction": [dx, dy, dz], "intensity": 0.3}
      ],
      "ambient": 0.05                 # irradiance from everywhere (the room), relative like the intensities
    }

``direction`` is the way the light travels (from the lamp toward the face);
intensities are relative: :class:`~facecap.cameras.Light` says what 1 means.
A ``"format": "facecap-lights"`` key and ``"version": 1`` are written and
accepted, not required: a file typed by hand from the issue's example reads.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FileFormatError, InputError
from ..io.atomic_write import atomic_write_text
from ..units import mm_per_unit, normalize_unit
from .light import LIGHT_KINDS, Light

__all__ = ["LightSetup", "LIGHT_FILE_FORMAT", "read_light_file", "write_light_file"]

LIGHT_FILE_FORMAT = "facecap-lights"
"""The ``format`` value written into ``lights.json``."""

_VERSION = 1
_KEYS = {"type", "name", "position", "direction", "intensity", "cone_deg", "penumbra_deg"}


@dataclass(frozen=True, eq=False)
class LightSetup:
    """The lights of a stage and its ambient light.

    Parameters
    ----------
    lights : sequence of Light
        At least one.
    ambient : float, default 0
        Irradiance arriving equally from every direction (the room), relative
        like the lights' intensities; >= 0.
    source_unit : {'mm', 'cm', 'm', 'in'}, default 'mm'
        The unit of the positions in the file this came from (the lights are in mm).
    """

    lights: tuple[Light, ...]
    ambient: float = 0.0
    source_unit: str = "mm"

    def __post_init__(self) -> None:
        lights = tuple(self.lights)
        if not lights or not all(isinstance(light, Light) for light in lights):
            raise InputError("lights: expected at least one light")
        object.__setattr__(self, "lights", lights)
        try:
            ambient = float(self.ambient)
        except (TypeError, ValueError):
            raise InputError(f"ambient: expected a number >= 0, got {self.ambient!r}") from None
        if not math.isfinite(ambient) or ambient < 0:
            raise InputError(f"ambient: expected a finite number >= 0, got {self.ambient!r}")
        object.__setattr__(self, "ambient", ambient)
        object.__setattr__(self, "source_unit", normalize_unit(self.source_unit, name="units"))

    def describe(self) -> dict[str, Any]:
        """The setup as ``lights.json`` holds it, in mm."""
        return {"format": LIGHT_FILE_FORMAT, "version": _VERSION, "units": "mm",
                "lights": [light.describe() for light in self.lights], "ambient": self.ambient}

    def moved(self, offsets_mm: Sequence[Any], intensity_scales: Sequence[float]) -> "LightSetup":
        """Every light displaced and rescaled (:meth:`Light.moved`), one offset and scale per light."""
        if len(offsets_mm) != len(self.lights) or len(intensity_scales) != len(self.lights):
            raise InputError(f"expected one offset and one scale per light ({len(self.lights)})")
        return LightSetup(tuple(light.moved(offset_mm=o, intensity_scale=s)
                                for light, o, s in zip(self.lights, offsets_mm, intensity_scales)),
                          self.ambient, self.source_unit)


def write_light_file(path: str | os.PathLike[str], setup: LightSetup) -> None:
    """Write ``lights.json`` (mm, atomically: a reader never sees half a file)."""
    if not isinstance(setup, LightSetup):
        raise InputError(f"setup: expected a LightSetup, got {type(setup).__name__}")
    atomic_write_text(path, json.dumps(setup.describe(), indent=2) + "\n")


def _light(entry: Any, where: str, mm: float) -> Light:
    if not isinstance(entry, dict):
        raise InputError(f"{where}: expected an object with \"type\"")
    unknown = sorted(set(entry) - _KEYS)
    if unknown:
        raise InputError(f"{where}: unknown keys {unknown} (known: {sorted(_KEYS)})")
    kind = entry.get("type")
    if kind not in LIGHT_KINDS:
        raise InputError(f"{where}.type: expected one of {list(LIGHT_KINDS)}, got {kind!r}")
    position = entry.get("position")
    if position is not None:
        try:
            position = np.asarray(position, dtype=np.float64) * mm
        except (TypeError, ValueError):
            raise InputError(f"{where}.position: expected three numbers, got {entry['position']!r}") from None
    try:
        return Light(kind, entry.get("intensity", 1.0), position, entry.get("direction"), entry.get("cone_deg"),
                     entry.get("penumbra_deg", 5.0), entry.get("name", ""))
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


def read_light_file(path: str | os.PathLike[str]) -> LightSetup:
    """Read ``lights.json`` (see the module notes for the schema).

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    LightSetup
        Positions in mm, ``source_unit`` the file's unit.

    Raises
    ------
    FileFormatError
        The file is missing or not JSON, has no ``"units"`` or ``"lights"``, or a
        light is malformed (a missing position, a zero direction, a spot without
        its cone, an unknown key); the message names the file and the light.
    """
    file = Path(path)
    if not file.is_file():
        raise FileFormatError("lights file not found", path=str(file))
    try:
        document = json.loads(file.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise FileFormatError(f"not a JSON file ({exc})", path=str(file)) from None
    try:
        if not isinstance(document, dict):
            raise InputError("expected a JSON object with \"units\", \"lights\" and \"ambient\"")
        if "format" in document and document["format"] != LIGHT_FILE_FORMAT:
            raise InputError(f"format {document['format']!r}: not a lights file ({LIGHT_FILE_FORMAT!r})")
        version = document.get("version", _VERSION)
        if not isinstance(version, int) or not 1 <= version <= _VERSION:
            raise InputError(f"version {version!r}; this facecap reads version {_VERSION}")
        if "units" not in document:
            raise InputError("no \"units\" (the length unit of the positions: \"mm\", \"cm\", \"m\" or \"in\")")
        unit = normalize_unit(document["units"], name="units")
        entries = document.get("lights")
        if not isinstance(entries, list) or not entries:
            raise InputError("\"lights\": expected a non-empty list")
        mm = mm_per_unit(unit)
        lights = tuple(_light(entry, f"lights[{i}]", mm) for i, entry in enumerate(entries))
        return LightSetup(lights, document.get("ambient", 0.0), unit)
    except InputError as exc:
        raise FileFormatError(str(exc), path=str(file)) from None

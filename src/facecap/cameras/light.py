"""A calibrated light of the capture stage: where its light comes from and how much reaches each point.

Three kinds, as ``lights.json`` names them (``light_file.py``), all in the
mocap frame (the cameras' world frame), millimetres:

- ``'point'``: a bulb at ``position``; irradiance falls with the inverse square
  of the distance.
- ``'spot'``: a point light that shines into a cone about ``direction`` (the
  way its light travels): full inside ``cone_deg - penumbra_deg`` of the axis,
  smoothly (smoothstep in the angle) down to nothing at ``cone_deg``.
- ``'directional'``: the sun, or a light so far away that its direction
  (``direction``, the way the light travels) is the same everywhere; no falloff.

``intensity`` is relative: the irradiance a surface facing the light receives
at :data:`REFERENCE_DISTANCE_MM` (one metre) from a point or spot light, or
anywhere from a directional one. So ``I (1000 / d)^2`` at distance ``d`` mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError
from ..typing import FloatArray

__all__ = ["Light", "LIGHT_KINDS", "REFERENCE_DISTANCE_MM"]

LIGHT_KINDS = ("point", "spot", "directional")
"""The kinds of light ``lights.json`` describes."""

REFERENCE_DISTANCE_MM = 1000.0
"""Distance at which a point or spot light's ``intensity`` is its irradiance (mm)."""

DEFAULT_PENUMBRA_DEG = 5.0
"""Width of a spot's soft edge, degrees: a theatre spot's beam softens over a few degrees."""


def _vector(value: Any, name: str) -> FloatArray:
    try:
        v = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected three numbers, got {value!r}") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise InputError(f"{name}: expected three finite numbers, got {value!r}")
    return v


@dataclass(frozen=True, eq=False)
class Light:
    """One light, in the mocap frame, millimetres.

    Parameters
    ----------
    kind : {'point', 'spot', 'directional'}
    intensity : float, default 1
        Relative (see the module notes); >= 0.
    position : (3,) array, mm
        Point and spot lights.
    direction : (3,) array
        Spot (its axis) and directional lights: the way the light travels
        (normalised here).
    cone_deg : float, optional
        Spot: the half-angle of the cone, in (0, 90].
    penumbra_deg : float, default 5
        Spot: the soft edge, in [0, cone_deg].
    name : str, optional

    Raises
    ------
    InputError
        A kind not in :data:`LIGHT_KINDS`, a missing or non-finite position or
        direction, a zero direction, a negative intensity, a cone out of range.

    Examples
    --------
    >>> light = Light("point", intensity=1.0, position=[0.0, 0.0, 1000.0])
    >>> to_light, irradiance = light.arriving([[0.0, 0.0, 0.0], [0.0, 0.0, 500.0]])
    >>> to_light.tolist(), irradiance.tolist()
    ([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]], [1.0, 4.0])
    """

    kind: str
    intensity: float = 1.0
    position: Any = None
    direction: Any = None
    cone_deg: float | None = None
    penumbra_deg: float = DEFAULT_PENUMBRA_DEG
    name: str = ""

    def __post_init__(self) -> None:
        if self.kind not in LIGHT_KINDS:
            raise InputError(f"type: expected one of {list(LIGHT_KINDS)}, got {self.kind!r}")
        try:
            intensity = float(self.intensity)
        except (TypeError, ValueError):
            raise InputError(f"intensity: expected a number, got {self.intensity!r}") from None
        if not math.isfinite(intensity) or intensity < 0:
            raise InputError(f"intensity: expected a finite number >= 0, got {self.intensity!r}")
        object.__setattr__(self, "intensity", intensity)
        if self.kind in ("point", "spot"):
            if self.position is None:
                raise InputError(f"a {self.kind} light needs a position (mm)")
            object.__setattr__(self, "position", _vector(self.position, "position"))
        else:
            object.__setattr__(self, "position", None)
        if self.kind in ("spot", "directional"):
            if self.direction is None:
                raise InputError(f"a {self.kind} light needs a direction (the way its light travels)")
            d = _vector(self.direction, "direction")
            length = float(np.linalg.norm(d))
            if length < 1e-12:
                raise InputError("direction: expected a non-zero vector")
            object.__setattr__(self, "direction", d / length)
        else:
            object.__setattr__(self, "direction", None)
        if self.kind == "spot":
            try:
                cone = float(self.cone_deg)  # type: ignore[arg-type]
                penumbra = float(self.penumbra_deg)
            except (TypeError, ValueError):
                raise InputError(f"a spot light needs cone_deg (degrees), got {self.cone_deg!r}") from None
            if not 0 < cone <= 90:
                raise InputError(f"cone_deg: expected a half-angle in (0, 90] degrees, got {self.cone_deg!r}")
            if not 0 <= penumbra <= cone:
                raise InputError(f"penumbra_deg: expected a value in [0, cone_deg = {cone:g}], got {penumbra!r}")
            object.__setattr__(self, "cone_deg", cone)
            object.__setattr__(self, "penumbra_deg", penumbra)
        else:
            object.__setattr__(self, "cone_deg", None)
        object.__setattr__(self, "name", str(self.name))

    def arriving(self, points: Any) -> tuple[FloatArray, FloatArray]:
        """The unit direction toward the light and the irradiance on a surface facing it, at each point.

        Parameters
        ----------
        points : (..., 3) array, mm

        Returns
        -------
        to_light : (..., 3) float64 array
            Unit vectors from each point toward the light.
        irradiance : (...) float64 array
            ``intensity (1000 / d)^2 * cone`` for point and spot lights (``cone``
            the spot's smooth profile, 1 for a point light), ``intensity`` for a
            directional one. Shadows are not included
            (:meth:`facecap.cameras.RayCaster.lit`); the cosine with the normal neither.
        """
        X = np.asarray(points, dtype=np.float64)
        if X.shape[-1:] != (3,):
            raise InputError(f"points: expected (..., 3), got shape {X.shape}")
        if self.kind == "directional":
            to_light = np.broadcast_to(-self.direction, X.shape).copy()
            return to_light, np.full(X.shape[:-1], self.intensity)
        offset = self.position - X
        distance = np.linalg.norm(offset, axis=-1)
        safe = np.maximum(distance, 1e-9)
        to_light = offset / safe[..., None]
        irradiance = self.intensity * (REFERENCE_DISTANCE_MM / safe) ** 2
        if self.kind == "spot":
            irradiance = irradiance * self.cone_profile(-to_light)
        return to_light, irradiance

    def cone_profile(self, outgoing: Any) -> FloatArray:
        """A spot's relative intensity along unit directions leaving it: 1 inside the cone, 0 outside.

        The angle to the axis is mapped by a smoothstep from 1 at
        ``cone_deg - penumbra_deg`` to 0 at ``cone_deg``; 1 everywhere for other kinds.
        """
        D = np.asarray(outgoing, dtype=np.float64)
        if self.kind != "spot":
            return np.ones(D.shape[:-1])
        angle = np.degrees(np.arccos(np.clip(D @ self.direction, -1.0, 1.0)))
        inner = self.cone_deg - self.penumbra_deg
        if self.penumbra_deg <= 0:
            return (angle <= self.cone_deg).astype(np.float64)
        s = np.clip((self.cone_deg - angle) / self.penumbra_deg, 0.0, 1.0)
        return np.where(angle <= inner, 1.0, s * s * (3.0 - 2.0 * s))

    def distance_to(self, points: Any) -> FloatArray:
        """(...) distance from each point to the light, mm (inf for a directional light)."""
        X = np.asarray(points, dtype=np.float64)
        if self.kind == "directional":
            return np.full(X.shape[:-1], np.inf)
        return np.linalg.norm(self.position - X, axis=-1)

    def moved(self, *, offset_mm: Any = (0.0, 0.0, 0.0), intensity_scale: float = 1.0) -> "Light":
        """The same light displaced by ``offset_mm`` and scaled in intensity (a calibration error, for tests)."""
        position = None if self.position is None else self.position + _vector(offset_mm, "offset_mm")
        return Light(self.kind, self.intensity * float(intensity_scale), position, self.direction, self.cone_deg,
                     self.penumbra_deg, self.name)

    def describe(self) -> dict[str, Any]:
        """The light as its ``lights.json`` entry (mm)."""
        entry: dict[str, Any] = {"type": self.kind, "intensity": self.intensity}
        if self.name:
            entry["name"] = self.name
        if self.position is not None:
            entry["position"] = self.position.tolist()
        if self.direction is not None:
            entry["direction"] = self.direction.tolist()
        if self.kind == "spot":
            entry["cone_deg"] = self.cone_deg
            entry["penumbra_deg"] = self.penumbra_deg
        return entry

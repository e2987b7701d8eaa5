"""The lights of the detail footage's stage: a spotlight key to one side and above the face, a weak fill, a little ambient."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InputError
from ..typing import FloatArray

__all__ = ["studio_lights", "LIGHTING_STYLES"]

LIGHTING_STYLES = ("phong", "independent")
"""``'phong'``: the placement the Phong footage is lit with; ``'independent'``: another, for the held-out footage."""

# style: [(name, kind, azimuth deg (to the subject's left), elevation deg, distance mm, irradiance at the face,
#          spot cone half-angle deg)], ambient
_PLACEMENTS = {
    "phong": ([("key", "spot", 40.0, 30.0, 1250.0, 0.85, 22.0),
               ("fill", "point", -55.0, 5.0, 1500.0, 0.15, None)], 0.06),
    "independent": ([("key", "spot", -30.0, 22.0, 1050.0, 0.80, 26.0),
                     ("fill", "directional", 65.0, -12.0, None, 0.18, None),
                     ("rim", "point", 110.0, 40.0, 900.0, 0.08, None)], 0.08),
}


def studio_lights(scan_vertices: FloatArray, landmarks: Any, mocap_from_scan: FloatArray, *,
                  style: str = "phong") -> Any:
    """The detail footage's lights, aimed at the face at rest, in the mocap frame (:class:`~facecap.cameras.LightSetup`).

    Parameters
    ----------
    scan_vertices : (n, 3) float array, mm
        The face at rest in the scan's frame (ICT: x to the subject's left, y up, z out).
    landmarks : (68,) int array
        Its landmarks; the face centre is the middle of the nose bridge and chin, lifted 12 mm
        (as :func:`~facecap.synth.write_footage_case.stage_cameras` aims).
    mocap_from_scan : (4, 4) float array
    style : {'phong', 'independent'}, default 'phong'
        ``'phong'``: a spot key 40 degrees to the subject's left and 30 up, 1.25 m away (cone 22
        degrees, 5 degree penumbra), 0.85 at the face; a point fill 55 degrees to the right, 1.5 m,
        0.15; ambient 0.06. ``'independent'``: a spot key 30 degrees to the right and 22 up, 1.05 m
        (cone 26), 0.80; a directional fill from the left and below, 0.18; a point rim light from
        behind the left, 0.08; ambient 0.08.

    Returns
    -------
    LightSetup
        Intensities are such that a white surface facing a light at the face centre receives the
        irradiance given above (radiance as a fraction of the sensor's full scale for albedo 1).

    Raises
    ------
    InputError
        On an unknown ``style``.
    """
    from ..cameras import Light, LightSetup

    if style not in _PLACEMENTS:
        raise InputError(f"style: expected one of {list(LIGHTING_STYLES)}, got {style!r}")
    V = np.asarray(scan_vertices, dtype=np.float64)
    lm = np.asarray(landmarks)
    target_scan = 0.5 * (V[lm[27]] + V[lm[8]]) + np.array([0.0, 12.0, 0.0])
    M = np.asarray(mocap_from_scan, dtype=np.float64)
    target = M[:3, :3] @ target_scan + M[:3, 3]
    lights = []
    placements, ambient = _PLACEMENTS[style]
    for name, kind, az_deg, el_deg, distance, irradiance, cone in placements:
        az, el = np.deg2rad(az_deg), np.deg2rad(el_deg)
        toward = M[:3, :3] @ np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])
        if kind == "directional":
            lights.append(Light(kind, intensity=irradiance, direction=-toward, name=name))
            continue
        position = target + distance * toward
        intensity = irradiance * (distance / 1000.0) ** 2  # inverse square: ``irradiance`` at the target
        if kind == "spot":
            lights.append(Light(kind, intensity=intensity, position=position, direction=-toward, cone_deg=cone,
                                name=name))
        else:
            lights.append(Light(kind, intensity=intensity, position=position, name=name))
    return LightSetup(lights, ambient=ambient)

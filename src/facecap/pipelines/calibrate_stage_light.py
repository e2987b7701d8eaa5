"""``facecap calibrate-light``'s job: a light calibrated from footage of a chrome sphere, written as ``lights.json``.

The job opens each camera's footage (:func:`~facecap.cameras.open_footage`; every frame is a sphere
position), checks the counts and sizes, runs :func:`~facecap.cameras.calibrate_light`, and writes

- ``lights.json`` (:func:`~facecap.cameras.write_light_file`, atomically): the one light, with the
  intensity and ambient the user gave (a mirror sphere measures neither);
- ``<name>_check.png`` beside it (``lights_check.png`` for ``lights.json``): each camera's first frame
  with the outline and highlight found (:func:`~facecap.report.draw_light_check.draw_light_check`).

Nothing is written when an image cannot be measured: the error names that camera's footage.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from contextlib import ExitStack
from pathlib import Path

from ..cameras.calibrate_light import LightCalibration, LightCalibrationError, calibrate_light
from ..cameras.camera import Camera
from ..cameras.footage import open_footage
from ..io.image_file import write_image
from ..cameras.light_file import LightSetup, write_light_file
from ..errors import FacecapWarning, InputError
from ..io.atomic_write import check_file_destination
from ..report.draw_light_check import draw_light_check

__all__ = ["calibrate_stage_light", "light_check_path"]


def light_check_path(out_path: str | os.PathLike[str]) -> Path:
    """Where the check picture of a lights file goes: ``<stem>_check.png`` beside it."""
    out = Path(out_path)
    return out.with_name(f"{out.stem}_check.png")


def calibrate_stage_light(
    cameras: Sequence[Camera],
    footage_paths: Sequence[str | os.PathLike[str]],
    sphere_radius_mm: float,
    out_path: str | os.PathLike[str],
    *,
    intensity: float = 1.0,
    ambient: float = 0.0,
    kind: str = "auto",
    highlight_sigma_px: float = 0.5,
    overwrite: bool = False,
) -> LightCalibration:
    """Calibrate the stage's light from each camera's footage of a chrome sphere and write ``lights.json``.

    Parameters
    ----------
    cameras : sequence of Camera
        One per footage, in its order (:func:`~facecap.cameras.read_footage_cameras`).
    footage_paths : sequence of path
        One image, image folder or video per camera; every camera the same number of frames, frame
        ``f`` of each showing the same sphere position.
    sphere_radius_mm : float, mm
        The sphere's radius.
    out_path : path
        ``lights.json`` to write (its picture goes beside it: :func:`light_check_path`).
    intensity, ambient : float
        Written as given (relative; :class:`~facecap.cameras.Light`).
    kind : {'auto', 'point', 'directional'}, default 'auto'
    highlight_sigma_px : float, default 0.5
        The highlight's assumed error, px, for the uncertainty.
    overwrite : bool, default False
        Replace an existing ``lights.json``; False refuses it before any work.

    Returns
    -------
    LightCalibration
        The solver's result (:func:`~facecap.cameras.calibrate_light`).

    Raises
    ------
    InputError
        Naming the footage: a count of footage that is not the cameras', frame counts or sizes that
        differ, an image without a sphere or a highlight, a highlight off the sphere.

    Warns
    -----
    FacecapWarning
        When the geometry is weak (the light's distance is uncertain, or it was taken as directional).
    """
    if len(footage_paths) != len(cameras):
        raise InputError(f"--images: {len(footage_paths)} footage for {len(cameras)} cameras (one per camera)")
    out = Path(out_path)
    check_file_destination(out, overwrite=overwrite)
    if not (ambient >= 0):
        raise InputError(f"--ambient: expected a number >= 0, got {ambient!r}")
    with ExitStack() as stack:
        footage = [stack.enter_context(open_footage(p)) for p in footage_paths]
        for camera, clip in zip(cameras, footage):
            clip.check_camera(camera)
        counts = [len(clip) for clip in footage]
        if len(set(counts)) != 1:
            odd = next(i for i, n in enumerate(counts) if n != counts[0])
            raise InputError(f"{counts[odd]} frames, but {footage_paths[0]} has {counts[0]}: each frame is one "
                             "sphere position seen by every camera", path=str(footage_paths[odd]))
        try:
            calibration = calibrate_light(footage, cameras, sphere_radius_mm, kind=kind, intensity=intensity,
                                          highlight_sigma_px=highlight_sigma_px)
        except LightCalibrationError as exc:
            where = footage[exc.camera]
            path = where.files[exc.frame] if where.kind == "images" else Path(footage_paths[exc.camera])
            raise InputError(exc.message, path=str(path)) from None
        picture = draw_light_check([clip.frame(0) for clip in footage], cameras, calibration)
    setup = LightSetup((calibration.light,), ambient)
    if calibration.weak:
        warnings.warn(f"weak geometry: {calibration.weak}", FacecapWarning, stacklevel=2)
    write_image(light_check_path(out), picture)
    write_light_file(out, setup)
    return calibration

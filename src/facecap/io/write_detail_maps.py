"""The detail layer's maps in a result folder: ``maps/displacement_NNNNNN.exr``, ``maps/normal_NNNNNN.png``, ``maps/maps.json``.

One pair of files per video frame (``NNNNNN`` the video frame, six digits):

- ``displacement_NNNNNN.exr``: one float32 channel ``Y``, the detail's height
  along the base surface's normal in millimetres (ZIP-compressed, lossless); the
  header says so (``unit = 'mm'``, ``facecapVideoFrame``, ``facecapMocapFrame``);
- ``normal_NNNNNN.png``: 16-bit RGB, the tangent-space normal encoded
  ``(n + 1) / 2`` (OpenGL convention: green is +v, up in UV).

``maps.json`` (written last) lists the size, units, conventions and every
video frame with its mocap frame. Each file is written under a temporary name
and renamed (:func:`~facecap.io.atomic_write.atomic_path`). The pixel arrays
come from :class:`facecap.sfs.DetailMaps`; this module only stores them.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from .atomic_write import atomic_path, atomic_write_text

__all__ = ["MAPS_FOLDER", "MAPS_INDEX", "detail_map_names", "write_detail_maps", "write_maps_index"]

MAPS_FOLDER = "maps"
"""The result folder's sub-folder that holds the maps."""

MAPS_INDEX = "maps.json"
"""The maps' index in :data:`MAPS_FOLDER`."""

NORMAL_CONVENTION = ("tangent space, MikkTSpace-like (per-corner tangents dP/du, Gram-Schmidt against the "
                     "interpolated normal, bitangent = sign * N x T), OpenGL convention: +Y (green) is +v, "
                     "up in UV; encoded (n + 1) / 2 in 16-bit RGB")


def detail_map_names(video_frame: int) -> tuple[str, str]:
    """The displacement and normal maps' file names for a video frame, relative to :data:`MAPS_FOLDER`."""
    return f"displacement_{int(video_frame):06d}.exr", f"normal_{int(video_frame):06d}.png"


def write_detail_maps(folder: str | os.PathLike[str], video_frame: int, displacement: Any, normal_map: Any, *,
                      mocap_frame: float | None = None, compression: int = 1) -> tuple[Path, Path]:
    """Write one video frame's displacement map (EXR) and normal map (16-bit PNG), each atomically.

    Parameters
    ----------
    folder : str or path-like
        The maps folder (it must exist).
    video_frame : int
    displacement : (size, size) float32 array, mm
        Row 0 the top of the map (``v = 1``).
    normal_map : (size, size, 3) uint16 array
        RGB, as :meth:`facecap.sfs.DetailMaps.normal_map` encodes it.
    mocap_frame : float, optional
        Recorded in the EXR header.
    compression : int, default 1
        zlib level of the PNG (0-9): 1 writes a 2048^2 map in about a third of the time of 9 for 10 % more bytes.

    Returns
    -------
    (Path, Path)
        The displacement and the normal map's paths.

    Raises
    ------
    InputError
        Arrays of other shapes or types, a folder that cannot be written.
    """
    import cv2
    import OpenEXR

    folder = Path(folder)
    D = np.asarray(displacement)
    N = np.asarray(normal_map)
    if D.ndim != 2 or D.shape[0] != D.shape[1] or not np.issubdtype(D.dtype, np.floating):
        raise InputError(f"displacement: expected a square (size, size) float array, got {D.shape} {D.dtype}")
    if N.shape != D.shape + (3,) or N.dtype != np.uint16:
        raise InputError(f"normal_map: expected a {D.shape + (3,)} uint16 array, got {N.shape} {N.dtype}")
    if not np.all(np.isfinite(D)):
        raise InputError("displacement: expected finite heights, got NaN or infinity")
    displacement_name, normal_name = detail_map_names(video_frame)
    header: dict[str, Any] = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
                              "unit": "mm", "facecapVideoFrame": int(video_frame)}
    if mocap_frame is not None:
        header["facecapMocapFrame"] = float(mocap_frame)
    with atomic_path(folder / displacement_name) as tmp:
        with OpenEXR.File(header, {"Y": np.ascontiguousarray(D, dtype=np.float32)}) as exr:
            exr.write(str(tmp))
    with atomic_path(folder / normal_name) as tmp:
        if not cv2.imwrite(str(tmp), np.ascontiguousarray(N[:, :, ::-1]), [cv2.IMWRITE_PNG_COMPRESSION, compression]):
            raise InputError("OpenCV could not write the normal map", path=str(folder / normal_name))
    return folder / displacement_name, folder / normal_name


def write_maps_index(folder: str | os.PathLike[str], *, size: int, video_frames: Sequence[int],
                     mocap_frames: Sequence[float], padding: int, base: str = "the layer below") -> Path:
    """Write ``maps.json``: what the maps are and which frame each holds.

    Parameters
    ----------
    folder : str or path-like
        The maps folder.
    size : int
        Texels along each side.
    video_frames : sequence of int
    mocap_frames : sequence of float
        The mocap frame (fractional) of each video frame.
    padding : int
        Texels of edge padding round the UV islands.
    base : str, default 'the layer below'
        What the maps are relative to (the result they were computed on).

    Returns
    -------
    Path
    """
    if len(video_frames) != len(mocap_frames):
        raise InputError(f"mocap_frames: expected one per video frame ({len(video_frames)}), got {len(mocap_frames)}")
    document = {
        "size": int(size), "padding_texels": int(padding),
        "uv_convention": "origin at the map's bottom-left, v up (OBJ, USD); row 0 of the files is v = 1",
        "base": base,
        "displacement": {"format": "OpenEXR, one float32 channel Y", "units": "mm",
                         "meaning": "height along the base surface's vertex normal; 0 outside the detail region"},
        "normal": {"format": "PNG, 16-bit RGB", "convention": NORMAL_CONVENTION,
                   "flat": [0.5, 0.5, 1.0]},
        "frames": [{"video_frame": int(j), "mocap_frame": float(m),
                    "displacement": detail_map_names(j)[0], "normal": detail_map_names(j)[1]}
                   for j, m in zip(video_frames, mocap_frames)],
    }
    path = Path(folder) / MAPS_INDEX
    atomic_write_text(path, json.dumps(document, indent=1))
    return path

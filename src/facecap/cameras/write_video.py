"""Write footage as a video file through PyAV, losslessly by default, atomically."""

from __future__ import annotations

import os
from collections.abc import Iterable
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from ..errors import InputError
from ..io.atomic_write import atomic_path
from ..validate import as_positive

__all__ = ["write_video", "LOSSLESS_VIDEO_CODECS"]

LOSSLESS_VIDEO_CODECS = {".mkv": "ffv1", ".avi": "ffv1", ".mov": "png"}
"""The lossless codec :func:`write_video` uses for each container (QuickTime does not hold FFV1, so PNG)."""

# codec -> the encoder's pixel format for (channels, bits): chosen so that RGB and grey, 8 and 16 bit, are exact
_PIXEL_FORMATS = {
    "ffv1": {(3, 8): "bgr0", (3, 16): "gbrp16le", (1, 8): "gray", (1, 16): "gray16le"},
    "png": {(3, 8): "rgb24", (3, 16): "rgb48be", (1, 8): "gray", (1, 16): "gray16be"},
    "libx264": {(3, 8): "yuv420p", (1, 8): "yuv420p"},
}
_INPUT_FORMATS = {(3, 8): "rgb24", (3, 16): "rgb48le", (1, 8): "gray", (1, 16): "gray16le"}


def write_video(path: str | os.PathLike[str], frames: Iterable[Any], *, rate_hz: float, codec: str | None = None,
                progress: bool = False) -> None:
    """Write frames to a video file, readable by :func:`open_footage`.

    Parameters
    ----------
    path : str or path-like
        Destination ``.mkv``, ``.avi``, ``.mov`` (lossless) or ``.mp4`` (H.264, lossy).
    frames : iterable of (H, W) or (H, W, 3) arrays
        ``uint8`` or ``uint16`` (16-bit needs a lossless codec), RGB order, all of one size.
    rate_hz : float
        Frame rate, stored exactly as a fraction (12.5 -> 25/2).
    codec : {'ffv1', 'png', 'libx264'} or None, default None
        None picks the container's lossless codec (:data:`LOSSLESS_VIDEO_CODECS`)
        or H.264 for ``.mp4``. FFV1 and PNG are lossless: frames read back
        bit-identical (tested); H.264 (yuv420p) is not, and needs even sizes.
    progress : bool, default False
        Show a tqdm progress bar.

    Raises
    ------
    InputError
        On an unknown container or codec, no frame, frames of differing size
        or type, a dtype the codec cannot hold, or a missing folder. Nothing
        is left at ``path`` then.
    """
    import av

    file = Path(path)
    suffix = file.suffix.lower()
    if codec is None:
        if suffix == ".mp4":
            codec = "libx264"
        elif suffix in LOSSLESS_VIDEO_CODECS:
            codec = LOSSLESS_VIDEO_CODECS[suffix]
        else:
            raise InputError(f"expected a .mkv, .avi, .mov or .mp4 file, got {suffix!r}", path=str(file))
    if codec not in _PIXEL_FORMATS:
        raise InputError(f"codec: expected one of {sorted(_PIXEL_FORMATS)}, got {codec!r}")
    rate = as_positive(rate_hz, name="rate_hz")
    fraction = Fraction(rate).limit_denominator(1001)
    total = len(frames) if hasattr(frames, "__len__") else None  # type: ignore[arg-type]
    with atomic_path(file) as tmp:
        container = av.open(str(tmp), mode="w", format=None)
        try:
            stream = None
            layout = None
            with tqdm(total=total, unit="frame", desc="video", disable=not progress, leave=False) as bar:
                for index, frame in enumerate(frames):
                    A = np.asarray(frame)
                    if layout is None:
                        key = _layout_key(A, codec, file)
                        layout = (A.shape, A.dtype)
                        stream = container.add_stream(codec, rate=fraction)
                        stream.width, stream.height = A.shape[1], A.shape[0]
                        stream.pix_fmt = _PIXEL_FORMATS[codec][key]
                        if codec == "libx264":
                            stream.options = {"crf": "12", "preset": "fast"}
                    elif (A.shape, A.dtype) != layout:
                        raise InputError(f"frame {index} is {A.shape} {A.dtype}, frame 0 is {layout[0]} {layout[1]}: "
                                         "every frame must match", path=str(file))
                    picture = av.VideoFrame.from_ndarray(np.ascontiguousarray(A), format=_INPUT_FORMATS[key])
                    for packet in stream.encode(picture):
                        container.mux(packet)
                    bar.update(1)
            if stream is None:
                raise InputError("no frame to write", path=str(file))
            for packet in stream.encode():
                container.mux(packet)
        finally:
            container.close()


def _layout_key(A: np.ndarray, codec: str, file: Path) -> tuple[int, int]:
    if A.ndim == 2:
        channels = 1
    elif A.ndim == 3 and A.shape[2] == 3:
        channels = 3
    else:
        raise InputError(f"frames must be (H, W) or (H, W, 3), got {A.shape}", path=str(file))
    if A.dtype not in (np.uint8, np.uint16):
        raise InputError(f"video frames must be uint8 or uint16, got {A.dtype} (convert floats first)",
                         path=str(file))
    key = (channels, 8 if A.dtype == np.uint8 else 16)
    if key not in _PIXEL_FORMATS[codec]:
        raise InputError(f"{codec} cannot hold {key[1]}-bit frames here; use a .mkv (FFV1) or .mov (PNG)",
                         path=str(file))
    if codec == "libx264" and (A.shape[0] % 2 or A.shape[1] % 2):
        raise InputError(f"H.264 (yuv420p) needs an even width and height, got {A.shape[1]}x{A.shape[0]}",
                         path=str(file))
    return key

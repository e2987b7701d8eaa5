"""Write footage as a folder of numbered images (PNG 8/16-bit, TIFF, JPEG, EXR), atomically."""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from ..errors import InputError
from ..io.atomic_write import atomic_folder
from ..io.image_file import IMAGE_SUFFIXES, write_image

__all__ = ["write_image_sequence", "SEQUENCE_FILE"]

SEQUENCE_FILE = "sequence.json"
"""Written last into every folder :func:`write_image_sequence` makes: its frame count, size and type."""


def write_image_sequence(folder: str | os.PathLike[str], frames: Iterable[Any], *, suffix: str = ".png",
                         name: str = "frame_{:06d}", progress: bool = False) -> None:
    """Write frames as ``folder/frame_000000.png`` ... (frame 0 first), readable by :func:`open_footage`.

    Parameters
    ----------
    folder : str or path-like
        Destination folder. Built under a hidden name and moved into place
        when every frame is written, so a failed write leaves nothing under
        ``folder``; an existing folder is replaced only if it is empty or an
        earlier sequence (holds ``sequence.json``).
    frames : iterable of (H, W) or (H, W, C) arrays
        All of one size and dtype, RGB(A) order: ``uint8`` or ``uint16`` for
        PNG/TIFF, ``uint8`` for JPEG, float for EXR (written as float32). A
        ``(T, H, W[, C])`` array is an iterable of frames.
    suffix : {'.png', '.tif', '.tiff', '.jpg', '.jpeg', '.exr'}, default '.png'
    name : str, default 'frame_{:06d}'
        File name stem, formatted with the frame index.
    progress : bool, default False
        Show a tqdm progress bar.

    Raises
    ------
    InputError
        On an unknown suffix, no frame, frames of differing size or type, a
        dtype the format cannot hold, or a folder holding something else.
    """
    suffix = suffix.lower() if suffix.startswith(".") else "." + suffix.lower()
    if suffix not in IMAGE_SUFFIXES:
        raise InputError(f"suffix: expected one of {IMAGE_SUFFIXES}, got {suffix!r}")
    try:
        name.format(0)
    except (IndexError, KeyError, ValueError):
        raise InputError(f"name: expected a format string with one field such as 'frame_{{:06d}}', got {name!r}") \
            from None
    total = len(frames) if hasattr(frames, "__len__") else None  # type: ignore[arg-type]
    # a library call that replaces an earlier sequence, as documented (a folder of anything else is refused)
    with atomic_folder(folder, marker_file=SEQUENCE_FILE, overwrite=True) as staging:
        layout: tuple[tuple[int, ...], np.dtype] | None = None
        count = 0
        with tqdm(total=total, unit="frame", desc="images", disable=not progress, leave=False) as bar:
            for index, frame in enumerate(frames):
                A = np.asarray(frame)
                if layout is None:
                    layout = (A.shape, A.dtype)
                elif (A.shape, A.dtype) != layout:
                    raise InputError(f"frame {index} is {A.shape} {A.dtype}, frame 0 is {layout[0]} {layout[1]}: "
                                     "every frame must match", path=str(folder))
                write_image(staging / f"{name.format(index)}{suffix}", A)
                count += 1
                bar.update(1)
        if layout is None:
            raise InputError("no frame to write", path=str(folder))
        shape = layout[0]
        info = {"n_frames": count, "width": int(shape[1]), "height": int(shape[0]),
                "channels": 1 if len(shape) == 2 else int(shape[2]),
                "dtype": "float32" if suffix == ".exr" else str(layout[1]),
                "first_file": f"{name.format(0)}{suffix}"}
        (Path(staging) / SEQUENCE_FILE).write_text(json.dumps(info, indent=2) + "\n", encoding="utf-8")

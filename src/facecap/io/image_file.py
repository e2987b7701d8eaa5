"""One image file, read and written as stored: PNG (8 or 16 bit), JPEG, TIFF, BMP through OpenCV, EXR through OpenEXR.

Images are ``(H, W)`` (grey) or ``(H, W, C)`` arrays with channels in **RGB(A)**
order (OpenCV's BGR is swapped at the boundary), in the file's own type and
encoding: ``uint8`` or ``uint16`` as stored (PNG and JPEG hold sRGB-encoded
values; nothing is decoded), ``float32`` for EXR (linear by convention).
:func:`~facecap.cameras.image_to_float` turns them into floats.

OpenCV's wheel is built without OpenEXR writing, so EXR goes through the
``openexr`` wheel (the Academy Software Foundation's bindings); half-float
EXR channels are read as float32.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FileFormatError, InputError
from .atomic_write import atomic_path

__all__ = ["read_image", "write_image", "IMAGE_SUFFIXES"]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".exr")
"""Image file suffixes facecap reads (lower case)."""

_JPEG_QUALITY = 95


def _read_exr(file: Path) -> np.ndarray:
    import OpenEXR

    try:
        with OpenEXR.File(str(file)) as exr:  # the pixels live only while the file is open: copy them inside
            channels = exr.channels()
            for key in ("RGBA", "RGB", "Y"):
                if key in channels:
                    return np.array(channels[key].pixels, dtype=np.float32, order="C")
            if len(channels) == 1:
                return np.array(next(iter(channels.values())).pixels, dtype=np.float32, order="C")
            names = sorted(channels)
    except RuntimeError as exc:
        raise FileFormatError(f"not a readable EXR file ({exc})", path=str(file)) from None
    raise FileFormatError(f"EXR channels {names}: expected RGB, RGBA or Y", path=str(file))


def read_image(path: str | os.PathLike[str]) -> np.ndarray:
    """Read one image as stored.

    Parameters
    ----------
    path : str or path-like
        A ``.png``, ``.jpg``/``.jpeg``, ``.tif``/``.tiff``, ``.bmp`` or ``.exr`` file.

    Returns
    -------
    image : (H, W) or (H, W, C) array
        ``uint8``, ``uint16`` (16-bit PNG or TIFF) or ``float32`` (EXR); RGB(A) channel order.

    Raises
    ------
    FileFormatError
        If the file is missing, has another suffix, or cannot be decoded.
    """
    file = Path(path)
    suffix = file.suffix.lower()
    if suffix not in IMAGE_SUFFIXES:
        raise FileFormatError(f"not an image file facecap reads (expected one of {IMAGE_SUFFIXES})", path=str(file))
    if not file.is_file():
        raise FileFormatError("image file not found", path=str(file))
    if suffix == ".exr":
        return _read_exr(file)
    import cv2

    image = cv2.imread(str(file), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise FileFormatError("OpenCV cannot decode this image (truncated or not an image)", path=str(file))
    if image.ndim == 3 and image.shape[2] == 3:
        image = image[:, :, ::-1]
    elif image.ndim == 3 and image.shape[2] == 4:
        image = image[:, :, [2, 1, 0, 3]]
    return np.ascontiguousarray(image)


def _as_image(image: Any, name: str) -> np.ndarray:
    A = np.asarray(image)
    if A.ndim not in (2, 3) or (A.ndim == 3 and A.shape[2] not in (1, 3, 4)) or A.size == 0:
        raise InputError(f"{name}: expected an (H, W) or (H, W, 1|3|4) image, got shape {A.shape}")
    if A.ndim == 3 and A.shape[2] == 1:
        A = A[:, :, 0]
    return A


def write_image(path: str | os.PathLike[str], image: Any) -> None:
    """Write one image (atomically), bit-exact for PNG, TIFF and EXR.

    Parameters
    ----------
    path : str or path-like
        Destination; the suffix chooses the format: ``.png`` (uint8 or uint16),
        ``.tif``/``.tiff`` (uint8 or uint16), ``.bmp`` (uint8), ``.jpg``/``.jpeg`` (uint8, quality 95, lossy)
        or ``.exr`` (float32, ZIP-compressed, lossless; float64 is narrowed to float32).
    image : (H, W) or (H, W, C) array, C in {1, 3, 4}
        RGB(A) channel order.

    Raises
    ------
    InputError
        If the suffix is unknown, the dtype does not fit the format (floats to
        PNG, integers to EXR: convert first, facecap does not guess a scale),
        the image is not 2D/3D, or the folder does not exist.
    """
    file = Path(path)
    suffix = file.suffix.lower()
    if suffix not in IMAGE_SUFFIXES:
        raise InputError(f"expected one of {IMAGE_SUFFIXES}", path=str(file))
    A = _as_image(image, "image")
    if suffix == ".exr":
        if not np.issubdtype(A.dtype, np.floating):
            raise InputError(f"EXR holds floats; got {A.dtype} (convert with image_to_float first)", path=str(file))
        import OpenEXR

        key = "Y" if A.ndim == 2 else {3: "RGB", 4: "RGBA"}[A.shape[2]]
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        with atomic_path(file) as tmp:
            with OpenEXR.File(header, {key: np.ascontiguousarray(A, dtype=np.float32)}) as exr:
                exr.write(str(tmp))
        return
    allowed = (np.uint8,) if suffix in (".jpg", ".jpeg", ".bmp") else (np.uint8, np.uint16)
    if A.dtype not in allowed:
        raise InputError(f"{suffix} holds {' or '.join(np.dtype(t).name for t in allowed)}; got {A.dtype}",
                         path=str(file))
    import cv2

    if A.ndim == 3:
        A = A[:, :, ::-1] if A.shape[2] == 3 else A[:, :, [2, 1, 0, 3]]
    params = [cv2.IMWRITE_JPEG_QUALITY, _JPEG_QUALITY] if suffix in (".jpg", ".jpeg") else []
    with atomic_path(file) as tmp:
        if not cv2.imwrite(str(tmp), np.ascontiguousarray(A), params):
            raise InputError("OpenCV could not write the image", path=str(file))

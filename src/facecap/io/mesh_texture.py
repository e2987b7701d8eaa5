"""A scan's colour texture: the images its materials name, read and packed into one atlas.

Scanners deliver colour as a texture the UVs index: an OBJ's ``mtllib`` names an MTL file whose
``map_Kd`` names the image (PNG, JPEG, TIFF, BMP or TGA), a glTF material's ``baseColorTexture``,
a PLY header's ``comment TextureFile``. Photogrammetry tools often split the colour over several
materials, each with its own image; facecap packs those into one atlas (each image beside the
last, its UVs moved with it), so everything downstream sees one image and one set of UVs
(:attr:`facecap.structures.Mesh.texture`).

A texture that cannot be found or read costs the colour, not the geometry: the mesh is read
without it and a warning names the file and the cause. A missing MTL file is passed over silently
(meshes are often copied without it, and most commands need no colour); the commands that need
colour say so when it is absent.
"""

from __future__ import annotations

import os
import re
import warnings
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import FacecapWarning, FileFormatError
from ..typing import FloatArray, IntArray
from .image_file import read_image

__all__ = ["read_texture_image", "read_mtl", "MtlMaterial", "pack_textures", "TEXTURE_SUFFIXES"]

TEXTURE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".tga")
"""Image types a mesh's texture may be in (lower case)."""

_PAD_PX = 2  # each packed image's edge repeated around it, so bilinear lookups near a seam stay inside it
_WRAP_TOLERANCE = 1e-5  # UVs this close outside [0, 1] are taken as on its edge when packing
_DEFAULT_KD = (0.8, 0.8, 0.8)  # the MTL specification's diffuse colour when a material gives none
# map_Kd options and how many values each takes (MTL specification, Wavefront 1995)
_MAP_OPTIONS = {"-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1, "-imfchan": 1,
                "-mm": 2, "-o": 3, "-s": 3, "-t": 3, "-texres": 1}


class MtlMaterial(NamedTuple):
    """One ``newmtl`` of an MTL file: its diffuse colour and the image its ``map_Kd`` names."""

    kd: tuple[float, float, float]
    texture: Path | None


def read_texture_image(path: str | os.PathLike[str]) -> np.ndarray:
    """Read a texture image as stored: ``(h, w, 3)`` uint8 or uint16, sRGB-encoded, RGB order.

    Grey images are repeated into three channels and alpha is dropped. PNG, JPEG, TIFF and BMP are
    read by :func:`facecap.io.image_file.read_image` (OpenCV), TGA by Pillow.

    Raises
    ------
    FileFormatError
        If the file is missing, of another type, or cannot be decoded.
    """
    file = Path(path)
    suffix = file.suffix.lower()
    if suffix not in TEXTURE_SUFFIXES:
        raise FileFormatError(f"not a texture image facecap reads (expected one of {TEXTURE_SUFFIXES})",
                              path=str(file))
    if not file.is_file():
        raise FileFormatError("texture image not found", path=str(file))
    if suffix == ".tga":  # the one texture type OpenCV does not read
        from PIL import Image

        try:
            with Image.open(file) as im:
                image = np.asarray(im.convert("RGB"))
        except OSError as exc:
            raise FileFormatError(f"Pillow cannot decode this image ({exc})", path=str(file)) from None
    else:
        image = read_image(file)
    if image.dtype not in (np.uint8, np.uint16):
        raise FileFormatError(f"a colour texture holds 8- or 16-bit values, this one {image.dtype}", path=str(file))
    if image.ndim == 2:
        image = np.repeat(image[:, :, None], 3, axis=2)
    return np.ascontiguousarray(image[:, :, :3])


def read_mtl(path: Path) -> dict[str, MtlMaterial]:
    """The materials of an MTL file by name: their ``Kd`` and the ``map_Kd`` image (found beside it).

    Image paths are taken relative to the MTL file's folder, with Windows separators read as
    ``/``; a name that is not there is looked for by its file name alone and without regard to
    case (files made on Windows and copied elsewhere). A material whose image is still not found
    has ``texture`` None and the warning says so.
    """
    materials: dict[str, MtlMaterial] = {}
    name: str | None = None
    kd, texture = _DEFAULT_KD, None

    def close() -> None:
        if name is not None:
            materials[name] = MtlMaterial(kd, texture)

    for raw in path.read_text(encoding="utf-8", errors="replace").splitlines():
        words = raw.split("#", 1)[0].split()
        if not words:
            continue
        key = words[0].lower()
        if key == "newmtl":
            close()
            name, kd, texture = " ".join(words[1:]), _DEFAULT_KD, None
        elif key == "kd" and len(words) >= 4:
            try:
                kd = (float(words[1]), float(words[2]), float(words[3]))
            except ValueError:
                pass  # a malformed colour keeps the default: the texture is what matters here
        elif key == "map_kd":
            texture = _find_image(path.parent, _image_name(words[1:]), path)
            if any(w.lower() in ("-o", "-s") for w in words[1:]):
                warnings.warn(f"{path}: material {name!r}: map_Kd's -o/-s (texture offset and scale) are not applied",
                              FacecapWarning, stacklevel=3)
    close()
    return materials


def _image_name(words: list[str]) -> str:
    """The file name of a ``map_Kd`` statement after its options (names may contain spaces)."""
    i = 0
    while i < len(words) and words[i].lower() in _MAP_OPTIONS:
        count = _MAP_OPTIONS[words[i].lower()]
        i += 1
        if count == 3:  # -o, -s, -t: u [v [w]], the file name still to come
            taken = 0
            while taken < 3 and i < len(words) - 1 and _is_number(words[i]):
                i += 1
                taken += 1
        else:
            i += count
    return " ".join(words[i:])


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True


def _find_image(folder: Path, name: str, mtl: Path) -> Path | None:
    if not name:
        return None
    name = name.replace("\\", "/").strip('"')
    for candidate in (folder / name, folder / Path(name).name):
        if candidate.is_file():
            return candidate
    wanted = Path(name).name.lower()
    for candidate in folder.iterdir() if folder.is_dir() else ():
        if candidate.name.lower() == wanted and candidate.is_file():
            return candidate
    warnings.warn(f"{mtl}: the texture {name!r} is not there; the mesh is read without its colour",
                  FacecapWarning, stacklevel=4)
    return None


def obj_texture(path: Path, data: bytes, line_starts: IntArray, face_lines: IntArray, uvs: FloatArray | None,
                uv_corners: IntArray | None, sizes: IntArray
                ) -> tuple[FloatArray | None, IntArray | None, np.ndarray | None]:
    """The texture of an OBJ from its ``mtllib`` and ``usemtl`` statements: ``(uvs, uv_corners, image)``.

    ``face_lines`` are the 0-based line numbers of the ``f`` statements, ``line_starts`` the byte
    offset of every line. Returns the UVs unchanged and ``None`` when the file names no texture
    (or it cannot be read: warned), and the packed atlas with its moved UVs when several images
    are used.
    """
    libraries: list[str] = []
    use_lines: list[int] = []
    use_names: list[str] = []
    for m in re.finditer(rb"^[ \t]*(mtllib|usemtl)[ \t]+([^\r\n#]*)", data, re.MULTILINE):
        line = int(np.searchsorted(line_starts, m.start(), side="right") - 1)
        value = m.group(2).decode("utf-8", errors="replace").strip()
        if m.group(1) == b"mtllib":
            libraries.append(value)
        else:
            use_lines.append(line)
            use_names.append(value)
    if not libraries or uvs is None or uv_corners is None:
        return uvs, uv_corners, None
    materials: dict[str, MtlMaterial] = {}
    for library in libraries:
        # one name (which may hold spaces), or several on one line as the OBJ specification allows
        names = [library] if (path.parent / library.replace("\\", "/")).is_file() else library.split()
        for name in names:
            mtl = path.parent / name.replace("\\", "/")
            if mtl.is_file():  # a missing one is common when a mesh is copied alone: colour matters only where asked
                materials.update(read_mtl(mtl))
    # each face's material: the last usemtl before it (-1: none)
    slot = np.searchsorted(np.asarray(use_lines, dtype=np.int64), face_lines, side="right") - 1
    used = np.unique(slot)
    used_materials = [materials.get(use_names[k]) if k >= 0 else None for k in used.tolist()]
    paths = [m.texture if m is not None else None for m in used_materials]
    if all(p is None for p in paths):
        return uvs, uv_corners, None
    try:
        decoded = {p: read_texture_image(p) for p in set(paths) if p is not None}
    except FileFormatError as exc:
        warnings.warn(f"{path}: {exc}; the mesh is read without its colour", FacecapWarning, stacklevel=3)
        return uvs, uv_corners, None
    if len(set(paths)) == 1:  # one image for every face: no packing, the file's UVs as they are
        return uvs, uv_corners, decoded[paths[0]]
    depth = np.uint16 if any(im.dtype == np.uint16 for im in decoded.values()) else np.uint8
    # a material without an image packs as its flat diffuse colour
    images = [decoded[p] if p is not None else
              np.full((4, 4, 3), np.round(np.clip(m.kd if m is not None else _DEFAULT_KD, 0, 1) * np.iinfo(depth).max),
                      dtype=depth)
              for p, m in zip(paths, used_materials)]
    return pack_textures(images, uvs, uv_corners, np.repeat(np.searchsorted(used, slot), sizes))


def pack_textures(images: list[np.ndarray], uvs: FloatArray, uv_corners: IntArray, corner_image: IntArray
                  ) -> tuple[FloatArray, IntArray, np.ndarray]:
    """Pack several textures into one atlas and move each corner's UV into its image's place.

    Parameters
    ----------
    images : list of (h_k, w_k, 3) uint8 or uint16 arrays
        The textures (converted to 16 bits when any is).
    uvs : (u, 2) float64 array
        Texture coordinates in the OBJ convention (``v = 0`` at an image's bottom).
    uv_corners : (c,) int64 array
        The UV of each polygon corner.
    corner_image : (c,) int64 array
        Which image each corner's UV indexes.

    Returns
    -------
    uvs : (u', 2) float64 array
        One UV per distinct (UV, image) pair, in the atlas.
    uv_corners : (c,) int64 array
    atlas : (H, W, 3) array
        The images side by side, tops aligned, each with its edge repeated ``2`` pixels around it.

    Notes
    -----
    A UV outside [0, 1] (a repeating texture) is wrapped into its image first, since the images'
    neighbours in the atlas are not their repeats.
    """
    depth = np.uint16 if any(im.dtype == np.uint16 for im in images) else np.uint8
    tiles = []
    for im in images:
        im = im.astype(np.uint16) * 257 if depth == np.uint16 and im.dtype == np.uint8 else im
        tiles.append(np.pad(im, ((_PAD_PX, _PAD_PX), (_PAD_PX, _PAD_PX), (0, 0)), mode="edge"))
    H = max(t.shape[0] for t in tiles)
    widths = np.array([t.shape[1] for t in tiles])
    W = int(widths.sum())
    x0 = np.cumsum(widths) - widths
    atlas = np.zeros((H, W, 3), dtype=depth)
    for k, t in enumerate(tiles):
        atlas[: t.shape[0], x0[k] : x0[k] + t.shape[1]] = t
        atlas[t.shape[0]:, x0[k] : x0[k] + t.shape[1]] = t[-1:]
    pairs, inverse = np.unique(np.stack([uv_corners, corner_image], axis=1), axis=0, return_inverse=True)
    uv = uvs[pairs[:, 0]].copy()
    uv[(uv < 0) & (uv > -_WRAP_TOLERANCE)] = 0.0  # rounding just outside an edge is the edge, not the far side
    uv[(uv > 1) & (uv < 1 + _WRAP_TOLERANCE)] = 1.0
    outside = (uv < 0) | (uv > 1)
    uv[outside] -= np.floor(uv[outside])
    k = pairs[:, 1]
    h = np.array([im.shape[0] for im in images], dtype=np.float64)[k]
    w = np.array([im.shape[1] for im in images], dtype=np.float64)[k]
    x = x0[k] + _PAD_PX + uv[:, 0] * w
    y = _PAD_PX + (1.0 - uv[:, 1]) * h  # from the atlas's top
    return np.stack([x / W, 1.0 - y / H], axis=1), inverse.reshape(-1).astype(np.int64), atlas

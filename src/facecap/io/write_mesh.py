"""Write a mesh (or one animation frame of it) to OBJ or binary PLY, atomically."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, InputError
from ..structures import Mesh
from ..typing import FloatArray, IntArray
from ..units import mm_per_unit, normalize_unit
from ..validate import as_vertices
from .atomic_write import atomic_path, atomic_write_text
from .image_file import write_image

__all__ = ["write_mesh", "check_uvs", "write_texture_files"]

_UV_DECIMALS = 9
_COLOR_DECIMALS = 6
_MATERIAL = "skin"  # the one material of a textured OBJ that facecap writes


def write_mesh(
    mesh: Mesh,
    path: str | os.PathLike[str],
    *,
    vertices: FloatArray | None = None,
    unit: str | None = None,
    decimals: int | None = None,
    shared_texture: str | None = None,
) -> Path:
    """Write a mesh to ``.obj`` or binary ``.ply``, keeping vertex order, polygons and UVs.

    The file is written to a temporary sibling and renamed onto ``path`` only
    when complete, so a reader never sees half a file.

    Parameters
    ----------
    mesh : Mesh
        The mesh: its topology (original polygons when kept, else triangles),
        UVs and source unit are written.
    path : str or path-like
        Output file; the suffix picks the format: ``.obj`` (text) or ``.ply``
        (binary little-endian).
    vertices : (n, 3) float64 array, mm, optional
        Positions to write instead of ``mesh.vertices`` (an animation frame of
        the same topology). Default None: ``mesh.vertices``.
    unit : {'mm', 'cm', 'm', 'in'} or None, optional
        Length unit of the file; positions are converted from mm. Default
        None: ``mesh.source_unit``, so a mesh read and written comes back in
        its own unit.
    decimals : int or None, optional
        OBJ only: digits after the decimal point of the coordinates, in
        ``unit``. Default None: enough for a resolution of 1e-6 mm (6 for
        mm, 7 for cm, 8 for inches, 9 for m). UVs always get 9 decimals.
        Trailing zeros are not written. PLY stores float64 positions exactly.
    shared_texture : str or None, optional
        For a sequence of frames: the name ``NAME`` of texture files already written beside
        ``path`` by :func:`write_texture_files` (``NAME_color.png``, ``NAME.mtl``), which the file
        refers to instead of writing its own. Default None: a textured mesh writes its own.

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    InputError
        If ``mesh`` is not a :class:`~facecap.structures.Mesh`, ``vertices``
        does not have the mesh's shape or is not finite, the mesh's UVs are
        not finite or their indices do not match the corners, or ``decimals``
        is not an integer in 0..15.
    FileFormatError
        If the suffix is neither ``.obj`` nor ``.ply`` or the folder does not exist.

    Notes
    -----
    Vertex colours (``mesh.vertex_colors``, sRGB-encoded in [0, 1]) are written
    when the mesh has them: OBJ as ``v x y z r g b`` with 6 decimals, PLY as
    ``uchar red, green, blue`` (rounded to the nearest of 0..255, so they read
    back within 1/510). Meshes without colours are written as before.

    A texture (``mesh.texture``, with UVs) is written beside the mesh as
    ``<stem>_color.png`` (8 or 16 bits, as held), before the mesh: OBJ names it
    through ``<stem>.mtl`` (``mtllib``, one material ``skin`` with ``map_Kd``),
    PLY through a ``comment TextureFile`` header line (MeshLab's convention).
    :func:`~facecap.io.read_mesh` reads both back.

    OBJ: ``v`` lines (no normals), ``vt`` lines and ``f v/vt`` corners when the
    mesh has UVs, 1-based indices, polygons as stored in ``mesh``. Numbers are
    formatted in fixed point by vectorised numpy code (no per-value Python
    formatting): a 10k-vertex, 20k-triangle frame takes about 5 ms (PLY about 3 ms).

    PLY: ``vertex`` with ``double x, y, z``; ``face`` with ``list uchar int
    vertex_indices`` (``list int int`` when a polygon has more than 255
    corners). UVs, as float32, go on the vertices (``float s, t``) when every
    vertex has a single UV, and otherwise on the faces as MeshLab's ``list
    uchar float texcoord``.

    Examples
    --------
    >>> import tempfile, pathlib, numpy as np
    >>> from facecap.structures import Mesh
    >>> mesh = Mesh(np.eye(3) * 10.0, np.array([[0, 1, 2]]), source_unit="cm")
    >>> p = write_mesh(mesh, pathlib.Path(tempfile.mkdtemp()) / "tri.obj")
    >>> print(p.read_text().splitlines()[1:5])
    ['v 1 0 0', 'v 0 1 0', 'v 0 0 1', 'f 1 2 3']
    """
    if not isinstance(mesh, Mesh):
        raise InputError(f"mesh: expected a facecap Mesh, got {type(mesh).__name__}")
    p = Path(os.fspath(path))
    suffix = p.suffix.lower()
    if suffix not in (".obj", ".ply"):
        raise FileFormatError(
            f"cannot write mesh files of type {p.suffix!r}: expected '.obj' or '.ply'", path=str(p)
        )
    if not p.parent.is_dir():
        raise FileFormatError(f"the folder {str(p.parent)!r} does not exist", path=str(p))
    unit = normalize_unit(mesh.source_unit if unit is None else unit, name="unit")
    if vertices is None:
        V = mesh.vertices
    else:
        V = as_vertices(vertices, name="vertices")
        if V.shape != mesh.vertices.shape:
            raise InputError(
                f"vertices: expected shape {mesh.vertices.shape} (the mesh's), got {V.shape}"
            )
    scale = mm_per_unit(unit)
    V = V / scale if scale != 1.0 else V
    sizes, corners = mesh.export_polygons()
    has_uv = mesh.uvs is not None and mesh.uv_indices is not None
    if has_uv:
        check_uvs(mesh.uvs, mesh.uv_indices, corners.size)  # type: ignore[arg-type]
    # the texture first, each file complete before the mesh that names it appears
    texture_name = material_name = None
    if mesh.texture is not None and has_uv:
        stem = p.stem if shared_texture is None else shared_texture
        if shared_texture is None:
            write_texture_files(mesh, p.parent, stem)
        texture_name, material_name = f"{stem}_color.png", f"{stem}.mtl"

    if suffix == ".obj":
        if decimals is None:
            decimals = math.ceil(6 + math.log10(scale) - 1e-9)
        if (isinstance(decimals, bool) or not isinstance(decimals, (int, np.integer))
                or not 0 <= decimals <= 15):
            raise InputError(f"decimals: expected an integer in 0..15, got {decimals!r}")
        payload = _obj_bytes(
            V, sizes, corners,
            mesh.uvs if has_uv else None, mesh.uv_indices if has_uv else None,
            int(decimals), unit, mesh.vertex_colors,
            material_name,
        )
    else:
        payload = _ply_bytes(
            V, sizes, corners,
            mesh.uvs if has_uv else None, mesh.uv_indices if has_uv else None,
            unit, mesh.vertex_colors, texture_name,
        )
    with atomic_path(p) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(payload)
    return p


def write_texture_files(mesh: Mesh, folder: str | os.PathLike[str], name: str) -> None:
    """Write ``mesh.texture`` as ``NAME_color.png`` and the MTL that names it, ``NAME.mtl``, in ``folder``.

    What a textured OBJ or PLY written by :func:`write_mesh` refers to (written by it, or once for a
    sequence of frames that share it through ``shared_texture``). 8- or 16-bit PNG, as held.
    """
    if mesh.texture is None:
        raise InputError("mesh: it has no texture to write")
    folder = Path(os.fspath(folder))
    write_image(folder / f"{name}_color.png", mesh.texture)
    atomic_write_text(folder / f"{name}.mtl", f"# written by facecap\nnewmtl {_MATERIAL}\n"
                      f"Ka 0 0 0\nKd 1 1 1\nKs 0 0 0\nillum 1\nmap_Kd {name}_color.png\n")


def check_uvs(uvs: FloatArray, uv_indices: IntArray, n_corners: int) -> None:
    """Check face-varying UVs before they are written (OBJ, Alembic).

    Parameters
    ----------
    uvs : (u, 2) float array
        Texture coordinates, finite.
    uv_indices : (c,) int array
        One row of ``uvs`` per polygon corner.
    n_corners : int
        The mesh's polygon corners ``c``.

    Raises
    ------
    InputError
        Naming what is wrong: the shapes, a non-finite UV, or an index out of range.
    """
    uvs = np.asarray(uvs)
    uv_indices = np.asarray(uv_indices)
    if uvs.ndim != 2 or uvs.shape[1] != 2 or not np.all(np.isfinite(uvs)):
        raise InputError(f"mesh.uvs: expected a finite (u, 2) array, got shape {uvs.shape}")
    if uv_indices.shape != (n_corners,):
        raise InputError(
            f"mesh.uv_indices: expected one index per polygon corner ({n_corners}), got shape "
            f"{uv_indices.shape}"
        )
    if n_corners and (uv_indices.min() < 0 or uv_indices.max() >= uvs.shape[0]):
        raise InputError(f"mesh.uv_indices: indices must lie in [0, {uvs.shape[0]})")


# ----------------------------------------------------------------------------- number text
# Numbers are turned into ASCII by numpy, four digits per step through a table of
# the 10,000 digit quadruples, in (characters, values) tables whose 0 bytes are
# padding; Python's per-value formatting would take ~1 us per number.

_QUADS = np.frombuffer(b"".join(b"%04d" % i for i in range(10000)), dtype="<u4").copy()
_ZERO, _MINUS, _POINT = ord("0"), ord("-"), ord(".")


def _digit_rows(m: np.ndarray, width: int) -> np.ndarray:
    """(width, k) uint8 ASCII of the last ``width`` decimal digits of the ints ``m`` >= 0."""
    if width > 8:  # uint32 arithmetic, 8 digits at a time
        return np.concatenate(
            [_digit_rows(m // 10**8, width - 8), _digit_rows(m % 10**8, 8)], axis=0
        )
    k = m.size
    n4 = (width + 3) // 4
    m = m.astype(np.uint32)
    base = np.uint32(10000)
    quads = np.empty((n4, k), dtype="<u4")
    for j in range(n4 - 1, -1, -1):
        q = m // base
        np.take(_QUADS, m - q * base, out=quads[j])
        m = q
    rows = quads.view(np.uint8).reshape(n4, k, 4).transpose(0, 2, 1).reshape(4 * n4, k)
    return rows[4 * n4 - width :]


def _number_rows(q: np.ndarray, decimals: int) -> np.ndarray:
    """(w, k) uint8 ASCII of the ints ``q`` / 10**decimals, one column per value, 0 = padding.

    Leading zeros are dropped (one integer digit is always kept), and so are
    the fraction's trailing zeros, with the point when the fraction is 0.
    """
    q = np.asarray(q, dtype=np.int64)
    m = np.abs(q)
    top = int(m.max()) if m.size else 0
    width = max(len(str(top)), decimals + 1)
    point = width - decimals  # number of integer digits
    digits = _digit_rows(m, width)
    zero = digits == _ZERO
    out = np.empty((width + 1 + (decimals > 0), q.size), dtype=np.uint8)
    out[0] = 0
    out[1 : point + 1] = digits[:point]
    # leading zeros of the integer part, row by row (rows are contiguous)
    blank = np.ones(q.size, dtype=bool)
    n_lead = np.zeros(q.size, dtype=np.int64)
    for j in range(point - 1):
        blank &= zero[j]
        out[1 + j] *= ~blank
        n_lead += blank
    if decimals:
        out[point + 1] = _POINT
        out[point + 2 :] = digits[point:]
        blank = np.ones(q.size, dtype=bool)
        for j in range(width - 1, point - 1, -1):
            blank &= zero[j]
            out[j + 2] *= ~blank
        out[point + 1] *= ~blank  # no point when the fraction is 0
    neg = np.flatnonzero(q < 0)
    out[n_lead[neg], neg] = _MINUS
    return out


def _fixed_rows(x: FloatArray, decimals: int) -> np.ndarray:
    """(w, k) uint8 ASCII of ``x`` rounded to ``decimals`` decimals (see :func:`_number_rows`)."""
    scaled = np.rint(x * 10.0**decimals)
    if scaled.size and np.abs(scaled).max() >= 1e17:
        raise InputError(
            f"coordinates up to {np.abs(x).max():.3g} are too large to write with {decimals} decimals"
        )
    return _number_rows(scaled, decimals)


def _join(*fields: np.ndarray) -> bytes:
    """Text of the table whose column i is line (or token) i, dropping the 0 padding."""
    flat = np.concatenate(fields, axis=0).T.reshape(-1)
    return flat[flat != 0].tobytes()


def _pattern(pieces: list[bytes], k: int) -> np.ndarray:
    """(w, k) rows repeating ``pieces`` (0-padded to one width) over k columns."""
    width = max(len(p) for p in pieces)
    table = np.zeros((len(pieces), width), dtype=np.uint8)
    for i, p in enumerate(pieces):
        table[i, : len(p)] = np.frombuffer(p, dtype=np.uint8)
    return np.tile(table.T, (1, k // len(pieces)))


# ----------------------------------------------------------------------------- OBJ


def _obj_bytes(V: FloatArray, sizes: IntArray, corners: IntArray, uvs: FloatArray | None,
               uv_indices: IntArray | None, decimals: int, unit: str,
               colors: np.ndarray | None = None, material_file: str | None = None) -> bytes:
    parts = [f"# written by facecap; unit: {unit}\n".encode()]
    if material_file is not None:
        parts.append(f"mtllib {material_file}\nusemtl {_MATERIAL}\n".encode())
    if colors is None:
        # one token per coordinate: "v " before x, " " or "\n" after
        parts.append(_join(
            _pattern([b"v ", b"", b""], V.size),
            _fixed_rows(V.reshape(-1), decimals),
            _pattern([b" ", b" ", b"\n"], V.size),
        ))
    else:
        # "v x y z r g b": coordinates and colours as two tables of rows, joined per line
        n = V.shape[0]
        xyz = _fixed_rows(V.reshape(-1), decimals)
        rgb = _fixed_rows(np.asarray(colors, dtype=np.float64).reshape(-1), _COLOR_DECIMALS)
        xyz_cols = xyz.reshape(xyz.shape[0], n, 3)
        rgb_cols = rgb.reshape(rgb.shape[0], n, 3)
        space = np.full((1, n), ord(" "), dtype=np.uint8)
        fields: list[np.ndarray] = [_pattern([b"v "], n)]
        for j in range(3):
            fields += [xyz_cols[:, :, j], space]
        for j in range(3):
            fields += [rgb_cols[:, :, j], space if j < 2 else np.full((1, n), ord("\n"), np.uint8)]
        parts.append(_join(*fields))
    if uvs is not None:
        parts.append(_join(
            _pattern([b"vt ", b""], uvs.size),
            _fixed_rows(np.ascontiguousarray(uvs, dtype=np.float64).reshape(-1), _UV_DECIMALS),
            _pattern([b" ", b"\n"], uvs.size),
        ))
    # one token per polygon corner: "f " before the first, " " or "\n" after
    c = corners.size
    starts = np.cumsum(sizes) - sizes
    prefix = np.zeros((2, c), dtype=np.uint8)
    prefix[0, starts] = ord("f")
    prefix[1, starts] = ord(" ")
    sep = np.full((1, c), ord(" "), dtype=np.uint8)
    sep[0, starts + sizes - 1] = ord("\n")
    # format each index once, then gather (a vertex is used by ~6 corners)
    cols = [prefix, np.take(_number_rows(np.arange(1, V.shape[0] + 1), 0), corners, axis=1)]
    if uv_indices is not None:
        uv_text = _number_rows(np.arange(1, uvs.shape[0] + 1), 0)  # type: ignore[union-attr]
        cols += [np.full((1, c), ord("/"), dtype=np.uint8), np.take(uv_text, uv_indices, axis=1)]
    parts.append(_join(*cols, sep))
    return b"".join(parts)


# ----------------------------------------------------------------------------- PLY


def _ply_bytes(V: FloatArray, sizes: IntArray, corners: IntArray, uvs: FloatArray | None,
               uv_indices: IntArray | None, unit: str, colors: np.ndarray | None = None,
               texture_name: str | None = None) -> bytes:
    n, k = V.shape[0], sizes.size
    vertex_uv = face_uv = None
    if uvs is not None and uv_indices is not None:
        corner_uv = uvs[uv_indices]
        per_vertex = np.zeros((n, 2))
        per_vertex[corners] = corner_uv
        if np.array_equal(per_vertex[corners], corner_uv):
            vertex_uv = per_vertex.astype("<f4")
        else:
            face_uv = corner_uv.astype("<f4")
    count_type, count_dt = ("uchar", "u1") if sizes.max() <= 255 else ("int", "<i4")

    header = ["ply", "format binary_little_endian 1.0", f"comment written by facecap; unit: {unit}"]
    if texture_name is not None:
        header.append(f"comment TextureFile {texture_name}")
    header += [f"element vertex {n}", "property double x", "property double y", "property double z"]
    if vertex_uv is not None:
        header += ["property float s", "property float t"]
    if colors is not None:
        header += ["property uchar red", "property uchar green", "property uchar blue"]
    header += [f"element face {k}", f"property list {count_type} int vertex_indices"]
    if face_uv is not None:
        header.append(f"property list {count_type} float texcoord")
    header.append("end_header\n")

    vfields = [("x", "<f8"), ("y", "<f8"), ("z", "<f8")]
    if vertex_uv is not None:
        vfields += [("s", "<f4"), ("t", "<f4")]
    if colors is not None:
        vfields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    vrec = np.empty(n, dtype=np.dtype(vfields))
    vrec["x"], vrec["y"], vrec["z"] = V[:, 0], V[:, 1], V[:, 2]
    if vertex_uv is not None:
        vrec["s"], vrec["t"] = vertex_uv[:, 0], vertex_uv[:, 1]
    if colors is not None:
        rgb8 = np.rint(np.asarray(colors, dtype=np.float64) * 255.0).clip(0, 255).astype(np.uint8)
        vrec["red"], vrec["green"], vrec["blue"] = rgb8[:, 0], rgb8[:, 1], rgb8[:, 2]

    # faces: records of [count, indices (int32) [, 2*count, uvs (float32)]], vectorised
    csize = np.dtype(count_dt).itemsize
    rec_len = csize + 4 * sizes + (csize + 8 * sizes if face_uv is not None else 0)
    offsets = np.cumsum(rec_len) - rec_len
    out = np.zeros(int(rec_len.sum()), dtype=np.uint8)
    rank = np.arange(corners.size) - np.repeat(np.cumsum(sizes) - sizes, sizes)

    def put(byte_offsets: np.ndarray, values: np.ndarray) -> None:
        raw = np.ascontiguousarray(values).view(np.uint8).reshape(byte_offsets.size, -1)
        out[byte_offsets[:, None] + np.arange(raw.shape[1])] = raw

    put(offsets, sizes.astype(count_dt))
    corner_at = np.repeat(offsets + csize, sizes) + 4 * rank
    put(corner_at, corners.astype("<i4"))
    if face_uv is not None:
        tc_at = offsets + csize + 4 * sizes
        put(tc_at, (2 * sizes).astype(count_dt))
        uv_at = np.repeat(tc_at + csize, sizes) + 8 * rank
        put(uv_at, face_uv)
    return "\n".join(header).encode() + vrec.tobytes() + out.tobytes()

"""Read a surface mesh from OBJ, PLY or glTF, keeping the file's vertex order and count.

OBJ and PLY have their own vectorised readers here: trimesh splits OBJ vertices
along UV seams even with ``process=False`` (the ICT neutral grows from 26,719 to
28,911 vertices), and its PLY reader cannot read binary files that mix triangles
and quads, which is what :func:`facecap.io.write_mesh` writes for quad meshes.
glTF goes through trimesh, which keeps each primitive's vertex array as stored.
"""

from __future__ import annotations

import os
import re
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FacecapWarning, FileFormatError, MeshError
from ..structures import Mesh
from ..typing import FloatArray, IntArray
from ..units import mm_per_unit, normalize_unit
from .mesh_texture import obj_texture, pack_textures, read_texture_image

__all__ = ["read_mesh", "MESH_FORMATS", "MESH_SUFFIXES"]

MESH_FORMATS: dict[str, str] = {".obj": "OBJ", ".ply": "PLY", ".glb": "glTF", ".gltf": "glTF"}
"""File suffix -> the format :func:`read_mesh` reads with it (``facecap --help`` lists these)."""

MESH_SUFFIXES = tuple(MESH_FORMATS)
"""File suffixes :func:`read_mesh` reads (the format is chosen by the suffix)."""

# byte classes: whitespace as numpy's text parser and OBJ/PLY understand it
_WS = np.zeros(256, dtype=bool)
_WS[[9, 10, 11, 12, 13, 32]] = True
_SPACE, _NEWLINE, _SLASH, _HASH = 32, 10, 47, 35


def read_mesh(path: str | os.PathLike[str], *, unit: str | None = None) -> Mesh:
    """Read a polygon mesh, keeping the file's vertex order and count.

    Parameters
    ----------
    path : str or path-like
        A ``.obj``, ``.ply``, ``.glb`` or ``.gltf`` file.
    unit : {'mm', 'cm', 'm', 'in'} or None, optional
        The length unit the file's coordinates are in (mesh files do not say).
        Vertices are converted to mm and the unit is recorded as
        ``Mesh.source_unit``. Default None: ``'m'`` for glTF, whose
        specification fixes metres, and ``'mm'`` for OBJ and PLY.

    Returns
    -------
    Mesh
        ``vertices`` (n, 3) float64 in mm, in file order; ``faces`` (m, 3)
        int64, each polygon fan-triangulated from its first corner
        (``(c0, c1, c2), (c0, c2, c3), ...``, as libigl does); the original
        polygons in ``polygon_sizes`` / ``polygon_indices`` when the file
        has any non-triangle (None when it holds triangles only); ``uvs``
        (u, 2) float64 and per-corner ``uv_indices`` when every face corner
        has a texture coordinate; ``vertex_colors`` (n, 3) float32 in [0, 1]
        (sRGB-encoded, as stored) when every vertex has a colour, else None.

    Raises
    ------
    FileFormatError
        If the file is missing, empty, of an unknown suffix, or holds text
        or numbers that cannot be parsed (the message names the line), or
        vertex colours outside [0, 1] (float) or [0, 255] (8-bit).
    MeshError
        If the file has no faces, or a face refers to a vertex or texture
        coordinate that does not exist (the message names the face and line).

    Warns
    -----
    FacecapWarning
        If only some face corners have texture coordinates; the UVs are dropped.
        If only some OBJ vertices have colours; the colours are dropped (the
        geometry is read as usual).

    Notes
    -----
    OBJ: ``v``, ``vt`` and ``f`` statements are read, with corners written
    ``v``, ``v/vt``, ``v//vn`` or ``v/vt/vn``, 1-based or negative (relative)
    indices, polygons of any size, ``#`` comments and ``\\`` line
    continuations; normals, ``o``, ``g``, ``s``, ``usemtl``, ``mtllib`` and
    other statements are ignored. A ``v`` line of 6 numbers ``x y z r g b``
    (the common colour extension) gives the vertex a colour; colours are read
    only when every ``v`` line has exactly 6 numbers, as floats in [0, 1], or
    as 8-bit values divided by 255 when any value exceeds 1. A ``v`` line of 4
    numbers (``w``) or 7 (``x y z r g b a``) carries no colour read here.
    Line numbers in messages count physical lines, except after a
    ``\\`` continuation.

    PLY: ASCII and binary (either byte order). Reads the ``vertex`` element's
    ``x, y, z`` and texture coordinates (``s, t``, ``u, v``, ``texture_u,
    texture_v`` or ``texture_s, texture_t``) and the ``face`` element's
    ``vertex_indices`` (or ``vertex_index``) and ``texcoord`` lists, and the
    vertex colours ``red, green, blue`` (also ``r, g, b`` or ``diffuse_red,
    ...``): integer types are divided by their maximum (255 for ``uchar``,
    65535 for ``ushort``), floats must lie in [0, 1]; alpha is ignored; other
    properties and elements are skipped.

    glTF (``.glb``, ``.gltf``): read by trimesh with ``process=False``. Every
    triangle primitive is placed by the transform of the one node that uses
    it, and the primitives are concatenated in file order (the order of the
    ``meshes`` array, then of each mesh's primitives), so vertex ``i`` of the
    result is vertex ``i - offset`` of its primitive's accessor. A primitive
    used by several nodes (instancing) is refused, since it has no single
    placement. Vertex colours come from ``COLOR_0`` as trimesh exposes it
    (``visual.vertex_colors``, 8-bit RGBA), kept only when every primitive has
    them; trimesh gives no colour for a primitive without ``COLOR_0``.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "quad.obj"
    >>> _ = p.write_text("v 0 0 0\\nv 1 0 0\\nv 1 1 0\\nv 0 1 0\\nf 1 2 3 4\\n")
    >>> mesh = read_mesh(p, unit="cm")
    >>> mesh.vertices[2]
    array([10., 10.,  0.])
    >>> mesh.faces
    array([[0, 1, 2],
           [0, 2, 3]])
    >>> mesh.polygon_sizes, mesh.source_unit
    (array([4]), 'cm')
    """
    p = Path(os.fspath(path))
    suffix = p.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise FileFormatError(
            f"unknown mesh file type {p.suffix!r}: expected one of {list(MESH_SUFFIXES)}", path=str(p)
        )
    if unit is None:
        unit = "m" if suffix in (".glb", ".gltf") else "mm"
    unit = normalize_unit(unit, name="unit")
    if not p.is_file():
        raise FileFormatError("no such file", path=str(p))
    if p.stat().st_size == 0:
        raise FileFormatError("the file is empty", path=str(p))

    if suffix == ".obj":
        parts = _read_obj(p)
    elif suffix == ".ply":
        parts = _read_ply(p)
    else:
        parts = _read_gltf(p)
    V, sizes, corners, uvs, uv_corners, colors, texture = parts

    if not np.all(np.isfinite(V)):
        bad = int(np.flatnonzero(~np.isfinite(V).all(axis=1))[0])
        raise FileFormatError(f"vertex {bad + 1} has a NaN or infinite coordinate", path=str(p))
    faces = _fan_triangulate(sizes, corners)
    all_triangles = bool(np.all(sizes == 3))
    return Mesh(
        vertices=V * mm_per_unit(unit),
        faces=faces,
        polygon_sizes=None if all_triangles else sizes,
        polygon_indices=None if all_triangles else corners,
        uvs=uvs,
        uv_indices=uv_corners,
        source_unit=unit,
        source_path=str(p),
        vertex_colors=colors,
        texture=texture,
    )


def _fan_triangulate(sizes: IntArray, corners: IntArray) -> IntArray:
    """Triangles ``(c0, c_j, c_j+1)`` for ``j = 1 .. size-2`` of every polygon, in order."""
    starts = np.cumsum(sizes) - sizes
    n_tri = sizes - 2
    poly = np.repeat(np.arange(sizes.size), n_tri)
    j = np.arange(poly.size) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri) + 1
    first = starts[poly]
    return np.stack(
        [corners[first], corners[first + j], corners[first + j + 1]], axis=1
    ).astype(np.int64, copy=False)


# ----------------------------------------------------------------------------- OBJ


class _ObjKind:
    """The lines of one OBJ statement kind, gathered into one text buffer."""

    def __init__(self, buf: np.ndarray, starts: np.ndarray, ends: np.ndarray,
                 key_end: np.ndarray, lines: np.ndarray) -> None:
        self.lines = lines  # 0-based physical line numbers
        if lines.size == 0:
            self.text = np.zeros(0, dtype=np.uint8)
            self.line_offsets = np.zeros(0, dtype=np.int64)
            return
        # consecutive lines are contiguous in the file: copy whole runs at once
        brk = np.flatnonzero(np.diff(lines) != 1) + 1
        run_first = np.r_[lines[0], lines[brk]]
        run_last = np.r_[lines[brk - 1], lines[-1]]
        text = np.concatenate(
            [buf[a : b + 1] for a, b in zip(starts[run_first].tolist(), ends[run_last].tolist())]
        )
        lengths = ends[lines] - starts[lines] + 1
        self.line_offsets = np.cumsum(lengths) - lengths
        # blank the statement keyword ('v', 'vt', 'f' and any indentation)
        key_len = key_end[lines] - starts[lines]
        blank = np.repeat(self.line_offsets, key_len) + (
            np.arange(int(key_len.sum())) - np.repeat(np.cumsum(key_len) - key_len, key_len)
        )
        text[blank] = _SPACE
        # blank '#' comments up to the end of their line
        hashes = np.flatnonzero(text == _HASH)
        if hashes.size:
            nl = np.flatnonzero(text == _NEWLINE)
            stop = nl[np.searchsorted(nl, hashes)]
            mark = np.zeros(text.size + 1, dtype=np.int64)
            np.add.at(mark, hashes, 1)
            np.add.at(mark, stop, -1)
            text[np.cumsum(mark[:-1]) > 0] = _SPACE
        self.text = text

    def tokens(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Start and end (exclusive) offset of every token, and the token count of each line."""
        ws = _WS[self.text]
        edge = np.diff(np.r_[True, ws, True].view(np.int8))
        tok_start = np.flatnonzero(edge == -1)
        tok_end = np.flatnonzero(edge == 1)
        line_of = np.searchsorted(self.line_offsets, tok_start, side="right") - 1
        counts = np.bincount(line_of, minlength=self.lines.size)
        return tok_start, tok_end, counts


def _parse_numbers(text: bytes, dtype: type, expected: int) -> np.ndarray | None:
    """Parse whitespace-separated numbers with numpy's C parser; None unless exactly ``expected``."""
    with warnings.catch_warnings():
        # numpy warns (DeprecationWarning) when it stops at text it cannot parse
        warnings.simplefilter("ignore", DeprecationWarning)
        try:
            values = np.fromstring(text, dtype=dtype, sep=" ")
        except ValueError:
            return None
    return values if values.size == expected else None


def _first_bad_line(kind: _ObjKind, check: Any, name: str, path: Path) -> FileFormatError:
    """Find the first line of ``kind`` with a token ``check`` refuses, for the error message."""
    data = kind.text.tobytes()
    bounds = np.r_[kind.line_offsets, len(data)].tolist()
    for i in range(kind.lines.size):
        for token in data[bounds[i] : bounds[i + 1]].split():
            if not check(token):
                return FileFormatError(
                    f"line {int(kind.lines[i]) + 1}: cannot parse {token.decode(errors='replace')!r} "
                    f"in a {name} statement",
                    path=str(path),
                )
    return FileFormatError(f"cannot parse the {name} statements", path=str(path))


def _is_float(token: bytes) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _is_int(token: bytes) -> bool:
    try:
        int(token)
    except ValueError:
        return False
    return True


def _is_corner(token: bytes) -> bool:
    """``v``, ``v/vt``, ``v//vn`` or ``v/vt/vn`` with integer indices."""
    parts = token.split(b"/")
    if len(parts) == 3 and parts[1] == b"":
        parts = [parts[0], parts[2]]
    return len(parts) <= 3 and all(_is_int(x) for x in parts)


_MeshParts = tuple[FloatArray, IntArray, IntArray, FloatArray | None, IntArray | None, np.ndarray | None,
                   np.ndarray | None]


def _read_obj(path: Path) -> _MeshParts:
    data = path.read_bytes()
    if data.startswith(b"\xef\xbb\xbf"):  # UTF-8 byte-order mark
        data = data[3:]
    if b"\\\n" in data or b"\\\r\n" in data:
        data = data.replace(b"\\\r\n", b" ").replace(b"\\\n", b" ")
    # extra newlines: the last line is terminated and the 2-byte keyword look-ahead stays in bounds
    buf = np.frombuffer(data + b"\n\n\n", dtype=np.uint8)
    ends = np.flatnonzero(buf == _NEWLINE)[:-2]
    starts = np.r_[0, ends[:-1] + 1]
    # keyword start: first non-blank byte (indented lines are rare; handle them one by one)
    key0 = starts.copy()
    indented = np.flatnonzero((buf[starts] == _SPACE) | (buf[starts] == 9))
    for i in indented.tolist():
        line = data[starts[i] : ends[i]]
        key0[i] = starts[i] + len(line) - len(line.lstrip(b" \t"))
    c0, c1, c2 = buf[key0], buf[key0 + 1], buf[key0 + 2]
    is_v = (c0 == ord("v")) & _WS[c1]
    is_vt = (c0 == ord("v")) & (c1 == ord("t")) & _WS[c2]
    is_f = (c0 == ord("f")) & _WS[c1]

    v = _ObjKind(buf, starts, ends, key0 + 1, np.flatnonzero(is_v))
    vt = _ObjKind(buf, starts, ends, key0 + 2, np.flatnonzero(is_vt))
    f = _ObjKind(buf, starts, ends, key0 + 1, np.flatnonzero(is_f))

    V, colors = _obj_vertices(v, path)
    UV = _obj_columns(vt, 2, "vt (texture coordinate)", path) if vt.lines.size else None
    if V.shape[0] == 0:
        raise MeshError("the file has no vertices ('v' lines)", path=str(path))
    if f.lines.size == 0:
        raise MeshError("the file has no faces ('f' lines)", path=str(path))

    # faces: corner tokens and their form (v, v/vt, v//vn, v/vt/vn)
    tok_start, tok_end, sizes = f.tokens()
    small = np.flatnonzero(sizes < 3)
    if small.size:
        i = int(small[0])
        raise FileFormatError(
            f"line {int(f.lines[i]) + 1}: a face needs at least 3 corners, got {int(sizes[i])}",
            path=str(path),
        )
    text = f.text
    slash = np.flatnonzero(text == _SLASH)
    corner_of_slash = np.searchsorted(tok_start, slash, side="right") - 1
    n_slash = np.bincount(corner_of_slash, minlength=tok_start.size)
    double = slash[:-1][np.diff(slash) == 1]
    has_double = np.zeros(tok_start.size, dtype=bool)
    has_double[np.searchsorted(tok_start, double, side="right") - 1] = True
    if np.any(n_slash > 2):
        bad = int(np.searchsorted(f.line_offsets, tok_start[np.argmax(n_slash > 2)], side="right") - 1)
        raise FileFormatError(
            f"line {int(f.lines[bad]) + 1}: a face corner has more than two '/'", path=str(path)
        )
    n_fields = np.where(has_double, 2, n_slash + 1)  # integers per corner
    has_vt = (n_slash >= 1) & ~has_double
    text = text.copy()
    text[slash] = _SPACE
    ints = _parse_numbers(text.tobytes(), np.int64, int(n_fields.sum()))
    if ints is None:
        raise _first_bad_line(f, _is_corner, "f (face)", path)
    first_field = np.cumsum(n_fields) - n_fields
    corner_line = np.repeat(np.arange(f.lines.size), sizes)

    corners = _resolve_obj_indices(
        ints[first_field], np.searchsorted(v.lines, f.lines)[corner_line], V.shape[0],
        f, corner_line, sizes, ("vertex", "vertices"), path,
    )
    uv_corners = None
    if has_vt.all() and UV is not None:
        uv_corners = _resolve_obj_indices(
            ints[first_field + 1], np.searchsorted(vt.lines, f.lines)[corner_line], UV.shape[0],
            f, corner_line, sizes, ("texture coordinate", "texture coordinates"), path,
        )
    elif has_vt.any():
        if UV is None:
            raise MeshError("faces refer to texture coordinates but the file has no 'vt' lines",
                            path=str(path))
        warnings.warn(
            f"{path}: only {int(has_vt.sum())} of {has_vt.size} face corners have texture "
            "coordinates; the UVs are dropped",
            FacecapWarning,
            stacklevel=3,
        )
    if uv_corners is None:
        UV = None
    UV, uv_corners, texture = obj_texture(path, data, starts, f.lines, UV, uv_corners, sizes)
    return V, sizes.astype(np.int64), corners, UV, uv_corners, colors, texture


def _obj_vertices(v: _ObjKind, path: Path) -> tuple[FloatArray, np.ndarray | None]:
    """Vertex positions and, when every ``v`` line has ``x y z r g b``, their colours."""
    if v.lines.size == 0:
        return np.zeros((0, 3)), None
    _, _, counts = v.tokens()
    six = counts == 6
    if not six.any():
        return _obj_columns(v, 3, "v (vertex)", path), None
    if not six.all():
        V = _obj_columns(v, 3, "v (vertex)", path)
        warnings.warn(
            f"{path}: only {int(six.sum())} of {six.size} vertices have colours "
            "('v x y z r g b'); the colours are dropped",
            FacecapWarning,
            stacklevel=4,
        )
        return V, None
    values = _obj_columns(v, 6, "v (vertex)", path)
    rgb = values[:, 3:]
    if not np.all(np.isfinite(rgb)) or rgb.min() < 0 or rgb.max() > 255:
        raise FileFormatError(
            "vertex colours ('v x y z r g b') must be finite and in [0, 1] or [0, 255], got "
            f"[{np.nanmin(rgb):.6g}, {np.nanmax(rgb):.6g}]",
            path=str(path),
        )
    if rgb.max() > 1.0:
        rgb = rgb / 255.0
    return np.ascontiguousarray(values[:, :3]), rgb.astype(np.float32)


def _obj_columns(kind: _ObjKind, columns: int, name: str, path: Path) -> FloatArray:
    """The first ``columns`` numbers of every line of ``kind`` as a float64 array."""
    n = kind.lines.size
    if n == 0:
        return np.zeros((0, columns))
    _, _, counts = kind.tokens()
    short = np.flatnonzero(counts < columns)
    if short.size:
        i = int(short[0])
        raise FileFormatError(
            f"line {int(kind.lines[i]) + 1}: a {name} statement needs {columns} numbers, "
            f"got {int(counts[i])}",
            path=str(path),
        )
    values = _parse_numbers(kind.text.tobytes(), np.float64, int(counts.sum()))
    if values is None:
        raise _first_bad_line(kind, _is_float, name, path)
    if np.all(counts == columns):
        return values.reshape(n, columns)
    first = np.cumsum(counts) - counts
    return values[first[:, None] + np.arange(columns)]


def _resolve_obj_indices(raw: IntArray, defined_before: IntArray, n_defined: int,
                         f: _ObjKind, corner_line: IntArray, sizes: IntArray,
                         what: tuple[str, str], path: Path) -> IntArray:
    """Turn 1-based or negative (relative) OBJ indices into 0-based ones, checking the range."""
    idx = np.where(raw < 0, defined_before + raw, raw - 1)
    bad = (raw == 0) | (idx < 0) | (idx >= n_defined)
    if bad.any():
        c = int(np.argmax(bad))
        line = int(corner_line[c])
        corner = c - int(np.sum(sizes[:line]))
        reason = (
            "OBJ indices start at 1, not 0" if raw[c] == 0
            else f"the file has {n_defined} {what[1]}"
            + (f" ({int(defined_before[c])} defined before this line)" if raw[c] < 0 else "")
        )
        raise MeshError(
            f"line {int(f.lines[line]) + 1}: face {line + 1}, corner {corner + 1} refers to {what[0]} "
            f"{int(raw[c])}, which does not exist: {reason}",
            path=str(path),
        )
    return idx.astype(np.int64, copy=False)


# ----------------------------------------------------------------------------- PLY

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
_PLY_UV_NAMES = (("s", "t"), ("u", "v"), ("texture_u", "texture_v"), ("texture_s", "texture_t"))


class _PlyProperty:
    def __init__(self, name: str, dtype: str, count_dtype: str | None) -> None:
        self.name, self.dtype, self.count_dtype = name, dtype, count_dtype


def _read_ply(path: Path) -> _MeshParts:
    data = path.read_bytes()
    fmt, elements, body = _ply_header(data, path)
    if fmt == "ascii":
        values = _ply_ascii(data[body:], elements, path)
    else:
        values = _ply_binary(data, body, "<" if fmt == "binary_little_endian" else ">", elements, path)

    vertex = values.get("vertex")
    if vertex is None or not all(k in vertex for k in "xyz"):
        raise FileFormatError("no 'vertex' element with x, y, z properties", path=str(path))
    V = np.stack([np.asarray(vertex[k], dtype=np.float64) for k in "xyz"], axis=1)
    face = values.get("face")
    key = None if face is None else next((k for k in ("vertex_indices", "vertex_index") if k in face), None)
    if face is None or key is None or len(face[key][0]) == 0:
        raise MeshError("the file has no faces", path=str(path))
    sizes, corners = face[key]
    sizes = sizes.astype(np.int64)
    corners = corners.astype(np.int64)
    small = np.flatnonzero(sizes < 3)
    if small.size:
        raise FileFormatError(
            f"face {int(small[0])}: a face needs at least 3 corners, got {int(sizes[small[0]])}",
            path=str(path),
        )
    bad = (corners < 0) | (corners >= V.shape[0])
    if bad.any():
        c = int(np.argmax(bad))
        fi = int(np.searchsorted(np.cumsum(sizes), c, side="right"))
        raise MeshError(
            f"face {fi} (0-based) refers to vertex {int(corners[c])}, which does not exist: "
            f"the file has {V.shape[0]} vertices",
            path=str(path),
        )

    uvs = uv_corners = None
    if "texcoord" in face:
        tsizes, tvalues = face["texcoord"]
        if np.array_equal(tsizes, 2 * sizes):
            uvs, uv_corners = np.unique(
                tvalues.astype(np.float64).reshape(-1, 2), axis=0, return_inverse=True
            )
            uv_corners = uv_corners.reshape(-1).astype(np.int64)
        else:
            raise FileFormatError(
                "face texcoord lists must hold two numbers per corner", path=str(path)
            )
    else:
        for su, sv in _PLY_UV_NAMES:
            if su in vertex and sv in vertex:
                uvs = np.stack([vertex[su], vertex[sv]], axis=1).astype(np.float64)
                uv_corners = corners
                break
    texture = None
    if uvs is not None and uv_corners is not None:
        uvs, uv_corners, texture = _ply_texture(data[:body], path, uvs, uv_corners, sizes, face.get("texnumber"))
    return V, sizes, corners, uvs, uv_corners, _ply_colors(vertex, path), texture


def _ply_texture(header: bytes, path: Path, uvs: FloatArray, uv_corners: IntArray, sizes: IntArray,
                 texnumber: Any) -> tuple[FloatArray, IntArray, np.ndarray | None]:
    """The images ``comment TextureFile NAME`` header lines name (MeshLab's convention), packed into one
    atlas by the faces' ``texnumber`` when there are several; the UVs as they come out."""
    names = [m.group(1).decode("utf-8", errors="replace").strip() for m in re.finditer(
        rb"^comment[ \t]+TextureFile[ \t]+([^\r\n]+)", header, re.MULTILINE | re.IGNORECASE)]
    if not names:
        return uvs, uv_corners, None
    try:
        images = [read_texture_image(path.parent / name.replace("\\", "/")) for name in names]
    except FileFormatError as exc:
        warnings.warn(f"{path}: {exc}; the mesh is read without its colour", FacecapWarning, stacklevel=4)
        return uvs, uv_corners, None
    if len(images) == 1:
        return uvs, uv_corners, images[0]
    which = None if texnumber is None or isinstance(texnumber, tuple) else np.asarray(texnumber, dtype=np.int64)
    if which is None or which.shape != sizes.shape or which.min() < 0 or which.max() >= len(images):
        warnings.warn(f"{path}: {len(images)} TextureFile images but no valid per-face 'texnumber'; "
                      "the mesh is read without its colour", FacecapWarning, stacklevel=4)
        return uvs, uv_corners, None
    return pack_textures(images, uvs, uv_corners, np.repeat(which, sizes))


_PLY_COLOR_NAMES = (("red", "green", "blue"), ("r", "g", "b"),
                    ("diffuse_red", "diffuse_green", "diffuse_blue"))


def _ply_colors(vertex: dict[str, Any], path: Path) -> np.ndarray | None:
    """(n, 3) float32 colours in [0, 1] from the vertex element's colour properties, or None."""
    names = next((c for c in _PLY_COLOR_NAMES if all(k in vertex for k in c)), None)
    if names is None:
        return None
    channels = []
    for k in names:
        x = np.asarray(vertex[k])
        if x.dtype.kind in "iu":
            top = np.iinfo(x.dtype).max
            if x.size and x.min() < 0:
                raise FileFormatError(f"vertex colour {k!r} has negative values", path=str(path))
            channels.append(x.astype(np.float64) / top)
        else:
            x = x.astype(np.float64)
            if not np.all(np.isfinite(x)) or (x.size and (x.min() < 0 or x.max() > 1)):
                raise FileFormatError(
                    f"vertex colour {k!r}: float colours must be finite and in [0, 1]",
                    path=str(path),
                )
            channels.append(x)
    return np.stack(channels, axis=1).astype(np.float32)


def _ply_header(data: bytes, path: Path) -> tuple[str, list[tuple[str, int, list[_PlyProperty]]], int]:
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise FileFormatError("not a PLY file (no 'ply' magic or no 'end_header')", path=str(path))
    body = data.find(b"\n", end) + 1
    fmt = None
    elements: list[tuple[str, int, list[_PlyProperty]]] = []
    for number, raw in enumerate(data[:end].decode("ascii", errors="replace").splitlines(), 1):
        words = raw.split()
        if not words or words[0] in ("ply", "comment", "obj_info"):
            continue
        try:
            if words[0] == "format":
                fmt = words[1]
                if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
                    raise ValueError(f"unknown format {fmt!r}")
            elif words[0] == "element":
                elements.append((words[1], int(words[2]), []))
            elif words[0] == "property":
                if not elements:
                    raise ValueError("a property before any element")
                if words[1] == "list":
                    prop = _PlyProperty(words[4], _PLY_TYPES[words[3]], _PLY_TYPES[words[2]])
                else:
                    prop = _PlyProperty(words[2], _PLY_TYPES[words[1]], None)
                elements[-1][2].append(prop)
            else:
                raise ValueError(f"unknown header keyword {words[0]!r}")
        except (IndexError, KeyError, ValueError) as exc:
            raise FileFormatError(f"header line {number}: cannot read {raw!r} ({exc})",
                                  path=str(path)) from None
    if fmt is None:
        raise FileFormatError("the PLY header has no 'format' line", path=str(path))
    return fmt, elements, body


_PlyValues = dict[str, dict[str, Any]]


def _ply_ascii(text: bytes, elements: list[tuple[str, int, list[_PlyProperty]]], path: Path) -> _PlyValues:
    ws = _WS[np.frombuffer(text, dtype=np.uint8)]
    n_tokens = int(np.count_nonzero(np.diff(np.r_[True, ws].view(np.int8)) == -1))
    tokens = _parse_numbers(text, np.float64, n_tokens)
    if tokens is None:
        bad = next(t for t in text.split() if not _is_float(t))
        raise FileFormatError(f"cannot parse {bad.decode(errors='replace')!r} as a number",
                              path=str(path))
    out: _PlyValues = {}
    pos = 0
    for name, count, props in elements:
        lists = [p for p in props if p.count_dtype is not None]
        if not lists:
            width = len(props)
            block = tokens[pos : pos + width * count]
            if block.size != width * count:
                raise FileFormatError(f"element {name!r} is truncated", path=str(path))
            block = block.reshape(count, width)
            out[name] = {p.name: _ascii_cast(block[:, j], p.dtype, name, path) for j, p in enumerate(props)}
            pos += width * count
            continue
        # records with lists: walk them, fast when all lists have the first record's length
        offsets = _ply_walk_ascii(tokens, pos, count, props, name, path)
        out[name] = {}
        for j, p in enumerate(props):
            start = offsets[:, j]
            if p.count_dtype is None:
                out[name][p.name] = _ascii_cast(tokens[start], p.dtype, name, path)
            else:
                n = _list_lengths(_ascii_cast(tokens[start], p.count_dtype, name, path), name, path)
                flat = np.repeat(start + 1, n) + _ranks(n)
                out[name][p.name] = (n, _ascii_cast(tokens[flat], p.dtype, name, path))
        if count:
            pos = int(offsets[-1, -1]) + _prop_span_ascii(tokens, offsets[-1, -1], props[-1])
    return out


def _ascii_cast(values: np.ndarray, dtype: str, name: str, path: Path) -> np.ndarray:
    """ASCII PLY numbers (parsed as float64) as ``dtype``; integer types must get integers."""
    if np.dtype(dtype).kind in "iu" and not np.all(values == np.round(values)):
        raise FileFormatError(f"element {name!r}: expected integers, got fractions", path=str(path))
    return values.astype(dtype)


def _list_lengths(n: np.ndarray, name: str, path: Path) -> np.ndarray:
    n = n.astype(np.int64)
    if np.any(n < 0):
        raise FileFormatError(f"element {name!r}: a list has a negative length", path=str(path))
    return n


def _ranks(n: np.ndarray) -> np.ndarray:
    """0, 1, ..., n[0]-1, 0, 1, ..., n[1]-1, ... as int64."""
    total = int(n.sum())
    return np.arange(total, dtype=np.int64) - np.repeat(np.cumsum(n) - n, n)


def _prop_span_ascii(tokens: np.ndarray, start: int, prop: _PlyProperty) -> int:
    return 1 if prop.count_dtype is None else 1 + int(tokens[start])


def _ply_walk_ascii(tokens: np.ndarray, pos: int, count: int, props: list[_PlyProperty],
                    name: str, path: Path) -> np.ndarray:
    """(count, n_props) token offset of every property of every record."""
    if count == 0:
        return np.zeros((0, len(props)), dtype=np.int64)
    # fast path: every record shaped like the first
    first = []
    p0 = pos
    try:
        for p in props:
            first.append(p0 - pos)
            p0 += _prop_span_ascii(tokens, p0, p)
        width = p0 - pos
        offsets = pos + width * np.arange(count)[:, None] + np.array(first)[None, :]
        if offsets[-1, -1] < tokens.size:
            ok = all(
                np.all(tokens[offsets[:, j]] == tokens[offsets[0, j]])
                for j, p in enumerate(props) if p.count_dtype is not None
            )
            if ok and pos + width * count <= tokens.size:
                return offsets
        # general path: one record at a time
        offsets = np.empty((count, len(props)), dtype=np.int64)
        t = tokens.tolist()
        q = pos
        for r in range(count):
            for j, p in enumerate(props):
                offsets[r, j] = q
                q += 1 if p.count_dtype is None else 1 + int(t[q])
        if q > tokens.size:
            raise IndexError
    except IndexError:
        raise FileFormatError(f"element {name!r} is truncated", path=str(path)) from None
    return offsets


def _ply_binary(data: bytes, body: int, endian: str,
                elements: list[tuple[str, int, list[_PlyProperty]]], path: Path) -> _PlyValues:
    buf = np.frombuffer(data, dtype=np.uint8)
    out: _PlyValues = {}
    pos = body
    for name, count, props in elements:
        lists = [p for p in props if p.count_dtype is not None]
        if not lists:
            dt = np.dtype([(f"p{j}", endian + p.dtype) for j, p in enumerate(props)])
            if pos + dt.itemsize * count > len(data):
                raise FileFormatError(f"element {name!r} is truncated", path=str(path))
            rec = np.frombuffer(data, dtype=dt, count=count, offset=pos)
            out[name] = {p.name: rec[f"p{j}"].astype(p.dtype) for j, p in enumerate(props)}
            pos += dt.itemsize * count
            continue
        offsets, end = _ply_walk_binary(data, pos, count, props, endian, name, path)
        out[name] = {}
        for j, p in enumerate(props):
            if p.count_dtype is None:
                out[name][p.name] = _gather(buf, offsets[:, j], endian + p.dtype)
            else:
                n = _list_lengths(_gather(buf, offsets[:, j], endian + p.count_dtype), name, path)
                size = np.dtype(p.dtype).itemsize
                csize = np.dtype(p.count_dtype).itemsize
                flat = np.repeat(offsets[:, j] + csize, n) + size * _ranks(n)
                out[name][p.name] = (n, _gather(buf, flat, endian + p.dtype).astype(p.dtype))
        pos = end
    return out


def _gather(buf: np.ndarray, offsets: np.ndarray, dtype: str) -> np.ndarray:
    """Values of ``dtype`` stored at byte ``offsets`` of ``buf`` (unaligned)."""
    dt = np.dtype(dtype)
    idx = offsets[:, None] + np.arange(dt.itemsize)
    return np.ascontiguousarray(buf[idx]).view(dt).reshape(-1)


def _ply_walk_binary(data: bytes, pos: int, count: int, props: list[_PlyProperty], endian: str,
                     name: str, path: Path) -> tuple[np.ndarray, int]:
    """(count, n_props) byte offset of every property of every record, and the end offset."""
    if count == 0:
        return np.zeros((0, len(props)), dtype=np.int64), pos
    buf = np.frombuffer(data, dtype=np.uint8)
    sizes = [(np.dtype(p.dtype).itemsize, None if p.count_dtype is None else np.dtype(p.count_dtype).itemsize)
             for p in props]
    try:
        # fast path: every record shaped like the first
        first, q, counts0 = [], pos, []
        for p, (size, csize) in zip(props, sizes):
            first.append(q - pos)
            if csize is None:
                q += size
            else:
                n = int(_gather(buf, np.array([q]), endian + p.count_dtype)[0])
                counts0.append((len(first) - 1, n))
                q += csize + n * size
        width = q - pos
        if pos + width * count <= len(data):
            offsets = pos + width * np.arange(count, dtype=np.int64)[:, None] + np.array(first)
            if all(
                np.all(_gather(buf, offsets[:, j], endian + str(props[j].count_dtype)) == n)
                for j, n in counts0
            ):
                return offsets, pos + width * count
        # general path (mixed polygon sizes): one record at a time
        offsets = np.empty((count, len(props)), dtype=np.int64)
        order = "little" if endian == "<" else "big"
        signed = [p.count_dtype is not None and p.count_dtype.startswith("i") for p in props]
        q = pos
        for r in range(count):
            for j, (size, csize) in enumerate(sizes):
                offsets[r, j] = q
                if csize is None:
                    q += size
                else:
                    q += csize + size * int.from_bytes(data[q : q + csize], order, signed=signed[j])
        if q > len(data):
            raise IndexError
    except IndexError:
        raise FileFormatError(f"element {name!r} is truncated", path=str(path)) from None
    return offsets, q


# ----------------------------------------------------------------------------- glTF


def _read_gltf(path: Path) -> _MeshParts:
    import trimesh

    try:
        with open(path, "rb") as fh:
            scene = trimesh.load_scene(
                fh,
                file_type=path.suffix.lower().lstrip("."),
                resolver=trimesh.resolvers.FilePathResolver(str(path)),
                process=False,
            )
    except Exception as exc:  # trimesh raises many kinds on bad files
        raise FileFormatError(f"cannot read glTF ({type(exc).__name__}: {exc})", path=str(path)) from None

    Vs: list[np.ndarray] = []
    Fs: list[np.ndarray] = []
    UVs: list[np.ndarray | None] = []
    Cs: list[np.ndarray | None] = []
    Ts: list[np.ndarray | None] = []
    decoded: dict[int, np.ndarray] = {}  # one array per image object: primitives sharing a material share it
    offset = 0
    for name, geom in scene.geometry.items():
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue
        nodes = scene.graph.geometry_nodes.get(name, [])
        if len(nodes) > 1:
            raise FileFormatError(
                f"mesh {name!r} is instanced by {len(nodes)} nodes; one placement is needed",
                path=str(path),
            )
        V = np.asarray(geom.vertices, dtype=np.float64)
        if nodes:
            T = np.asarray(scene.graph[nodes[0]][0], dtype=np.float64)
            V = V @ T[:3, :3].T + T[:3, 3]
        Vs.append(V)
        Fs.append(np.asarray(geom.faces, dtype=np.int64) + offset)
        uv = getattr(geom.visual, "uv", None)
        UVs.append(None if uv is None or len(uv) != len(V) else np.asarray(uv, dtype=np.float64))
        Cs.append(_gltf_colors(geom, len(V)))
        Ts.append(_gltf_texture(geom, decoded))
        offset += len(V)
    if not Vs:
        raise MeshError("the file has no triangle meshes", path=str(path))
    V = np.concatenate(Vs)
    F = np.concatenate(Fs)
    uvs = uv_corners = None
    if all(u is not None for u in UVs):
        uvs = np.concatenate(UVs)  # type: ignore[arg-type]
        uv_corners = F.reshape(-1)
    elif any(u is not None for u in UVs):
        warnings.warn(
            f"{path}: only some meshes have texture coordinates; the UVs are dropped",
            FacecapWarning,
            stacklevel=3,
        )
    colors = np.concatenate(Cs) if all(c is not None for c in Cs) else None  # type: ignore[arg-type]
    texture = None
    if uvs is not None and uv_corners is not None and all(t is not None for t in Ts):
        if all(t is Ts[0] for t in Ts):
            texture = Ts[0]
        else:  # each primitive its own image: packed into one atlas
            corner_image = np.repeat(np.arange(len(Fs)), [3 * f.shape[0] for f in Fs])
            uvs, uv_corners, texture = pack_textures(Ts, uvs, uv_corners, corner_image)  # type: ignore[arg-type]
    elif uvs is not None and any(t is not None for t in Ts):
        warnings.warn(f"{path}: only some meshes have a base colour texture; the texture is dropped",
                      FacecapWarning, stacklevel=3)
    return V, np.full(F.shape[0], 3, dtype=np.int64), F.reshape(-1), uvs, uv_corners, colors, texture


def _gltf_texture(geom: Any, decoded: dict[int, np.ndarray]) -> np.ndarray | None:
    """The base colour image of a trimesh primitive's material as (h, w, 3) uint8/uint16, or None."""
    material = getattr(geom.visual, "material", None)
    image = getattr(material, "baseColorTexture", None)
    if image is None:
        image = getattr(material, "image", None)
    if image is None:
        return None
    if id(image) not in decoded:
        if image.mode.startswith("I"):
            rgb = np.repeat(np.asarray(image, dtype=np.uint16)[:, :, None], 3, axis=2)
        else:
            rgb = np.asarray(image.convert("RGB"), dtype=np.uint8)
        decoded[id(image)] = np.ascontiguousarray(rgb)
    return decoded[id(image)]


def _gltf_colors(geom: Any, n: int) -> np.ndarray | None:
    """(n, 3) float32 colours of a trimesh primitive read from ``COLOR_0``, or None."""
    visual = geom.visual
    if getattr(visual, "kind", None) != "vertex":  # trimesh's kind for COLOR_0 colours
        return None
    c = np.asarray(visual.vertex_colors)
    if c.ndim != 2 or c.shape[0] != n or c.shape[1] < 3:
        return None
    c = c[:, :3]
    if c.dtype.kind in "iu":
        return (c.astype(np.float64) / np.iinfo(c.dtype).max).astype(np.float32)
    return np.clip(c.astype(np.float64), 0.0, 1.0).astype(np.float32)

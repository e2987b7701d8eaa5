"""Read a marker-to-scan correspondence map (JSON) and match it to a take.

File format
-----------
A JSON object mapping each marker label to where that marker sits on the
scan, either a vertex index or a 3D point::

    {"Chin": 963, "NoseTop": [1.2, 40.5, 118.0]}

or the same map wrapped with the unit of its points::

    {"units": "cm", "markers": {"Chin": 963, "NoseTop": [0.12, 4.05, 11.8]}}

- An integer is a 0-based vertex index in the scan file's own vertex order.
- A list of three numbers is a point in the **scan's source unit** (the unit
  of the mesh file, ``mesh.source_unit``), or in ``units`` when the wrapped
  form gives it. It is converted to mm and snapped to the closest point of
  the scan's surface, which is stored as a triangle and barycentric weights.
"""

from __future__ import annotations

import json
import math
import os
import warnings
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ..errors import CorrespondenceError, FacecapWarning, FileFormatError, InputError
from ..structures import Correspondence, Mesh
from ..typing import FloatArray, IntArray
from ..units import mm_per_unit, normalize_unit

__all__ = ["CorrespondenceMatch", "read_correspondence", "match_correspondence", "MAP_FORMATS"]

MAP_FORMATS: dict[str, str] = {".json": "JSON"}
"""File suffix -> the format :func:`read_correspondence` reads (``facecap --help`` lists it); the content,
not the suffix, is checked."""


class CorrespondenceMatch(NamedTuple):
    """A map matched to a take's markers (see :func:`match_correspondence`)."""

    correspondence: Correspondence
    """The map, rows in the take's column order."""
    take_columns: IntArray
    """(K,) int64: row k of ``correspondence`` is take column ``take_columns[k]``."""
    ignored_labels: tuple[str, ...]
    """Take markers that the map does not place, in take order."""


def read_correspondence(
    path: str | os.PathLike[str],
    mesh: Mesh,
    *,
    labels: tuple[str, ...] | list[str] | None = None,
) -> Correspondence:
    """Read a JSON marker-to-scan map (format in the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The JSON file.
    mesh : Mesh
        The scan the map refers to; vertex indices are checked against it
        and points are snapped to its surface.
    labels : sequence of str or None, optional
        The take's marker labels. If given, the map is checked and ordered
        against them with :func:`match_correspondence`: markers the take lacks
        raise, take markers the map lacks are ignored with a FacecapWarning,
        and the result's rows follow the take's column order. Default None
        returns the map in file order.

    Returns
    -------
    correspondence : Correspondence
        Labels, ``vertex_indices`` (K, 3) int64, ``weights`` (K, 3) float64,
        ``triangles`` (K,), ``snap_distances`` (K,) mm.

    Raises
    ------
    FileFormatError
        If the file is missing or unreadable.
    CorrespondenceError
        If the JSON is malformed, the map is empty, a label is repeated or
        empty, an entry is neither a non-negative integer vertex index below
        the mesh's vertex count nor three finite numbers, ``units`` is
        unknown, or (with ``labels``) the map names markers the take lacks.

    Notes
    -----
    A point ``p`` is snapped to its closest surface point ``c`` on triangle
    ``t`` (``igl.point_mesh_squared_distance``); its weights are the
    barycentric coordinates of ``c`` in ``t`` (``igl.barycentric_coordinates``),
    with a closest-point-on-edge fallback for degenerate triangles. Vertices
    not used by any triangle are not snap targets.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> V = np.array([[0.0, 0, 0], [10, 0, 0], [0, 10, 0]])
    >>> mesh = Mesh(V, np.array([[0, 1, 2]]))
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "map.json"
    >>> _ = p.write_text('{"a": 2, "b": [2.0, 3.0, 5.0]}')
    >>> corr = read_correspondence(p, mesh)
    >>> corr.points(mesh.vertices).tolist()
    [[0.0, 10.0, 0.0], [2.0, 3.0, 0.0]]
    >>> corr.snap_distances.tolist()
    [0.0, 5.0]
    """
    if not isinstance(mesh, Mesh):
        raise InputError(f"mesh: expected a Mesh, got {type(mesh).__name__}")
    p = Path(os.fspath(path))
    name = str(p)
    if not p.is_file():
        raise FileFormatError("file not found" if not p.exists() else "not a regular file", path=name)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise FileFormatError(f"cannot read the file as UTF-8 text ({exc})", path=name) from None

    def no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key, value in pairs:
            if key in out:
                raise CorrespondenceError(f"label {key!r} appears more than once", path=name)
            out[key] = value
        return out

    try:
        doc = json.loads(text, object_pairs_hook=no_duplicates)
    except json.JSONDecodeError as exc:
        raise CorrespondenceError(
            f"malformed JSON at line {exc.lineno}, column {exc.colno}: {exc.msg}", path=name
        ) from None
    if not isinstance(doc, dict):
        raise CorrespondenceError(f"expected a JSON object of label -> entry, got a {type(doc).__name__}", path=name)

    point_unit = mesh.source_unit
    if "markers" in doc and isinstance(doc["markers"], dict) and set(doc) <= {"markers", "units"}:
        entries = doc["markers"]
        if "units" in doc:
            try:
                point_unit = normalize_unit(str(doc["units"]), name="units")
            except InputError as exc:
                raise CorrespondenceError(exc.message, path=name) from None
    else:
        entries = doc
    if not entries:
        raise CorrespondenceError("the map is empty", path=name)

    n = mesh.n_vertices
    labels_out: list[str] = []
    vertex_rows: list[int] = []
    vertex_ids: list[int] = []
    point_rows: list[int] = []
    points: list[list[float]] = []
    for k, (label, entry) in enumerate(entries.items()):
        if not label.strip():
            raise CorrespondenceError("a marker label is empty", path=name)
        labels_out.append(label)
        if isinstance(entry, int) and not isinstance(entry, bool):
            if not 0 <= entry < n:
                raise CorrespondenceError(
                    f"marker {label!r}: vertex index {entry} out of range (the mesh has {n} vertices, "
                    f"indices 0..{n - 1})",
                    path=name,
                )
            vertex_rows.append(k)
            vertex_ids.append(entry)
        elif (
            isinstance(entry, list)
            and len(entry) == 3
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in entry)
        ):
            point_rows.append(k)
            points.append([float(x) for x in entry])
        else:
            raise CorrespondenceError(
                f"marker {label!r}: expected a non-negative integer vertex index or a point [x, y, z], "
                f"got {json.dumps(entry)[:60]}",
                path=name,
            )

    K = len(labels_out)
    idx = np.zeros((K, 3), dtype=np.int64)
    w = np.zeros((K, 3), dtype=np.float64)
    tri = np.full(K, -1, dtype=np.int64)
    dist = np.zeros(K, dtype=np.float64)
    if vertex_rows:
        idx[vertex_rows] = np.asarray(vertex_ids, dtype=np.int64)[:, None]
        w[vertex_rows, 0] = 1.0
    if point_rows:
        P = np.asarray(points, dtype=np.float64) * mm_per_unit(point_unit)
        t, bary, d = _snap(P, mesh.vertices, mesh.faces)
        idx[point_rows] = mesh.faces[t]
        w[point_rows] = bary
        tri[point_rows] = t
        dist[point_rows] = d
    corr = Correspondence(tuple(labels_out), idx, w, tri, dist, source_path=name)
    if labels is None:
        return corr
    return _match(corr, labels, stacklevel=3).correspondence


def _snap(P: FloatArray, V: FloatArray, F: IntArray) -> tuple[IntArray, FloatArray, FloatArray]:
    """Closest surface points: triangle index, barycentric weights (k, 3), distance (mm)."""
    import igl

    sqrD, I, C = igl.point_mesh_squared_distance(P, V, F)
    I = np.asarray(I, dtype=np.int64)
    A, B, Cc = V[F[I, 0]], V[F[I, 1]], V[F[I, 2]]
    bary = np.asarray(igl.barycentric_coordinates(C, A, B, Cc), dtype=np.float64).reshape(-1, 3)
    bad = ~np.isfinite(bary).all(axis=1)
    for i in np.flatnonzero(bad):  # degenerate triangles only: rare, so a loop is fine
        bary[i] = _segment_weights(C[i], A[i], B[i], Cc[i])
    bary = np.clip(bary, 0.0, None)
    bary /= bary.sum(axis=1, keepdims=True)
    return I, bary, np.sqrt(np.maximum(sqrD, 0.0))


def _segment_weights(c: FloatArray, a: FloatArray, b: FloatArray, d: FloatArray) -> FloatArray:
    """Weights of ``c`` on the longest edge of a degenerate triangle (a, b, d)."""
    corners = (a, b, d)
    best = (0.0, 0, 1)
    for i, j in ((0, 1), (1, 2), (2, 0)):
        length = float(np.sum((corners[j] - corners[i]) ** 2))
        if length > best[0]:
            best = (length, i, j)
    length, i, j = best
    out = np.zeros(3)
    if length == 0.0:
        out[0] = 1.0
        return out
    s = float(np.clip(np.dot(c - corners[i], corners[j] - corners[i]) / length, 0.0, 1.0))
    out[i], out[j] = 1.0 - s, s
    return out


def match_correspondence(corr: Correspondence, take_labels: tuple[str, ...] | list[str]) -> CorrespondenceMatch:
    """Match a map to a take's markers.

    Parameters
    ----------
    corr : Correspondence
        The map, from :func:`read_correspondence`.
    take_labels : sequence of str, length M
        The take's marker labels, in column order.

    Returns
    -------
    match : CorrespondenceMatch
        ``correspondence``: the map with rows in take column order;
        ``take_columns`` (K,) int64: the take column of each row, so that
        ``take.positions[:, take_columns]`` lines up with it;
        ``ignored_labels``: take markers the map does not place.

    Raises
    ------
    CorrespondenceError
        If the map names markers that are not in the take.

    Warns
    -----
    FacecapWarning
        If some take markers are not in the map; they are listed and ignored.

    Examples
    --------
    >>> corr = Correspondence(("b", "a"), [[1, 1, 1], [0, 0, 0]], [[1, 0, 0], [1, 0, 0]])
    >>> m = match_correspondence(corr, ["a", "b"])
    >>> m.correspondence.labels, m.take_columns.tolist(), m.ignored_labels
    (('a', 'b'), [0, 1], ())
    """
    return _match(corr, take_labels, stacklevel=3)


def _match(corr: Correspondence, take_labels: tuple[str, ...] | list[str], *, stacklevel: int) -> CorrespondenceMatch:
    if not isinstance(corr, Correspondence):
        raise InputError(f"corr: expected a Correspondence, got {type(corr).__name__}")
    take = [str(s) for s in take_labels]
    in_take = set(take)
    extra = [s for s in corr.labels if s not in in_take]
    if extra:
        raise CorrespondenceError(
            f"the map places {len(extra)} marker(s) that the take does not have: {extra}", path=corr.source_path
        )
    in_map = set(corr.labels)
    ignored = tuple(s for s in take if s not in in_map)
    if ignored:
        warnings.warn(
            f"{len(ignored)} take marker(s) are not in the marker map, so they do not drive the face (they may still "
            f"give the head's motion): {list(ignored)}",
            FacecapWarning,
            stacklevel=stacklevel,
        )
    columns = np.array([i for i, s in enumerate(take) if s in in_map], dtype=np.int64)
    ordered = corr.select([take[i] for i in columns])
    return CorrespondenceMatch(ordered, columns, ignored)

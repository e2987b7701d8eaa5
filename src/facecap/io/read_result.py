"""One reader for every finished result folder, whichever form holds its frames.

A result folder (``facecap animate``, ``facecap blend``) holds its frames as
``vertices.npy`` (the default), as the exact compact rig in ``rig/`` (see
:mod:`facecap.io.result_rig`), or both. :func:`read_result` opens either and
gives frames, or blocks of frames, lazily: nothing is computed or paged in
until asked for. ``facecap info``, ``facecap evaluate`` and every export read
through it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from ..errors import FileFormatError, InputError
from ..structures import Mesh
from ..units import mm_per_unit
from .result_rig import ResultRig, check_frame_range, read_rig
from .result_layout import file_sizes, read_performance_info

__all__ = ["read_result", "Result", "MESH_FILE"]

MESH_FILE = "mesh.npz"
"""The scan's topology, UVs and rest vertices in a result folder (for exports made after the run)."""


@dataclass(frozen=True, eq=False)
class Result:
    """A finished result folder, opened.

    Attributes
    ----------
    path : Path
    info : dict
        ``performance.json``.
    n_frames, n_vertices : int
    rate : float, Hz
    units : str
        Unit of the frames (the scan's own), as in ``vertices.npy``.
    mesh : Mesh
        The scan: rest vertices (mm), triangles, polygons and UVs.
    rig : ResultRig or None
        The exact compact form, when the folder has one.
    head_motion : (T, 4, 4) float64 array or None
        Rigid head motion per frame (translation in :attr:`units`) of a stabilised result.
    markers : (T, K, 3) float32 array or None
        Where the markers drive the face, in the face's frame and :attr:`units`.
    marker_labels : tuple of str
    """

    path: Path
    info: dict[str, Any]
    n_frames: int
    n_vertices: int
    rate: float
    units: str
    mesh: Mesh
    rig: ResultRig | None = None
    head_motion: np.ndarray | None = None
    markers: np.ndarray | None = None
    marker_labels: tuple[str, ...] = ()
    _vertices: np.ndarray | None = field(default=None, repr=False)

    @property
    def has_vertices(self) -> bool:
        """Whether the folder holds ``vertices.npy``."""
        return self._vertices is not None

    @property
    def mm_per_unit(self) -> float:
        """Millimetres per unit of the frames."""
        return mm_per_unit(self.units)

    def frames(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """Frames ``start`` to ``stop`` as a float32 ``(stop - start, n, 3)`` array in :attr:`units`.

        From ``vertices.npy`` when present (a copy out of the memory map),
        else evaluated from the rig.
        """
        start, stop = check_frame_range(start, stop, self.n_frames)
        if self._vertices is not None:
            return np.array(self._vertices[start:stop], dtype=np.float32)
        return self.rig.frames(start, stop)

    def blocks(self, batch_frames: int = 64, *, start: int = 0, stop: int | None = None) -> Iterator[tuple[int, np.ndarray]]:
        """Yield ``(first_frame, frames)`` blocks of at most ``batch_frames`` frames, in order."""
        start, stop = check_frame_range(start, stop, self.n_frames)
        if batch_frames < 1:
            raise InputError(f"batch_frames: expected a positive integer, got {batch_frames}")
        for lo in range(start, stop, batch_frames):
            yield lo, self.frames(lo, min(lo + batch_frames, stop))

    def files(self) -> dict[str, int]:
        """Every file in the folder (relative path) with its size in bytes, ``performance.json`` less."""
        return file_sizes(self.path)


def read_result(path: str | os.PathLike[str]) -> Result:
    """Open a finished result folder.

    Parameters
    ----------
    path : str or Path
        A folder written by ``facecap animate`` or ``facecap blend``.

    Returns
    -------
    Result

    Raises
    ------
    InputError
        If the folder is not a finished result (no ``performance.json``), has
        neither ``vertices.npy`` nor a rig, or its parts disagree (frame or
        vertex counts, a rig whose basis and coefficients disagree).
    """
    folder = Path(path)
    if not folder.is_dir():
        raise InputError("is not a folder (a facecap result folder was expected)", path=str(folder))
    info = read_performance_info(folder)
    T, n = int(info.get("n_frames", -1)), int(info.get("n_vertices", -1))
    units = str(info.get("units", "mm"))

    vertices = None
    vertices_path = folder / "vertices.npy"
    if vertices_path.is_file():
        try:
            vertices = np.load(vertices_path, mmap_mode="r")
        except ValueError as exc:
            raise FileFormatError(f"not a readable .npy ({exc})", path=str(vertices_path)) from None
        if vertices.shape != (T, n, 3):
            raise InputError(f"has shape {vertices.shape}; performance.json states ({T}, {n}, 3)", path=str(vertices_path))
    rig = read_rig(folder / "rig") if (folder / "rig").is_dir() else None
    if rig is not None and (rig.n_frames, rig.n_vertices) != (T, n):
        raise InputError(f"the rig holds {rig.n_frames} frames x {rig.n_vertices} vertices; "
                         f"performance.json states {T} x {n}", path=str(folder / "rig"))
    if vertices is None and rig is None:
        raise InputError("holds neither vertices.npy nor a rig/ folder: no frames to read", path=str(folder))

    mesh = _read_mesh(folder, info, vertices, rig)
    head_motion = _optional_array(folder / "head_motion.npy", (T, 4, 4), np.float64)
    markers = _optional_array(folder / "markers.npy", None, np.float32)
    labels = tuple(info.get("markers", ()))
    if markers is not None and (markers.ndim != 3 or markers.shape[0] != T or markers.shape[1] != len(labels)):
        raise InputError(f"has shape {markers.shape}; expected ({T}, {len(labels)}, 3) for the labels of "
                         "performance.json", path=str(folder / "markers.npy"))
    return Result(path=folder, info=info, n_frames=T, n_vertices=n, rate=float(info["rate"]), units=units,
                  mesh=mesh, rig=rig, head_motion=head_motion, markers=markers,
                  marker_labels=labels if markers is not None else (), _vertices=vertices)


def _read_mesh(folder: Path, info: dict[str, Any], vertices: np.ndarray | None, rig: ResultRig | None) -> Mesh:
    """The scan from ``mesh.npz``; for folders written before it existed, ``faces.npy`` and the first frame."""
    scale = mm_per_unit(str(info.get("units", "mm")))
    path = folder / MESH_FILE
    if path.is_file():
        try:
            with np.load(path, allow_pickle=False) as data:
                arrays = {k: data[k] for k in data.files}
            return Mesh(
                arrays["rest"].astype(np.float64) * scale, arrays["faces"],
                polygon_sizes=arrays.get("polygon_sizes"), polygon_indices=arrays.get("polygon_indices"),
                uvs=arrays.get("uvs"), uv_indices=arrays.get("uv_indices"),
                source_unit=str(info.get("units", "mm")), source_path=str(path),
            )
        except (KeyError, ValueError, OSError) as exc:
            raise FileFormatError(f"not a readable facecap mesh ({exc})", path=str(path)) from None
    faces_path = folder / "faces.npy"
    if not faces_path.is_file():
        raise InputError(f"has neither {MESH_FILE} nor faces.npy", path=str(folder))
    rest = rig.rest if rig is not None else vertices[int(info.get("rest_frame", 0))]
    return Mesh(np.asarray(rest, np.float64) * scale, np.load(faces_path), source_unit=str(info.get("units", "mm")))


def _optional_array(path: Path, shape: tuple[int, ...] | None, dtype: Any) -> np.ndarray | None:
    if not path.is_file():
        return None
    try:
        arr = np.load(path).astype(dtype, copy=False)
    except ValueError as exc:
        raise FileFormatError(f"not a readable .npy ({exc})", path=str(path)) from None
    if shape is not None and arr.shape != shape:
        raise InputError(f"has shape {arr.shape}, expected {shape}", path=str(path))
    return arr

"""Streamed export of an animated mesh to Alembic (``.abc``, Ogawa).

Layout of the archive::

    /Head            Xform: identity (one static sample), or the head motion per frame
    /Head/Face       PolyMesh: the mesh's polygons, face-varying indexed
                     UVs ("uv") when it has UVs, and one positions sample
                     per frame on a uniform time sampling of 1 / rate
                     seconds starting at 0 (frame k at k / rate seconds)

Alembic lists each polygon's corners clockwise (seen from the side its normal
points to); facecap's meshes, like OBJ, PLY and USD, list them
counter-clockwise. So every polygon's corners, and its UV indices with them,
are written in reverse order: what Blender's and Maya's exporters write and
what their importers undo (Blender's ``abc_reader_mesh.cc``: "Alembic data is
stored in the reverse order").

Written with ``alembic3d``, the only Alembic wheel on PyPI: an unofficial
repackaging of the Alembic project's own Python bindings (PyAlembic), not
affiliated with or supported by the Alembic project. It is an optional
dependency (``pip install "facecap[alembic]"``), imported only when an
Alembic file is written.

Memory holds one frame block: Ogawa writes each sample's data as it is set.
The archive is written to a hidden temporary name and renamed once it is
closed, so a failed export leaves nothing behind.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from ..errors import InputError
from ..structures import Mesh
from ..validate import as_positive
from .atomic_write import atomic_path
from .frame_blocks import as_frame_count, check_frame_blocks, path_with_suffix
from .write_mesh import check_uvs

__all__ = ["write_alembic", "import_alembic"]

_XFORM_NAME = "Head"
_MESH_NAME = "Face"


def import_alembic() -> tuple[Any, Any, Any, Any]:
    """``(Abc, AbcGeom, AbcCoreAbstract, imath)`` from alembic3d, the optional package Alembic needs.

    Also how a job checks, before its long work, that an Alembic export can be written.

    Raises
    ------
    InputError
        Naming the extra to install (``pip install "facecap[alembic]"``) when alembic3d is missing.
    """
    try:
        from alembic3d import Abc, AbcCoreAbstract, AbcGeom
        import imath  # PyImath, shipped inside the alembic3d wheel
    except ImportError as exc:
        raise InputError(
            f'writing Alembic needs the optional alembic3d package ({exc}): pip install "facecap[alembic]"'
        ) from None
    return Abc, AbcGeom, AbcCoreAbstract, imath


def write_alembic(
    path: str | os.PathLike[str],
    mesh: Mesh,
    blocks: Iterable[tuple[int, Any]],
    *,
    n_frames: int,
    rate: float,
    unit_scale: float = 1.0,
    head_motion: Any = None,
    progress: bool = False,
) -> Path:
    """Write an animated mesh to an Alembic archive from a stream of frame blocks.

    Parameters
    ----------
    path : str or path-like
        The ``.abc`` file to write (replaced if it exists, only once the
        archive is complete).
    mesh : Mesh
        The mesh whose topology and UVs are written: its export polygons
        (:meth:`~facecap.Mesh.export_polygons`) and ``uvs`` (face-varying
        through ``uv_indices``, or one per vertex without them). Its
        vertices are not written: the positions come from ``blocks``.
    blocks : iterable of (int, (b, n, 3) float32 array)
        ``(start, block)`` pairs: ``block`` holds the vertex positions of
        frames ``start .. start + b - 1`` in ``mesh``'s vertex order; in order,
        without gaps, adding up to ``n_frames`` frames.
    n_frames : int
        Number of frames T, at least 1.
    rate : float
        Frame rate in Hz: the time sampling's interval is ``1 / rate`` seconds.
    unit_scale : float, optional
        Factor applied to every position before it is written, to reach the
        client's unit (Alembic stores no unit): for example 0.001 from mm
        blocks for Blender (1 unit = 1 m) or 0.1 for Maya (1 unit = 1 cm);
        default 1.0 writes the blocks as given.
    head_motion : (n_frames, 4, 4) array, optional
        Rigid motion per frame (column-vector convention, translation in the
        blocks' unit) written as the ``/Head`` Xform's samples, so a stabilised
        result plays where the capture saw it; default None: an identity Xform.
    progress : bool, optional
        Show a tqdm progress bar; default False.

    Returns
    -------
    path : pathlib.Path
        The file written.

    Raises
    ------
    InputError
        If alembic3d is not installed, an argument is invalid, the UVs do not
        match the polygons, the folder does not exist, a block is out of
        order, of the wrong shape or holds NaN or infinite values, or the
        stream ends before ``n_frames`` frames. No file is left behind.

    Notes
    -----
    Reading it back with alembic3d: ``ISampleSelector(x)`` with a number
    selects by time in seconds (``k / rate`` for frame k), not by sample index.

    Examples
    --------
    >>> import numpy as np, os, tempfile
    >>> from facecap.structures import Mesh
    >>> V = np.array([[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0]], float)
    >>> quad = Mesh(V, [[0, 1, 2], [0, 2, 3]], polygon_sizes=[4], polygon_indices=[0, 1, 2, 3])
    >>> frames = np.stack([V, V + 1.0]).astype(np.float32)
    >>> out = write_alembic(os.path.join(tempfile.mkdtemp(), "take.abc"), quad, [(0, frames)],
    ...                     n_frames=2, rate=60.0)
    >>> out.stat().st_size > 0
    True
    """
    final = path_with_suffix(path, ".abc")
    if not isinstance(mesh, Mesh):
        raise InputError(f"mesh: expected a facecap Mesh, got {type(mesh).__name__}")
    n_frames = as_frame_count(n_frames, name="n_frames")
    rate_hz = as_positive(rate, name="rate")
    scale = as_positive(unit_scale, name="unit_scale")
    if not final.parent.is_dir():
        raise InputError("cannot write: the folder does not exist", path=str(final))
    sizes, corners = mesh.export_polygons()
    file_order = _clockwise_corner_order(sizes)
    face_counts = np.ascontiguousarray(sizes, dtype=np.int32)
    face_indices = np.ascontiguousarray(corners[file_order], dtype=np.int32)
    uv = _file_order_uvs(mesh, corners, file_order)
    motion = None
    if head_motion is not None:
        motion = np.asarray(head_motion, dtype=np.float64)
        if motion.shape != (n_frames, 4, 4) or not np.all(np.isfinite(motion)):
            raise InputError(f"head_motion: expected finite ({n_frames}, 4, 4) transforms, got {motion.shape}")
    modules = import_alembic()
    with atomic_path(final) as tmp:
        _write_archive(tmp, modules, face_counts, face_indices, uv, blocks, n_frames=n_frames,
                       n_vertices=mesh.n_vertices, rate=rate_hz, scale=scale, path=final, progress=progress,
                       motion=motion)
    return final


def _clockwise_corner_order(sizes: np.ndarray) -> np.ndarray:
    """Index, into the corner list, of each corner in file order: every polygon's corners reversed.

    Corner ``p`` of a polygon starting at ``s`` with ``c`` corners takes corner
    ``s + c - 1 - (p - s)``.
    """
    sizes = np.asarray(sizes, dtype=np.int64)
    starts = np.cumsum(sizes) - sizes
    owner = np.repeat(np.arange(sizes.size), sizes)
    return 2 * starts[owner] + sizes[owner] - 1 - np.arange(int(sizes.sum()))


def _file_order_uvs(mesh: Mesh, corners: np.ndarray, file_order: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(uvs float32 (u, 2), per-corner indices in file order)``, or None without UVs."""
    if mesh.uvs is None:
        return None
    uvs = np.asarray(mesh.uvs)
    if mesh.uv_indices is None:  # one UV per vertex: index them by the corners' vertices
        if uvs.ndim != 2 or uvs.shape != (mesh.n_vertices, 2) or not np.all(np.isfinite(uvs)):
            raise InputError(
                f"mesh.uvs: without uv_indices expected a finite ({mesh.n_vertices}, 2) array, got shape {uvs.shape}"
            )
        uv_indices = np.asarray(corners)
    else:
        uv_indices = np.asarray(mesh.uv_indices)
        check_uvs(uvs, uv_indices, corners.size)
    return np.ascontiguousarray(uvs, dtype=np.float32), uv_indices[file_order]


def _write_archive(
    tmp: Path,
    modules: tuple[Any, Any, Any, Any],
    face_counts: np.ndarray,
    face_indices: np.ndarray,
    uv: tuple[np.ndarray, np.ndarray] | None,
    blocks: Iterable[tuple[int, Any]],
    *,
    n_frames: int,
    n_vertices: int,
    rate: float,
    scale: float,
    path: Path,
    progress: bool,
    motion: np.ndarray | None = None,
) -> None:
    """Write the archive to ``tmp`` and close it (Alembic writes the file when the archive is released)."""
    Abc, AbcGeom, AbcCoreAbstract, imath = modules
    archive = xform = poly = schema = None
    try:
        try:
            archive = Abc.OArchive(str(tmp))
        except RuntimeError as exc:
            raise InputError(f"could not create the Alembic archive ({exc})", path=str(path)) from None
        sampling = archive.addTimeSampling(AbcCoreAbstract.TimeSampling(1.0 / rate, 0.0))
        if motion is None:
            xform = AbcGeom.OXform(archive.getTop(), _XFORM_NAME)
            xform.getSchema().set(AbcGeom.XformSample())  # identity
        else:
            xform = AbcGeom.OXform(archive.getTop(), _XFORM_NAME, sampling)
            for M in motion:
                row_major = M.T.copy()  # Alembic (Imath) matrices act on row vectors: translation in the last row
                row_major[3, :3] *= scale
                sample = AbcGeom.XformSample()
                sample.setMatrix(imath.M44d(*[tuple(map(float, row)) for row in row_major]))
                xform.getSchema().set(sample)
        poly = AbcGeom.OPolyMesh(xform, _MESH_NAME, sampling)
        schema = poly.getSchema()
        counts_array = imath.IntArrayFromBuffer(face_counts)
        indices_array = imath.IntArrayFromBuffer(face_indices)
        uv_sample = None
        if uv is not None:
            uv_values, uv_indices = uv
            # PyImath has no unsigned buffer constructor; float64 holds every index exactly.
            uv_index_array = imath.UnsignedIntArray(imath.DoubleArrayFromBuffer(uv_indices.astype(np.float64)))
            uv_sample = AbcGeom.OV2fGeomParamSample(imath.V2fArrayFromBuffer(uv_values), uv_index_array,
                                                   AbcGeom.GeometryScope.kFacevaryingScope)
        with tqdm(total=n_frames, unit="frame", desc="Alembic", disable=not progress, leave=False) as bar:
            for start, block in check_frame_blocks(blocks, n_frames=n_frames, n_vertices=n_vertices, path=path):
                for j in range(block.shape[0]):
                    points = np.multiply(block[j], scale, dtype=np.float32)
                    if scale > 1.0 and not np.all(np.isfinite(points)):  # scaled up past the float32 range
                        raise InputError(f"blocks: frame {start + j} times unit_scale={scale:g} overflows float32",
                                         path=str(path))
                    positions = imath.V3fArrayFromBuffer(points)
                    if start + j == 0:  # topology and UVs once; later samples repeat them
                        if uv_sample is None:
                            sample = AbcGeom.OPolyMeshSchemaSample(positions, indices_array, counts_array)
                        else:
                            sample = AbcGeom.OPolyMeshSchemaSample(positions, indices_array, counts_array,
                                                                   uv_sample)
                    else:
                        sample = AbcGeom.OPolyMeshSchemaSample()
                        sample.setPositions(positions)
                    schema.set(sample)
                bar.update(block.shape[0])
    finally:
        # Release every writer object, children first, so the archive is finished on disk (or
        # abandoned) before atomic_path renames or removes the file, even while a traceback
        # still holds this frame.
        schema = poly = xform = None
        archive = None

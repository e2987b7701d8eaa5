"""Streamed output of an animated scan: the output folder facecap writes.

Layout of a finished folder (see ``docs/output_format.md``):

- ``vertices.npy``: float32 ``(T, n, 3)`` in the scan's own coordinates, units
  and vertex order; written frame block by frame block, readable with
  ``np.load(path, mmap_mode="r")``. On by default; ``vertices=False`` leaves
  it out where the result is a rig.
- ``rig/``: the exact compact form (:mod:`facecap.io.result_rig`) of a result
  linear in its per-frame coefficients, written by :meth:`PerformanceWriter.write_rig`.
- ``faces.npy``: int64 ``(m, 3)`` triangles; ``mesh.npz``: the scan's rest
  vertices, triangles, polygons and UVs (for exports made later).
- ``performance.json``: rate, units, frame count, source files, parameters,
  and every file written with its size.
- optional exports: ``obj/frame_000000.obj ...``, ``ply/...``, ``performance.usdc``
  (time-sampled points, streamed with the frames) and, made from the finished
  frames through :func:`facecap.io.read_result`, ``performance_rig.usdc``
  (UsdSkel blend shapes), ``performance.glb``, ``.mdd``, ``.pc2``, ``.abc``
  (:func:`facecap.pipelines.export_result`, called by :func:`facecap.pipelines.finish_result`).
- ``report.html``: the run's figures, plots and pictures in one page, linking
  ``review.html`` (the result played in the browser) when a glTF was written.
- whatever else the caller adds (``report.json``, pictures).

Everything is written into a hidden staging folder beside the destination and
renamed onto it only when the run finishes, so an interrupted or failed run
never leaves a folder that looks finished. A destination holding an earlier
result is refused unless ``overwrite`` (``--overwrite``) is given
(:func:`facecap.io.atomic_write.atomic_folder`); a job checks it before its long
work with :func:`check_result_destination`. Paths ``performance.json`` records
(``source_files``) are final: relative to the folder when inside it, else
absolute, never a staging name (:func:`facecap.io.atomic_write.recorded_path`).
"""

from __future__ import annotations

import json
import os
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np
from tqdm.auto import tqdm

from ..errors import InputError
from ..structures import Mesh
from ..units import mm_per_unit
from .atomic_write import atomic_folder, check_folder_destination, recorded_path
from .result_layout import PERFORMANCE_FILE, STREAMED_FORMATS, WORLD_FRAME_FORMATS, file_sizes, parse_export_formats

__all__ = ["PerformanceWriter", "check_result_destination"]

class _NpyStream:
    """Append frames to a ``.npy`` file whose header already states the final shape.

    Plain ``write`` calls, not a memory map: dirty pages of a writable map count
    toward the process's resident memory, which would then grow with the take.
    """

    def __init__(self, path: Path, shape: tuple[int, ...], dtype: np.dtype) -> None:
        self.path = path
        self.shape = shape
        self.dtype = np.dtype(dtype)
        self._file = open(path, "wb")
        header = {"descr": np.lib.format.dtype_to_descr(self.dtype), "fortran_order": False, "shape": shape}
        np.lib.format.write_array_header_1_0(self._file, header)
        self.frames_written = 0

    def write(self, block: np.ndarray) -> None:
        if block.dtype != self.dtype or block.shape[1:] != self.shape[1:]:
            raise InputError(f"frame block: expected {self.shape[1:]} {self.dtype}, got {block.shape} {block.dtype}")
        np.ascontiguousarray(block).tofile(self._file)
        self.frames_written += block.shape[0]

    def close(self) -> None:
        self._file.close()


class PerformanceWriter:
    """Write an animated scan frame block by frame block into an output folder.

    Parameters
    ----------
    out_dir : str or Path
        Destination folder. If it exists it must be empty, or hold an earlier
        facecap result and ``overwrite`` be True (it is replaced only once
        this run succeeds).
    mesh : Mesh
        The scan: topology, UVs and source unit of the output.
    rate : float
        Frame rate in Hz.
    n_frames : int
        Number of frames that will be written.
    exports : iterable of str, optional
        Exports (:data:`EXPORT_FORMATS`). ``usd``, ``obj`` and ``ply`` are
        streamed with the frames (``usd`` also gets ``performance_rig.usdc``
        when a rig is written); the others are made from the finished frames
        before the folder is moved into place.
    vertices : bool, default True
        Write ``vertices.npy``. Without it the result needs a rig
        (:meth:`write_rig`), and frames are computed only for streamed exports.
    export_options : dict, optional
        What the job passes to :func:`facecap.pipelines.export_result` for the exports made from the
        finished frames (e.g. ``gltf_targets``; :func:`facecap.pipelines.finish_result`).
    overwrite : bool, default False
        Replace an earlier result in ``out_dir``; without it one is refused
        (:class:`~facecap.errors.InputError`), here and again at the rename.

    Examples
    --------
    Use as a context manager; leaving it by an exception discards everything::

        with PerformanceWriter(out, mesh=scan, rate=60.0, n_frames=T) as writer:
            for start, block_mm in blocks:
                writer.write_frames(start, block_mm)
            writer.finish({"source": ...})
    """

    def __init__(
        self,
        out_dir: str | os.PathLike[str],
        *,
        mesh: Mesh,
        rate: float,
        n_frames: int,
        exports: Iterable[str] = (),
        vertices: bool = True,
        export_options: dict[str, Any] | None = None,
        overwrite: bool = False,
    ) -> None:
        self.out_dir = Path(out_dir)
        self.mesh = mesh
        self.rate = float(rate)
        self.n_frames = int(n_frames)
        self.exports = tuple(parse_export_formats(exports))
        self._folder = atomic_folder(self.out_dir, marker_file=PERFORMANCE_FILE, overwrite=overwrite)
        self.staging = self._folder.__enter__()
        self._unit_scale = np.float32(1.0 / mm_per_unit(mesh.source_unit))
        self._npy = (_NpyStream(self.staging / "vertices.npy", (self.n_frames, mesh.n_vertices, 3), np.dtype("<f4"))
                     if vertices else None)
        self.export_options = dict(export_options or {})
        self._rig = None
        self._rig_written: Future[Any] | None = None
        self._frames_written = 0
        self._usd = None
        if "usd" in self.exports and vertices:
            from .write_usd import UsdPerformanceWriter

            self._usd = UsdPerformanceWriter(self.staging / "performance.usdc", mesh, self.rate, self.n_frames)
        for fmt in ("obj", "ply"):
            if fmt in self.exports:
                (self.staging / fmt).mkdir()
        self._metadata_written = False
        self._finished = False

    def __enter__(self) -> "PerformanceWriter":
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is not None or not self._finished:
            self.abort()

    @property
    def frames_written(self) -> int:
        """Frames written so far."""
        return self._frames_written

    @property
    def needs_frames(self) -> bool:
        """Whether anything is written frame by frame (``vertices.npy`` or a streamed export)."""
        return self._npy is not None or self._usd is not None or "obj" in self.exports or "ply" in self.exports

    def write_rig(self, rig: Any, *, precision: str = "float32") -> None:
        """Write the result's exact compact form into ``rig/`` (see :mod:`facecap.io.result_rig`).

        Parameters
        ----------
        rig : ResultRig
            In the scan's source unit, like ``vertices.npy``.
        precision : {'float32', 'int16'}, default 'float32'
            Storage of the basis; int16 halves it within the bound ``rig.json`` states.
        """
        from .result_rig import RIG_PRECISIONS, write_rig

        if precision not in RIG_PRECISIONS:
            raise InputError(f"rig precision: expected one of {list(RIG_PRECISIONS)}, got {precision!r}")
        if (rig.n_frames, rig.n_vertices) != (self.n_frames, self.mesh.n_vertices):
            raise InputError(f"rig: {rig.n_frames} frames x {rig.n_vertices} vertices, the result has "
                             f"{self.n_frames} x {self.mesh.n_vertices}")
        self._wait_for_rig()  # a rig given again replaces the first only once that is on disk
        self._rig = rig.quantized() if precision == "int16" else rig
        # Written on a second thread (the file writes release the GIL): the caller goes on with its
        # report while 0.26 GB go to disk at 700k vertices; finish() and abort() wait for it.
        self._rig_writer = ThreadPoolExecutor(1, thread_name_prefix="facecap-rig")
        self._rig_written = self._rig_writer.submit(write_rig, self.staging / "rig", self._rig)

    def _wait_for_rig(self) -> None:
        """Wait until ``rig/`` is on disk; raise what writing it raised."""
        if self._rig_written is not None:
            written, self._rig_written = self._rig_written, None
            try:
                written.result()
            finally:
                self._rig_writer.shutdown()

    def stream_rig(self, *, batch_frames: int = 64, head_pose: np.ndarray | None = None,
                   progress: bool = False, desc: str = "frames") -> None:
        """Write every frame from the rig given to :meth:`write_rig` (for ``vertices.npy`` and streamed exports)."""
        if self._rig is None:
            raise InputError("stream_rig: write_rig first")
        rig, to_mm = self._rig, np.float32(1.0 / self._unit_scale)

        def compute(start: int, stop: int, out: np.ndarray) -> None:
            rig.frames_into(start, stop, out)
            if to_mm != 1:  # write_frames takes mm; in mm (the usual unit) the rig's frames go out bit for bit
                out *= to_mm

        self.stream(compute, batch_frames=batch_frames, head_pose=head_pose, progress=progress, desc=desc)

    def write_frames(self, start: int, vertices_mm: np.ndarray, *, head_pose: np.ndarray | None = None) -> None:
        """Append a block of consecutive frames.

        Parameters
        ----------
        start : int
            Index of the block's first frame; must follow the previous block.
        vertices_mm : (b, n, 3) float32 array, mm
            Deformed vertices. Converted to the scan's source unit on writing.
        head_pose : (b, 4, 4) float array, optional
            Rigid head motion per frame, in scan coordinates (mm), for USD.
        """
        if start != self.frames_written:
            raise InputError(f"frames must be written in order: expected frame {self.frames_written}, got {start}")
        block_mm = np.asarray(vertices_mm, dtype=np.float32)
        if start + block_mm.shape[0] > self.n_frames:
            raise InputError(f"more frames than announced ({self.n_frames})")
        block = block_mm * self._unit_scale if self._unit_scale != 1 else block_mm
        if self._npy is not None:
            self._npy.write(block)
        if self._usd is not None:  # the USD writer takes mm and converts itself
            self._usd.write_frames(start, block_mm, head_pose=head_pose)
        if "obj" in self.exports or "ply" in self.exports:
            from .write_mesh import write_mesh

            shared = None
            if self.mesh.texture is not None and self.mesh.uvs is not None:
                shared = "texture"  # one image and MTL per folder, not one per frame
                if start == 0:
                    from .write_mesh import write_texture_files

                    for fmt in ("obj", "ply"):
                        if fmt in self.exports:
                            write_texture_files(self.mesh, self.staging / fmt, shared)
            for k in range(block.shape[0]):
                for fmt in ("obj", "ply"):
                    if fmt in self.exports:
                        frame_path = self.staging / fmt / f"frame_{start + k:06d}.{fmt}"
                        write_mesh(self.mesh, frame_path, vertices=block_mm[k], shared_texture=shared)
        self._frames_written += block_mm.shape[0]

    def stream(
        self,
        compute: Callable[[int, int, np.ndarray], Any],
        *,
        batch_frames: int = 32,
        head_pose: np.ndarray | None = None,
        progress: bool = False,
        desc: str = "frames",
    ) -> None:
        """Compute every frame batch by batch and write it, the writes overlapping the next batch.

        Two buffers of ``batch_frames`` frames and one writer thread, so memory
        does not grow with the take and the disk works while the CPU does.

        Parameters
        ----------
        compute : callable ``(start, stop, out) -> Any``
            Fills ``out``, a (stop - start, n, 3) float32 array, with frames
            ``start`` to ``stop`` in mm.
        batch_frames : int, default 32
        head_pose : (T, 4, 4) float array, optional
            Passed on to :meth:`write_frames` batch by batch.
        progress : bool, default False
            Show a progress bar labelled ``desc``.
        """
        T, n = self.n_frames, self.mesh.n_vertices
        buffers = [np.empty((min(batch_frames, T), n, 3), np.float32) for _ in range(2)]
        pending: list[Any] = [None, None]
        bar = tqdm(total=T, unit="frame", desc=desc, disable=not progress, leave=False)
        try:
            with ThreadPoolExecutor(max_workers=1) as pool:
                for k, start in enumerate(range(0, T, batch_frames)):
                    stop = min(start + batch_frames, T)
                    slot = k % 2
                    if pending[slot] is not None:
                        pending[slot].result()  # the buffer is free once its write finished
                    out = buffers[slot][: stop - start]
                    compute(start, stop, out)
                    pose = None if head_pose is None else head_pose[start:stop]
                    pending[slot] = pool.submit(self.write_frames, start, out, head_pose=pose)
                    bar.update(stop - start)
                for future in pending:
                    if future is not None:
                        future.result()
        finally:
            bar.close()

    def path(self, name: str) -> Path:
        """Where to put an extra file (report, picture) in the staging folder."""
        return self.staging / name

    def record_path(self, path: str | os.PathLike[str]) -> str:
        """What a file of this folder records for ``path``: final, relative when inside the folder, else absolute."""
        return recorded_path(path, folder=self.staging)

    @property
    def later_exports(self) -> list[str]:
        """The exports made from the finished frames, not streamed (glTF, point caches, Alembic, USD blend shapes).

        What the job exports into :attr:`staging` between :meth:`write_metadata` and
        :meth:`finish` (:func:`facecap.pipelines.finish_result`).
        """
        return [f for f in self.exports if f not in STREAMED_FORMATS or (f == "usd" and self._rig is not None)]

    def write_metadata(self, metadata: dict[str, Any]) -> Path:
        """Close the frames and write ``faces.npy``, ``mesh.npz`` and ``performance.json`` into the staging folder.

        After it the staging folder reads as a finished result (:func:`facecap.io.read_result`),
        so the exports made from the frames and the pages can be written into it
        before :meth:`finish` moves it into place.

        Parameters
        ----------
        metadata : dict
            JSON-ready description: source files, parameters, ...; ``rate``,
            ``units``, ``n_frames`` and ``n_vertices`` are added. The paths in
            ``source_files`` (a path, or a list of them, per name; None kept)
            are recorded as :meth:`record_path` gives them.

        Returns
        -------
        Path
            The staging folder.

        Raises
        ------
        InputError
            If frames are missing, the result has neither ``vertices.npy`` nor a
            rig, or the metadata were written already.
        """
        if self._metadata_written:
            raise InputError("the result's metadata were written already")
        if self.needs_frames and self.frames_written != self.n_frames:
            raise InputError(f"only {self.frames_written} of {self.n_frames} frames were written")
        if self._npy is None and self._rig is None:
            raise InputError("the result has neither vertices.npy nor a rig")
        self._wait_for_rig()
        if self._npy is not None:
            self._npy.close()
        if self._usd is not None:
            self._usd.close()
        np.save(self.staging / "faces.npy", self.mesh.faces)
        _write_mesh_npz(self.staging / "mesh.npz", self.mesh)
        info = {
            "format": "facecap-performance",
            "version": 1,
            "rate": self.rate,
            "units": self.mesh.source_unit,
            "n_frames": self.n_frames,
            "n_vertices": self.mesh.n_vertices,
            "exports": self._export_names(),
            "frames_in": (["vertices.npy"] if self._npy is not None else []) + (["rig/"] if self._rig is not None else []),
            **metadata,
        }
        if isinstance(info.get("source_files"), dict):
            info["source_files"] = {name: self._recorded(value) for name, value in info["source_files"].items()}
        (self.staging / PERFORMANCE_FILE).write_text(json.dumps(info, indent=2, default=_json_default))
        self._metadata_written = True
        return self.staging

    def finish(self, metadata: dict[str, Any] | None = None) -> Path:
        """List every file with its size in ``performance.json`` and move the folder into place.

        Writes the metadata first (:meth:`write_metadata`) unless that was done.
        The exports made from the finished frames and the run's pages are the
        job's, written between the two (:func:`facecap.pipelines.finish_result`).

        Parameters
        ----------
        metadata : dict, optional
            As for :meth:`write_metadata`; required when it was not called.

        Returns
        -------
        Path
            The finished output folder.
        """
        if not self._metadata_written:
            if metadata is None:
                raise InputError("finish: the result's metadata are missing (write_metadata or finish(metadata))")
            self.write_metadata(metadata)
        elif metadata is not None:
            raise InputError("finish: the result's metadata were written already")
        info_path = self.staging / PERFORMANCE_FILE
        info = json.loads(info_path.read_text())
        info["files"] = file_sizes(self.staging)
        info_path.write_text(json.dumps(info, indent=2, default=_json_default))
        self._folder.__exit__(None, None, None)
        self._finished = True
        return self.out_dir

    def _export_names(self) -> list[str]:
        """The exports as ``performance.json`` lists them: ``mdd_world`` for a point cache in the world frame."""
        world = self.export_options.get("export_frame", "stabilized") == "world"
        return [f"{f}_world" if world and f in WORLD_FRAME_FORMATS else f for f in self.exports]

    def _recorded(self, value: Any) -> Any:
        """A ``source_files`` entry with its paths recorded final (lists entry by entry; None and labels kept)."""
        if isinstance(value, (list, tuple)):
            return [self._recorded(v) for v in value]
        if isinstance(value, (str, os.PathLike)) and str(value):
            return self.record_path(value)
        return value

    def abort(self) -> None:
        """Discard everything written so far."""
        try:
            self._wait_for_rig()
        except Exception:
            pass
        try:
            if self._npy is not None:
                self._npy.close()
        except Exception:
            pass
        if self._usd is not None:
            try:
                self._usd.abort()
            except Exception:
                pass
        if not self._finished:
            self._folder.__exit__(InputError, InputError("aborted"), None)


def check_result_destination(out_dir: str | os.PathLike[str], *, overwrite: bool = False) -> None:
    """Refuse, before a job's long work, an ``out_dir`` :class:`PerformanceWriter` would refuse.

    Raises
    ------
    InputError
        One line naming ``out_dir``: an earlier result without ``overwrite``, a
        file or a non-empty folder of something else (never replaced), or a
        folder that cannot be created (the cause). See
        :func:`facecap.io.atomic_write.check_folder_destination`.
    """
    check_folder_destination(out_dir, marker_file=PERFORMANCE_FILE, overwrite=overwrite)


def _write_mesh_npz(path: str | os.PathLike[str], mesh: Mesh) -> None:
    """The scan a result was made on, as ``mesh.npz``: rest vertices in its source unit, topology, UVs."""
    arrays: dict[str, np.ndarray] = {"rest": mesh.to_source_unit(mesh.vertices).astype(np.float32), "faces": mesh.faces}
    for name in ("polygon_sizes", "polygon_indices", "uvs", "uv_indices"):
        value = getattr(mesh, name)
        if value is not None:
            arrays[name] = np.asarray(value)
    np.savez(path, **arrays)


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.floating,)):
        return float(obj)
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")

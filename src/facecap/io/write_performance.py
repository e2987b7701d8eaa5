"""Streamed output of an animated scan: the output folder facecap writes.

Layout of a finished folder (see ``docs/output_format.md``):

- ``vertices.npy``: float32 ``(T, n, 3)`` in the scan's own coordinates, units
  and vertex order; written frame block by frame block, readable with
  ``np.load(path, mmap_mode="r")``.
- ``faces.npy``: int64 ``(m, 3)`` triangles (polygons are kept in the exports).
- ``performance.json``: rate, units, frame count, source files, parameters.
- optional exports: ``obj/frame_000000.obj ...``, ``ply/...``, ``performance.usdc``.
- whatever else the caller adds (``report.json``, pictures).

Everything is written into a hidden staging folder beside the destination and
renamed onto it only when the run finishes, so an interrupted or failed run
never leaves a folder that looks finished.
"""

from __future__ import annotations

import json
import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np
from tqdm.auto import tqdm

from ..errors import InputError
from ..structures import Mesh
from ..units import mm_per_unit
from ._atomic import atomic_folder

__all__ = ["PerformanceWriter", "EXPORT_FORMATS", "read_performance_info"]

EXPORT_FORMATS = ("obj", "ply", "usd")
"""Per-frame exports ``--export`` accepts besides the always-written ``vertices.npy``."""

_MARKER_FILE = "performance.json"


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
        Destination folder. If it exists it must be empty or hold an earlier
        facecap result (which is replaced only once this run succeeds).
    mesh : Mesh
        The scan: topology, UVs and source unit of the output.
    rate : float
        Frame rate in Hz.
    n_frames : int
        Number of frames that will be written.
    exports : iterable of {'obj', 'ply', 'usd'}, optional
        Per-frame exports besides ``vertices.npy``.

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
    ) -> None:
        self.out_dir = Path(out_dir)
        self.mesh = mesh
        self.rate = float(rate)
        self.n_frames = int(n_frames)
        self.exports = tuple(dict.fromkeys(exports))
        unknown = [e for e in self.exports if e not in EXPORT_FORMATS]
        if unknown:
            raise InputError(f"--export: unknown format(s) {unknown}; choose from {list(EXPORT_FORMATS)}")
        self._folder = atomic_folder(self.out_dir, marker_file=_MARKER_FILE)
        self.staging = self._folder.__enter__()
        self._unit_scale = np.float32(1.0 / mm_per_unit(mesh.source_unit))
        self._npy = _NpyStream(self.staging / "vertices.npy", (self.n_frames, mesh.n_vertices, 3), np.dtype("<f4"))
        self._usd = None
        if "usd" in self.exports:
            from .write_usd import UsdPerformanceWriter

            self._usd = UsdPerformanceWriter(self.staging / "performance.usdc", mesh, self.rate, self.n_frames)
        for fmt in ("obj", "ply"):
            if fmt in self.exports:
                (self.staging / fmt).mkdir()
        self._finished = False

    def __enter__(self) -> "PerformanceWriter":
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is not None or not self._finished:
            self.abort()

    @property
    def frames_written(self) -> int:
        """Frames written so far."""
        return self._npy.frames_written

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
        self._npy.write(block)
        if self._usd is not None:  # the USD writer takes mm and converts itself
            self._usd.write_frames(start, block_mm, head_pose=head_pose)
        if "obj" in self.exports or "ply" in self.exports:
            from .write_mesh import write_mesh

            for k in range(block.shape[0]):
                for fmt in ("obj", "ply"):
                    if fmt in self.exports:
                        frame_path = self.staging / fmt / f"frame_{start + k:06d}.{fmt}"
                        write_mesh(self.mesh, frame_path, vertices=block_mm[k])

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

    def finish(self, metadata: dict[str, Any]) -> Path:
        """Write ``faces.npy`` and ``performance.json`` and move the folder into place.

        Parameters
        ----------
        metadata : dict
            JSON-ready description: source files, parameters, ...; ``rate``,
            ``units``, ``n_frames`` and ``n_vertices`` are added.

        Returns
        -------
        Path
            The finished output folder.
        """
        if self.frames_written != self.n_frames:
            raise InputError(f"only {self.frames_written} of {self.n_frames} frames were written")
        self._npy.close()
        if self._usd is not None:
            self._usd.close()
        np.save(self.staging / "faces.npy", self.mesh.faces)
        info = {
            "format": "facecap-performance",
            "version": 1,
            "rate": self.rate,
            "units": self.mesh.source_unit,
            "n_frames": self.n_frames,
            "n_vertices": self.mesh.n_vertices,
            "exports": list(self.exports),
            **metadata,
        }
        (self.staging / _MARKER_FILE).write_text(json.dumps(info, indent=2, default=_json_default))
        self._folder.__exit__(None, None, None)
        self._finished = True
        return self.out_dir

    def abort(self) -> None:
        """Discard everything written so far."""
        try:
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


def read_performance_info(out_dir: str | os.PathLike[str]) -> dict[str, Any]:
    """Read ``performance.json`` of a finished output folder, or raise InputError."""
    path = Path(out_dir) / _MARKER_FILE
    if not path.is_file():
        raise InputError("is not a finished facecap result (no performance.json)", path=str(out_dir))
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise InputError(f"unreadable performance.json ({exc})", path=str(path)) from None


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

"""The result folder of the muscle jobs (``facecap solve-muscles``, ``facecap edit-muscles``), written in one atomic step.

The layout is ``animate``'s (:class:`~facecap.io.PerformanceWriter`: ``vertices.npy``,
``performance.json``, ``report.json``, exports) plus :data:`ACTIVATIONS_FILE`,
:data:`BONE_TRANSFORMS_FILE` and ``activations.png`` (:func:`plot_muscle_activations`).
"""

from __future__ import annotations

import json
import os
import time
import zipfile
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from ..io.write_performance import PerformanceWriter
from ..muscles.muscle_solver import FLAG_RESIDUAL_MM
from ..report.plot_activations import plot_activations
from ..structures import Mesh
from .finish_result import finish_result

__all__ = ["write_muscle_result", "plot_muscle_activations", "ACTIVATIONS_FILE", "BONE_TRANSFORMS_FILE"]

ACTIVATIONS_FILE = "activations.csv"
"""Per frame and muscle: a header row ``frame,<muscle names>``, one row per frame."""
BONE_TRANSFORMS_FILE = "bone_transforms.npz"
"""``cranium``, ``mandible`` (T, 3, 4), ``jaw_pose`` (T, 3) and ``frames`` (T,) of the result."""


def _write_npz(path: Path, **arrays: np.ndarray) -> None:
    """An uncompressed ``.npz`` with fixed member order and ZIP times: the same arrays give the same bytes."""
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_STORED) as archive:
        for name, value in arrays.items():
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.external_attr = 0o644 << 16
            with archive.open(info, "w") as member:
                np.lib.format.write_array(member, np.ascontiguousarray(value), allow_pickle=False)


def _write_activations(path: Path, frames: np.ndarray, names: Iterable[str], activations: np.ndarray) -> None:
    """``activations.csv``: ``frame,<names>``, one row per frame (its number in ``frames``), 6 decimals."""
    lines = [",".join(["frame", *names])]
    for number, row in zip(frames, np.asarray(activations)):
        lines.append(",".join([str(int(number)), *(f"{v:.6f}" for v in row)]))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def plot_muscle_activations(path: Path, frames: np.ndarray, rate: float, names: tuple[str, ...],
                            activations: np.ndarray, report: Mapping[str, Any], metadata: Mapping[str, Any], *,
                            title: str | None = None, caption: str | None = None) -> None:
    """``activations.png`` of a muscle result: :func:`~facecap.report.plot_activations` with the result's flags.

    The activations over time, the flagged frames shaded, each frame's largest marker residual
    against the ``large_residual`` threshold (when the report has residuals: a solve, not an edit).

    Parameters
    ----------
    path : path-like
        The picture (PNG).
    frames : (T,) int array
        Frame numbers of the rows; ``frames / rate`` is the time axis, s.
    rate : float, Hz
    names : tuple of str
        The muscles, in column order.
    activations : (T, k) float64 array
    report, metadata : mapping
        The result's ``report.json`` (``flags``, ``marker_residual_mm``) and ``performance.json``
        (its solver options: ``flag_residual_mm``).
    title : str, optional
        Replaces the default title (``muscle activations, frames A-B``).
    caption : str, optional
        A caption under the plot (the demo says what its frames are).
    """
    flags = report.get("flags") or {}
    flagged = np.array([bool(flags.get(str(int(f)))) for f in frames])
    residual = (report.get("marker_residual_mm") or {}).get("per_frame_max")
    if residual is not None:
        residual = np.array([np.nan if r is None else r for r in residual], dtype=np.float64)
    solver = ((metadata.get("parameters") or {}).get("solver") or {})
    threshold = float(solver.get("flag_residual_mm", FLAG_RESIDUAL_MM))
    plot_activations(frames / rate, activations, names, path, flagged=flagged,
                     max_residual_mm=residual, flag_residual_mm=threshold if residual is not None else None,
                     title=title or f"muscle activations, frames {int(frames[0])}-{int(frames[-1])}", caption=caption)


def write_muscle_result(out_dir: str | os.PathLike[str], scan: Mesh, rate: float, frames: Any,
                        muscle_names: Iterable[str], arrays: Mapping[str, Any], *, report: dict[str, Any],
                        metadata: dict[str, Any], extra_arrays: Mapping[str, np.ndarray] | None = None,
                        exports: Iterable[str] = (), progress: bool = False, timings: dict[str, float] | None = None,
                        started: float | None = None, write_started: float | None = None,
                        desc: str = "solve-muscles", export_options: Mapping[str, Any] | None = None,
                        overwrite: bool = False) -> Path:
    """Write a muscle result folder (``solve-muscles``, ``edit-muscles``) in one atomic step.

    Parameters
    ----------
    out_dir : str or path-like
    scan : Mesh
        The model's scan (the output mesh).
    rate : float, Hz
    frames : (T,) int array
        Frame numbers of the rows (``activations.csv``'s ``frame`` column, ``bone_transforms.npz``'s ``frames``).
    muscle_names : iterable of str
    arrays : mapping
        ``vertices`` (T, n, 3) float32 mm (sliced by frame ranges: an array or a memory map),
        ``activations`` (T, k), ``cranium`` and ``mandible`` (T, 3, 4), ``jaw_pose`` (T, 3).
    report, metadata : dict
        ``report.json`` and what :meth:`PerformanceWriter.finish` adds to ``performance.json``;
        both get ``timings``.
    extra_arrays : mapping of file name to array, optional
        Saved with ``np.save`` (``markers.npy``, ``head_motion.npy``).
    exports, progress
        As for :class:`~facecap.io.PerformanceWriter`.
    timings : dict, optional
        Updated with ``write_s`` (since ``write_started``, default now) and ``total_s`` (since ``started``).
    desc : str
        The progress bar's label.
    export_options : mapping, optional
        Passed to :func:`facecap.pipelines.export_result`.
    overwrite : bool, default False
        Replace an earlier result in ``out_dir`` (:class:`~facecap.io.PerformanceWriter`).

    Returns
    -------
    Path
        The finished folder.
    """
    t = time.perf_counter() if write_started is None else write_started
    frames = np.asarray(frames, dtype=np.int64).reshape(-1)
    names = tuple(muscle_names)
    timings = {} if timings is None else timings
    with PerformanceWriter(out_dir, mesh=scan, rate=rate, n_frames=frames.size, exports=exports, overwrite=overwrite,
                           export_options={"progress": progress, **(export_options or {})}) as writer:
        skin = arrays["vertices"]

        def compute(lo: int, hi: int, out: np.ndarray) -> None:
            out[:] = skin[lo:hi]

        writer.stream(compute, batch_frames=32, progress=progress, desc=desc)
        for name, value in (extra_arrays or {}).items():
            np.save(writer.path(name), value)
        _write_activations(writer.path(ACTIVATIONS_FILE), frames, names, arrays["activations"])
        _write_npz(writer.path(BONE_TRANSFORMS_FILE), cranium=arrays["cranium"], mandible=arrays["mandible"],
                   jaw_pose=arrays["jaw_pose"], frames=frames)
        plot_muscle_activations(writer.path("activations.png"), frames, float(rate), names, arrays["activations"],
                                report, metadata)
        timings["write_s"] = time.perf_counter() - t
        if started is not None:
            timings["total_s"] = time.perf_counter() - started
        report["timings"] = timings
        writer.path("report.json").write_text(json.dumps(report, indent=1))
        metadata["timings"] = timings
        return finish_result(writer, metadata)

"""The blend's result folder: a performance from blendshape bases and weights, written as ``facecap animate`` writes.

The rig from :func:`~facecap.blendshapes.blend_rig` (Huang et al. 2011, eq. 12 about the bases'
centroid) in the template's unit, streamed through :class:`~facecap.io.PerformanceWriter` with the
head motion, the map back into the capture's frame and the job's own files. :func:`~facecap.pipelines.blend_take`
writes through it; so can any program holding bases and weights.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable

import numpy as np

from ..blendshapes.reconstruct_performance import blend_rig
from ..errors import InputError
from ..io.mocap_correspondence import write_mocap_correspondence
from ..io.result_rig import ResultRig
from ..io.write_performance import PerformanceWriter
from ..structures import Mesh
from ..units import mm_per_unit
from .finish_result import finish_result

__all__ = ["write_blended_performance"]


def write_blended_performance(
    out_dir: str | Path,
    template: Mesh,
    bases: np.ndarray,
    weights: np.ndarray,
    *,
    rate: float,
    output_from_bases: np.ndarray | None = None,
    head_motion: np.ndarray | None = None,
    exports: Iterable[str] = (),
    metadata: dict[str, Any] | None = None,
    extra_files: dict[str, Any] | None = None,
    correspondence: dict[str, Any] | None = None,
    batch_frames: int = 64,
    write_vertices: bool = True,
    rig_precision: str = "float32",
    export_options: dict[str, Any] | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> Path:
    """Write ``m_t = c + sum_i w_t,i (d_i - c)`` to an output folder like ``facecap animate`` writes.

    ``c`` is the bases' centroid (see ``output_from_bases``); with weights
    summing to one this is eq. 12's ``sum_i w_t,i d_i``. The result is a rig
    (``rig/``, :class:`~facecap.io.ResultRig`) about the template
    (:func:`~facecap.blendshapes.blend_rig`), in the template's unit.
    ``vertices.npy`` is evaluated from it.

    Parameters
    ----------
    out_dir : str or Path
    template : Mesh
        Topology, UVs and unit of the output.
    bases : (K, n, 3) float array, mm
        Blendshape bases (in the markers' frame).
    weights : (T, K) float array
    rate : float
        Frame rate, Hz.
    output_from_bases : (4, 4) float array, optional
        Rigid transform from the bases' frame to the output's (the template's
        own coordinates). The bases are moved by it and blended about their
        centroid, so weights that do not sum to one scale the face about its
        middle, not about either frame's origin.
    head_motion : (T, 4, 4) float array, optional
        The head's rigid motion per frame in the output frame (mm), as
        ``facecap animate`` writes it: saved as ``head_motion.npy`` (in the
        template's unit) and carried by the USD export as the mesh's
        transform. The vertices stay stabilised.
    exports : iterable of str
        See :data:`facecap.io.EXPORT_FORMATS`.
    metadata : dict, optional
        Added to ``performance.json``.
    extra_files : dict of str to array or str, optional
        Written into the folder before it is moved into place: ``.npy`` names
        get arrays, other names get text.
    correspondence : dict, optional
        The map from the output's face back into the capture's frame, written as
        ``correspondence.npz``: the arguments of
        :func:`~facecap.io.write_mocap_correspondence` (``mocap_points``,
        ``face_points``, ``labels``, ``mocap_from_stabilized``: (K, 3) mm points,
        K labels, (T, 4, 4) mm transforms).
    batch_frames : int, default 64
    write_vertices : bool, default True
        Write ``vertices.npy`` besides the rig.
    rig_precision : {'float32', 'int16'}, default 'float32'
        Storage of the rig's shapes.
    export_options : dict, optional
        Passed to :func:`facecap.pipelines.export_result`.
    progress : bool, default True
    overwrite : bool, default False
        Replace an earlier result in ``out_dir`` (:class:`~facecap.io.PerformanceWriter`).

    Returns
    -------
    Path
        The finished folder.
    """
    rest = template.vertices.astype(np.float64)
    blended = blend_rig(rest, bases, weights, output_from_bases=output_from_bases)
    K, T = blended.shapes.shape[0] - 1, blended.coefficients.shape[0]
    to_unit = 1.0 / mm_per_unit(template.source_unit)
    rig = ResultRig((rest * to_unit).astype(np.float32), blended.shapes.astype(np.float32) * np.float32(to_unit),
                    blended.coefficients, units=template.source_unit,
                    names=tuple(f"basis_{k}" for k in range(K)) + ("weight_sum",))
    del blended  # its float64 shapes, before the frames are streamed

    pose = None
    if head_motion is not None:
        pose = np.asarray(head_motion, dtype=np.float64)
        if pose.shape != (T, 4, 4) or not np.all(np.isfinite(pose)):
            raise InputError(f"head_motion: expected finite ({T}, 4, 4) transforms, got {pose.shape}")
    with PerformanceWriter(out_dir, mesh=template, rate=rate, n_frames=T, exports=exports, vertices=write_vertices,
                           overwrite=overwrite,
                           export_options={"progress": progress, **(export_options or {})}) as writer:
        writer.write_rig(rig, precision=rig_precision)
        if writer.needs_frames:
            writer.stream_rig(batch_frames=batch_frames, head_pose=pose, progress=progress, desc="blend")
        if pose is not None:
            in_unit = pose.copy()
            in_unit[:, :3, 3] = template.to_source_unit(in_unit[:, :3, 3])
            np.save(writer.path("head_motion.npy"), in_unit)
        if correspondence is not None:
            write_mocap_correspondence(writer.path("correspondence.npz"), **correspondence)
        for name, content in (extra_files or {}).items():
            if name.endswith(".npy"):
                np.save(writer.path(name), content)
            else:
                writer.path(name).write_text(str(content))
        return finish_result(writer, {"method": "huang2011-blendshapes", "stabilized": pose is not None, **(metadata or {})})

"""``facecap view``: a result's review page in the browser, and its HTML report.

:func:`view_result` makes what the page needs in the result folder, each file
written atomically: ``performance.glb`` when the result has none yet (the
glTF review export), ``review.html`` (:func:`facecap.report.write_review_page`;
with ``truth``, the error heat map at sampled frames) and ``report.html``
(:func:`facecap.report.write_run_report`, linking the page). The command
then serves the folder on localhost (:func:`facecap.report.serve`).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..io.read_result import Result, read_result
from .export_result import export_result

__all__ = ["view_result", "ERROR_ROWS"]

ERROR_ROWS = 120
"""Frames sampled for the review page's error heat map (each row is one byte per vertex in the page)."""


def view_result(
    result_dir: str | os.PathLike[str],
    *,
    truth: str | os.PathLike[str] | None = None,
    frame: str = "auto",
    error_rows: int = ERROR_ROWS,
    progress: bool = False,
) -> Path:
    """Write the review page (and the glTF it plays, if missing) and the HTML report of a result.

    Parameters
    ----------
    result_dir : str or path-like
        A finished result folder.
    truth : str or path-like, optional
        Ground truth (``truth.npz`` of the generator): the page then shows the
        error heat map, compared as ``facecap evaluate --frame`` does.
    frame : {'auto', 'world', 'stabilized'}, default 'auto'
        How a stabilised result is compared with the truth (see :func:`facecap.report.evaluate_result`).
    error_rows : int, default 120
        Frames of the heat map, evenly spread over the take.
    progress : bool, default False

    Returns
    -------
    Path
        ``review.html`` in the result folder.

    Raises
    ------
    InputError
        If the folder is not a finished result, or the truth does not match it.
    """
    from ..report.review_page import write_review_page
    from ..report.write_run_report import write_run_report

    result = read_result(result_dir)
    glb = result.path / "performance.glb"
    if not glb.is_file():
        export_result(result, "gltf", progress=progress, pages=False)  # the pages: below, with the error
    error = error_frames = None
    if truth is not None:
        error, error_frames = _error_rows(result, truth, frame, glb, error_rows)
    page = write_review_page(
        result.path / "review.html", glb, title=f"facecap: {result.path.name}", rate=result.rate,
        n_frames=result.n_frames, error=error, error_frames=error_frames,
    )
    write_run_report(result)
    return page


def _error_rows(result: Result, truth: str | os.PathLike[str], frame: str, glb: Path,
                rows: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-vertex error (mm) on the GLB's vertices at ``rows`` frames spread over the take."""
    from scipy.spatial import cKDTree

    from ..report.evaluate_result import result_and_truth_mm

    result_mm, truth_mm, _ = result_and_truth_mm(truth, result.path, frame=frame)
    frames = np.unique(np.round(np.linspace(0, result.n_frames - 1, min(rows, result.n_frames))).astype(np.int64))
    rest_m = _glb_rest_positions(glb)
    # The GLB's vertices are scan vertices (a subset, split along UV seams): found by their rest position.
    _, scan_vertex = cKDTree(result.mesh.vertices).query(rest_m * 1000.0)
    error = np.linalg.norm(result_mm[frames][:, scan_vertex] - truth_mm[frames][:, scan_vertex], axis=2)
    return error.astype(np.float32), frames


def _glb_rest_positions(glb: Path) -> np.ndarray:
    """The rest shape of a facecap GLB (metres): its base mesh moved by the targets at ``rest_weights``."""
    import pygltflib

    gltf = pygltflib.GLTF2().load_binary(str(glb))
    blob = gltf.binary_blob()

    def positions(index: int) -> np.ndarray:
        accessor = gltf.accessors[index]
        view = gltf.bufferViews[accessor.bufferView]
        return np.frombuffer(blob, np.float32, count=3 * accessor.count,
                             offset=(view.byteOffset or 0) + (accessor.byteOffset or 0)).reshape(-1, 3).astype(np.float64)

    primitive = gltf.meshes[0].primitives[0]
    rest = positions(primitive.attributes.POSITION)
    weights = ((gltf.asset.extras or {}).get("facecap") or {}).get("rest_weights") or []
    for w, target in zip(weights, primitive.targets or []):
        rest += w * positions(target["POSITION"])
    return rest

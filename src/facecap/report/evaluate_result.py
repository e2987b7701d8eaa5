"""Dense error of a facecap output folder against a ground-truth file (``facecap evaluate``)."""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FileFormatError, InputError
from ..io.read_result import read_result
from ..units import mm_per_unit
from .evaluate_performance import DenseError, evaluate_performance

__all__ = ["evaluate_result", "read_truth", "result_and_truth_mm"]


def read_truth(path: str | Path) -> dict[str, np.ndarray]:
    """Read a ground-truth ``.npz`` written by :func:`facecap.synth.write_synthetic_case`.

    Keys: ``vertices`` (T, n, 3) float32 in ``units``; ``units`` (str);
    optional ``head_pose`` (T, 4, 4) rigid head motion in scan coordinates
    (translation in ``units``), ``region_labels`` (n,) and ``region_names``.

    Raises
    ------
    FileFormatError
        If the file is not such an archive.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(2, "No such file", str(p))
    try:
        data = np.load(p, allow_pickle=False)
        truth = {k: data[k] for k in data.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise FileFormatError(f"not a readable ground-truth .npz ({exc})", path=str(p)) from None
    if "vertices" not in truth or truth["vertices"].ndim != 3 or truth["vertices"].shape[2] != 3:
        raise FileFormatError("expected a 'vertices' array of shape (T, n, 3)", path=str(p))
    return truth


def evaluate_result(truth_path: str | Path, result_dir: str | Path, *, frame: str = "auto",
                    vertex_mask: Any = None) -> DenseError:
    """Compare a result folder with ground truth, in mm.

    What a user gets from a stabilised result is the face *and* its head
    motion, so by default a result with ``head_motion.npy`` is compared in
    the world: its vertices moved by its head motion against the truth moved
    by the true head motion (both relative to the rest frame). A pose the
    stabilisation got wrong and the face then followed cancels there; one it
    did not follow does not. ``frame='stabilized'`` compares the stabilised
    vertices with the expression-only truth instead, which also charges the
    stabilisation's own error. An unstabilised result is compared with the
    truth moved by the head motion relative to the rest frame (which is what
    the warp maps onto the scan).

    Parameters
    ----------
    truth_path : str or Path
        Ground-truth ``.npz`` (see :func:`read_truth`).
    result_dir : str or Path
        A finished ``facecap animate`` or ``facecap blend`` output folder.
    frame : {'auto', 'world', 'stabilized'}, default 'auto'
        'auto': 'world' when the result has ``head_motion.npy``, else the
        result's own frame as described above.
    vertex_mask : (n,) bool array or None, optional
        Evaluate only these vertices (say, the part of the face the scans saw); None: all.

    Returns
    -------
    DenseError

    Raises
    ------
    InputError
        If frame or vertex counts differ.
    """
    opened = read_result(result_dir)
    result_mm, truth_mm, truth = result_and_truth_mm(truth_path, result_dir, frame=frame, opened=opened)
    names = [str(s) for s in truth["region_names"]] if "region_names" in truth else None
    labels = truth.get("region_labels")
    return evaluate_performance(result_mm, truth_mm, region_labels=labels, region_names=names,
                                vertex_mask=vertex_mask, faces=opened.mesh.faces)  # split across/along the skin


def result_and_truth_mm(truth_path: str | Path, result_dir: str | Path, *, frame: str = "auto",
                        opened: Any = None) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """The result's frames and the truth's, in mm, in the frame :func:`evaluate_result` compares them in.

    ``opened``: the folder already opened by :func:`~facecap.io.read_result` (None: opened here).

    Returns
    -------
    result_mm, truth_mm : (T, n, 3) float32 arrays
    truth : dict
        The ground-truth file's arrays (:func:`read_truth`).
    """
    if frame not in ("auto", "world", "stabilized"):
        raise InputError(f"frame: expected 'auto', 'world' or 'stabilized', got {frame!r}")
    truth = read_truth(truth_path)
    if opened is None:
        opened = read_result(result_dir)
    info = opened.info
    motion_path = Path(result_dir) / "head_motion.npy"
    stabilized = bool(info.get("stabilized", False))
    if frame == "world" and not (stabilized and motion_path.is_file()):
        raise InputError("frame='world' needs a stabilised result with head_motion.npy", path=str(result_dir))
    world = stabilized and motion_path.is_file() and frame != "stabilized"
    T_truth = truth["vertices"]
    if (opened.n_frames, opened.n_vertices, 3) != T_truth.shape:
        raise InputError(
            f"result has {opened.n_frames} frames x {opened.n_vertices} vertices, "
            f"truth has {T_truth.shape[0]} x {T_truth.shape[1]}",
            path=str(result_dir),
        )
    result = opened.frames()
    truth_unit = str(truth["units"]) if "units" in truth else "mm"
    truth_mm = T_truth.astype(np.float32) * np.float32(mm_per_unit(truth_unit))
    rest = int(info.get("rest_frame", 0))
    if (world or not stabilized) and "head_pose" in truth:
        pose = truth["head_pose"].astype(np.float64)
        pose[:, :3, 3] *= mm_per_unit(truth_unit)
        truth_mm = _moved(truth_mm, np.linalg.inv(pose[rest])[None] @ pose)
    result_scale = np.float32(mm_per_unit(info.get("units", "mm")))
    result_mm = result if result_scale == 1 else np.asarray(result) * result_scale
    if world:
        motion = np.load(motion_path).astype(np.float64)
        if motion.shape != (result.shape[0], 4, 4):
            raise FileFormatError(f"head_motion.npy has shape {motion.shape}, expected ({result.shape[0]}, 4, 4)",
                                  path=str(motion_path))
        motion[:, :3, 3] *= float(result_scale)
        # head_motion.npy is absolute: where the face is at each frame, in the scan's coordinates at the
        # rest frame's pose (its rest-frame entry is the identity only to within the capture's noise)
        result_mm = _moved(np.asarray(result_mm, dtype=np.float32), motion)
    return np.asarray(result_mm, dtype=np.float32), truth_mm, truth


def _moved(vertices: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """(T, n, 3) float32 vertices moved by per-frame rigid transforms (T, 4, 4)."""
    return (np.einsum("tij,tnj->tni", pose[:, :3, :3].astype(np.float32), vertices)
            + pose[:, None, :3, 3].astype(np.float32))

"""Write a marker take to C3D, TRC or facecap CSV (see :mod:`facecap.io.read_markers`)."""

from __future__ import annotations

import math
import os
import warnings
from pathlib import Path

import numpy as np

from ..errors import FacecapWarning, InputError
from ..structures import MarkerSequence
from ..units import mm_per_unit, normalize_unit
from .atomic_write import atomic_path, atomic_write_text

__all__ = ["write_markers"]

_C3D_MAX_FRAMES = 0xFFFF
_RESIDUAL_STEPS = 255  # C3D stores a residual as one byte times |POINT:SCALE|


def write_markers(markers: MarkerSequence, path: str | os.PathLike[str], *, unit: str = "mm") -> None:
    """Write a marker take to a ``.c3d``, ``.trc`` or ``.csv`` file, chosen by suffix.

    The file is written atomically: to a hidden sibling first, renamed onto
    ``path`` only once complete, so a failed write leaves no partial file.

    Parameters
    ----------
    markers : MarkerSequence
        The take; ``positions`` (T, M, 3) float64 in mm, NaN at gaps.
    path : str or os.PathLike
        Destination; its suffix (case-insensitive) picks the format.
    unit : {'mm', 'cm', 'm', 'in'}, optional
        Length unit of the coordinates in the file, default ``'mm'``; it is
        recorded in the file (C3D ``POINT:UNITS``, TRC ``Units``, CSV
        ``# unit=``) so :func:`~facecap.io.read_markers` converts back to mm.

    Raises
    ------
    InputError
        If ``markers`` is not a MarkerSequence, ``unit`` is unknown, the suffix
        is not one of ``.c3d``, ``.trc``, ``.csv``, a label cannot be written
        in the format (a tab in TRC, a comma in CSV, a line break in either),
        the take has more than 65535 frames for C3D, or the destination
        directory does not exist.

    Notes
    -----
    Gaps are written the way each format expects: C3D sets x, y, z to 0 and
    the residual to -1; TRC and CSV leave the cells empty.

    C3D keeps residuals: ``markers.residuals`` (mm, NaN or negative for
    none) is stored, like every C3D residual, as an integer 0..255 times
    ``|POINT:SCALE|``; the writer sets ``POINT:SCALE = -max_residual / 255``
    (in ``unit``), so residuals come back to within half of that step. The
    positions are stored as float32. TRC and CSV hold no residuals.

    Frame numbers: C3D header first frame and TRC ``Frame#`` are written as
    ``first_frame + 1`` (they count from 1), CSV ``frame`` as
    ``first_frame``. A ``first_frame`` C3D cannot store (negative, or past
    frame 65535) is written as 0 with a FacecapWarning.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from facecap.io.read_markers import read_markers
    >>> take = MarkerSequence(np.array([[[10.0, 20.0, 30.0]], [[np.nan] * 3]]), ("a",), 100.0)
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "take.trc"
    >>> write_markers(take, p, unit="cm")
    >>> back = read_markers(p)
    >>> back.positions[0, 0].tolist(), back.source_unit, bool(back.gap_mask[1, 0])
    ([10.0, 20.0, 30.0], 'cm', True)
    """
    if not isinstance(markers, MarkerSequence):
        raise InputError(f"markers: expected a MarkerSequence, got {type(markers).__name__}")
    file_unit = normalize_unit(unit, name="unit")
    p = Path(os.fspath(path))
    suffix = p.suffix.lower()
    if suffix == ".c3d":
        _write_c3d(markers, p, file_unit)
    elif suffix == ".trc":
        _check_labels(markers, p, forbidden="\t\r\n", what="a tab or line break")
        atomic_write_text(p, _trc_text(markers, p.name, file_unit))
    elif suffix == ".csv":
        _check_labels(markers, p, forbidden=",\r\n", what="a comma or line break")
        atomic_write_text(p, _csv_text(markers, file_unit))
    else:
        raise InputError(
            f"unsupported marker file suffix {p.suffix!r}; expected one of .c3d, .trc, .csv", path=str(p)
        )


def _check_labels(markers: MarkerSequence, p: Path, *, forbidden: str, what: str) -> None:
    bad = [s for s in markers.labels if any(c in s for c in forbidden) or not s.strip()]
    if bad:
        raise InputError(f"labels {bad} are empty or contain {what}, which {p.suffix} cannot hold", path=str(p))


def _format_block(values: np.ndarray) -> list[str]:
    """Each row as comma-joined shortest round-trip float text, an empty cell for NaN."""
    out = []
    for row in values.tolist():
        out.append(",".join("" if v != v else repr(v) for v in row))
    return out


def _rows(markers: MarkerSequence, file_unit: str, sep: str, frame_offset: int) -> list[str]:
    T, M = markers.n_frames, markers.n_markers
    coords = (markers.positions / mm_per_unit(file_unit)).reshape(T, 3 * M)
    cells = _format_block(coords)
    frames = np.arange(T) + markers.first_frame + frame_offset
    times = markers.times.tolist()
    lines = []
    for f, t, c in zip(frames.tolist(), times, cells):
        row = f"{f},{t!r},{c}"
        lines.append(row if sep == "," else row.replace(",", sep))
    return lines


def _trc_text(markers: MarkerSequence, file_name: str, file_unit: str) -> str:
    M, T, rate = markers.n_markers, markers.n_frames, markers.rate
    names = "\t".join(f"{s}\t\t" for s in markers.labels)
    axes = "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, M + 1))
    head = [
        f"PathFileType\t4\t(X/Y/Z)\t{file_name}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
        f"{rate!r}\t{rate!r}\t{T}\t{M}\t{file_unit}\t{rate!r}\t{markers.first_frame + 1}\t{T}",
        f"Frame#\tTime\t{names}",
        f"\t\t{axes}",
        "",
    ]
    return "\n".join(head + _rows(markers, file_unit, "\t", 1)) + "\n"


def _csv_text(markers: MarkerSequence, file_unit: str) -> str:
    columns = ",".join(f"{s}_x,{s}_y,{s}_z" for s in markers.labels)
    head = [
        "# facecap marker sequence",
        f"# rate={markers.rate!r}",
        f"# unit={file_unit}",
        f"frame,time,{columns}",
    ]
    return "\n".join(head + _rows(markers, file_unit, ",", 0)) + "\n"


def _write_c3d(markers: MarkerSequence, p: Path, file_unit: str) -> None:
    import ezc3d

    T, M = markers.n_frames, markers.n_markers
    if T > _C3D_MAX_FRAMES:
        raise InputError(
            f"C3D as written here holds at most {_C3D_MAX_FRAMES} frames, the take has {T}; write .trc or .csv",
            path=str(p),
        )
    first = int(markers.first_frame)
    if first < 0 or first + T > _C3D_MAX_FRAMES:
        warnings.warn(
            f"{p}: first_frame {first} cannot be stored in a C3D header; writing 0",
            FacecapWarning,
            stacklevel=3,
        )
        first = 0

    scale = 1.0 / mm_per_unit(file_unit)
    xyz = markers.positions * scale  # (T, M, 3)
    gaps = markers.gap_mask
    if markers.residuals is None:
        residuals = np.zeros((T, M))
    else:
        residuals = np.asarray(markers.residuals, dtype=np.float64) * scale
    residuals = np.where(np.isfinite(residuals) & (residuals >= 0), residuals, 0.0)
    top = float(residuals[~gaps].max()) if (~gaps).any() else 0.0
    step = top / _RESIDUAL_STEPS if top > 0 and math.isfinite(top) else 1.0
    # ezc3d truncates residual / step to an integer: pass k + 1/4 steps so it stores round(residual / step).
    k = np.clip(np.round(residuals / step), 0, _RESIDUAL_STEPS)
    stored = (k + 0.25) * step
    stored[gaps] = -1.0
    xyz = np.where(gaps[..., None], 0.0, xyz)

    c3d = ezc3d.c3d()
    point = c3d["parameters"]["POINT"]
    point["RATE"]["value"] = [float(markers.rate)]
    point["LABELS"]["value"] = list(markers.labels)
    point["UNITS"]["value"] = [file_unit]
    point["SCALE"]["value"] = [-step]
    c3d["header"]["points"]["first_frame"] = first
    data = np.ones((4, M, T))
    data[:3] = xyz.transpose(2, 1, 0)
    c3d["data"]["points"] = data
    c3d["data"]["meta_points"] = {"residuals": stored.T[None, :, :]}
    with atomic_path(p, suffix=".c3d") as tmp:
        c3d.write(str(tmp))

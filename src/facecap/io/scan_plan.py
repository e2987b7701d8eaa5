"""``plan.json``: which frames of a take to scan, and how the take was conditioned to choose them."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from ..errors import FileFormatError, InputError
from .atomic_write import atomic_write_text, recorded_path

__all__ = ["write_scan_plan", "read_scan_plan", "PLAN_FORMAT"]

PLAN_FORMAT = "facecap-scan-plan"


def write_scan_plan(path: str | Path, plan: dict[str, Any], *, conditioning: dict[str, Any],
                    source: str | os.PathLike[str] | None) -> None:
    """Write a plan (``ScanPlan.to_dict()``) with the conditioning that produced it.

    Parameters
    ----------
    path : str or Path
        ``plan.json``; written atomically.
    plan : dict
        From :meth:`facecap.blendshapes.select_scan_frames.ScanPlan.to_dict`;
        holds ``frames`` (0-based indices into the take, in the order chosen)
        and their ``times_s`` and ``timecodes``.
    conditioning : dict
        ``rest_frame``, ``stable_markers`` (labels), ``smooth``: what
        ``register-scans`` and ``blend`` must repeat to see the same markers.
    source : str, path-like or None
        The take the plan was made from; recorded final (absolute, or relative
        to the plan's folder when inside it: :func:`facecap.io.atomic_write.recorded_path`).
    """
    if source is not None:
        source = recorded_path(source, folder=Path(path).parent)
    content = {"format": PLAN_FORMAT, "version": 1, "markers": source, "conditioning": conditioning, **plan}
    atomic_write_text(path, json.dumps(content, indent=1))


def read_scan_plan(path: str | Path, *, n_frames: int | None = None) -> dict[str, Any]:
    """Read ``plan.json`` and check its frames exist in a take of ``n_frames`` frames.

    Raises
    ------
    FileFormatError
        If the file is not a facecap plan.
    InputError
        If a planned frame is outside the take.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(2, "No such file", str(p))
    try:
        plan = json.loads(p.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise FileFormatError(f"not a JSON file ({exc})", path=str(p)) from None
    if not isinstance(plan, dict) or not isinstance(plan.get("frames"), list) or not plan["frames"]:
        raise FileFormatError("expected a facecap scan plan with a non-empty 'frames' list", path=str(p))
    frames = plan["frames"]
    if not all(isinstance(f, int) and not isinstance(f, bool) for f in frames):
        raise FileFormatError("'frames' must be 0-based integer frame indices", path=str(p))
    if len(set(frames)) != len(frames):
        raise FileFormatError("'frames' lists a frame twice", path=str(p))
    if n_frames is not None:
        bad = [f for f in frames if not 0 <= f < n_frames]
        if bad:
            raise InputError(f"planned frames {bad} do not exist in the take (frames 0..{n_frames - 1})", path=str(p))
    plan.setdefault("conditioning", {"rest_frame": 0, "stable_markers": [], "smooth": True})
    return plan

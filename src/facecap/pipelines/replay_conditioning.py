"""The scan workflow's one conditioning of a take, replayed by every step from the plan's record.

``facecap plan-scans`` conditions the take (rest frame, stable markers, filtering), records how in
``plan.json`` and keeps the result beside it; ``register-scans`` and ``blend`` read that result back
when they are given the same take, and condition another take afresh with the recorded settings,
so all three steps see the same markers and head motion.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..errors import InputError
from ..io.conditioned_take import file_sha256, read_conditioned_take
from ..markers.condition_take import DEFAULT_HEAD_MOTION_SIGMA_S, condition_take
from ..structures import ConditionedTake, MarkerSequence

__all__ = ["replay_conditioning"]


def replay_conditioning(take: MarkerSequence, conditioning: dict[str, Any], *, markers_path: str | Path | None = None,
                        saved: str | Path | None = None) -> ConditionedTake:
    """The take as a plan conditioned it: read from ``saved`` when it is the same take, else conditioned afresh.

    Parameters
    ----------
    take : MarkerSequence
        The take, read from ``markers_path``.
    conditioning : dict
        A plan's record of its conditioning (``plan.json``'s ``conditioning``). Plans written before
        a setting was recorded replay what was done then: the fixed stable-marker set, a 0.02 s
        temporal filter, the most rigid set as the skin's head pose.
    markers_path : str or Path, optional
        The take's file; its hash is compared with the plan's record. Required with ``saved``.
    saved : str or Path, optional
        The conditioned take the plan kept (``plan.conditioned.npz``, or a bases folder's
        ``conditioned_take.npz``). Without it, or when the take is another (another take of the
        actor, or an edited file), the take is conditioned afresh with the recorded settings.

    Returns
    -------
    ConditionedTake

    Raises
    ------
    InputError
        If ``saved`` is given without ``markers_path``.
    """
    if saved is not None:
        if markers_path is None:
            raise InputError("markers_path: needed to tell whether the saved conditioned take is this take's")
        saved = Path(saved)
        if saved.is_file() and conditioning.get("source_sha256") == file_sha256(markers_path):
            conditioned, meta = read_conditioned_take(saved)
            if meta["labels"] == tuple(take.labels) and conditioned.positions.shape[0] == take.n_frames:
                return conditioned
    stabilize = conditioning.get("stabilize")
    if stabilize is None:  # plans written before the consensus stabiliser: replay the fixed set
        stabilize = conditioning.get("stable_markers") or False
    elif stabilize == "auto":
        stabilize = True
    elif stabilize == "off":
        stabilize = False
    return condition_take(
        take, rest_frame=int(conditioning.get("rest_frame", 0)), stabilize=stabilize,
        smooth=bool(conditioning.get("smooth", True)),
        head_motion_sigma_s=float(conditioning.get("head_motion_sigma_s", DEFAULT_HEAD_MOTION_SIGMA_S)),
        # plans from before the cross-validated sigma were filtered at 0.02 s
        temporal_sigma_s=conditioning.get("temporal_sigma_s", 0.02),
        skin_head_pose=conditioning.get("skin_head_pose", "rigid_set"),  # unrecorded: a plan from before the consensus
    )

"""The contract of a slow per-frame stage, and the identity that keeps resumed runs honest.

A *stage* is whatever computes a range of frames: the wrinkle layer, the muscle
solve. The frame runner (:func:`~facecap.runner.run_frames`) only needs it to be a
picklable callable with the signature of :class:`FrameStage`; it may also say
which parameters its frames depend on (:meth:`FrameStage.parameters`), which the
runner records in the work folder's manifest so that a resume with different
parameters is refused instead of mixing chunks of two different runs.
"""

from __future__ import annotations

import hashlib
import json
import pickle
import types
from collections.abc import Mapping
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..errors import InputError

__all__ = ["FrameStage", "StageState", "stage_identity"]

#: The state a stage hands from one chunk to the next (see :class:`FrameStage`):
#: None, or named arrays. Arrays, not arbitrary objects, so that it can be stored
#: in the chunk file byte for byte and read back by any worker on a resume.
StageState = Mapping[str, np.ndarray] | None


@runtime_checkable
class FrameStage(Protocol):
    """A slow per-frame stage as the frame runner calls it.

    The runner calls ``stage(start, stop, state)`` for each chunk of frames
    ``start <= frame < stop``, possibly in another process or on another machine,
    possibly twice for the same chunk (a worker lost after it finished). So the
    call must be a pure function of ``(stage, start, stop, state)``: no global
    state, no writes except through its return value, random seeds derived from
    the frame numbers, and the same bytes every time it runs.

    Parameters
    ----------
    start, stop : int
        The chunk's frames, ``0 <= start < stop <= n_frames``.
    state : mapping of str to ndarray, or None
        None where the chunk starts cold (the first chunk of a segment, see
        :func:`~facecap.runner.plan_chunks`); otherwise the state the previous
        chunk of the same segment returned (for example the last solved frame of
        a warm-started solver), read back from that chunk's file.

    Returns
    -------
    arrays : dict of str to ndarray
        The chunk's results, each of shape ``(stop - start, ...)``, the same names,
        dtypes and trailing shapes for every chunk. Names are Python identifiers.
    state : mapping of str to ndarray, or None
        What the next chunk of the segment starts from; None if the stage does
        not warm-start.

    Notes
    -----
    A stage whose frames are independent ignores ``state`` and returns None. A
    stage that warm-starts each frame from the previous one (the muscle solve of
    issue 11) does so inside the chunk, and either starts every chunk cold (with
    the extra iterations of a cold start; chunks then run in parallel) or returns
    its last state so that the next chunk continues the chain exactly
    (``segment_chunks`` of :func:`~facecap.runner.run_frames`).
    """

    def __call__(self, start: int, stop: int, state: StageState) -> tuple[dict[str, np.ndarray], StageState]:
        ...  # pragma: no cover


def stage_identity(stage: Any) -> dict[str, Any]:
    """What identifies a stage's results, as recorded in a run's manifest.

    Parameters
    ----------
    stage : FrameStage
        The stage. If it has a ``parameters()`` method, that method's return
        value (JSON-serialisable: numbers, strings, booleans, None, lists and
        dicts of them) is its identity: it must name everything the frames
        depend on. Otherwise the identity is the SHA-256 of the stage's pickle,
        which is exact but says nothing readable when two runs differ (and may
        change between library versions, refusing a resume that was in fact
        safe).

    Returns
    -------
    identity : dict
        ``{'stage': 'module.QualifiedName', 'parameters': {...}}`` or
        ``{'stage': ..., 'pickle_sha256': '...'}``, JSON-serialisable, with lists
        where the parameters had tuples (what a JSON round trip gives).

    Raises
    ------
    InputError
        If the stage is not callable, cannot be pickled, or its parameters are
        not JSON-serialisable.
    """
    if not callable(stage):
        raise InputError(f"stage must be callable as stage(start, stop, state); got {type(stage).__name__}")
    named = stage if isinstance(stage, types.FunctionType) else type(stage)
    identity: dict[str, Any] = {"stage": f"{named.__module__}.{named.__qualname__}"}
    parameters = getattr(stage, "parameters", None)
    if callable(parameters):
        values = parameters()
        try:
            identity["parameters"] = json.loads(json.dumps(values, sort_keys=True, allow_nan=False))
        except (TypeError, ValueError) as exc:
            raise InputError(
                f"stage.parameters() of {identity['stage']} must return JSON-serialisable values "
                f"(plain numbers, strings, lists, dicts; convert numpy scalars with float/int): {exc}"
            ) from exc
        return identity
    try:
        pickled = pickle.dumps(stage, protocol=5)
    except Exception:  # a class defined in __main__ or a closure: what Dask itself sends
        pickled = None
    if pickled is None:
        try:
            import cloudpickle

            pickled = cloudpickle.dumps(stage, protocol=5)
        except Exception as exc:  # any pickling failure is the caller's stage, said plainly
            raise InputError(
                f"stage {identity['stage']} cannot be pickled, so it cannot be sent to workers: {exc}"
            ) from exc
    identity["pickle_sha256"] = hashlib.sha256(pickled).hexdigest()
    return identity

"""A stage's identity: its parameters when it names them, else its exact pickle; bad stages are clear errors."""

from __future__ import annotations

import hashlib
import pickle

import numpy as np
import pytest

from facecap import InputError
from facecap.runner import FrameStage, stage_identity
from runner_stages import SlowStage, WarmStage


class _NoParameters:
    def __init__(self, scale: float):
        self.scale = scale

    def __call__(self, start, stop, state):
        return {"x": np.full(stop - start, self.scale)}, None


class _NumpyParameters:
    def parameters(self):
        return {"scale": np.float32(1.5)}

    def __call__(self, start, stop, state):
        return {"x": np.zeros(stop - start)}, None


def test_named_parameters_are_the_identity() -> None:
    identity = stage_identity(SlowStage(4, n_values=10, iterations=2, log_dir="/somewhere"))
    assert identity == {"stage": "runner_stages.SlowStage",
                        "parameters": {"seed": 4, "n_values": 10, "iterations": 2}}  # the log folder is not one
    assert isinstance(SlowStage(1), FrameStage) and isinstance(WarmStage(), FrameStage)


def test_without_parameters_the_pickle_is_the_identity() -> None:
    stage = _NoParameters(2.0)
    identity = stage_identity(stage)
    assert identity["pickle_sha256"] == hashlib.sha256(pickle.dumps(stage, protocol=5)).hexdigest()
    assert stage_identity(_NoParameters(2.0)) == identity
    assert stage_identity(_NoParameters(2.5)) != identity


def test_a_closure_is_identified_through_cloudpickle() -> None:
    offset = 3.0

    def stage(start, stop, state):
        return {"x": np.arange(start, stop) + offset}, None

    identity = stage_identity(stage)
    assert identity["stage"] == (
        "test_frame_stage.test_a_closure_is_identified_through_cloudpickle.<locals>.stage"
    )
    assert len(identity["pickle_sha256"]) == 64


def test_bad_stages_are_clear_errors() -> None:
    with pytest.raises(InputError, match="stage must be callable"):
        stage_identity(42)
    with pytest.raises(InputError, match="JSON-serialisable"):
        stage_identity(_NumpyParameters())

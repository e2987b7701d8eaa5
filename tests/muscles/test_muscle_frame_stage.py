"""MuscleFrameStage: the muscle solve as a frame-runner stage, against the forward model's truth."""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import numpy as np
import pytest

from facecap.errors import FileFormatError, InputError
from facecap.muscles import (FRAME_FLAG_MEANINGS, FRAME_FLAGS, MuscleFrameStage, MuscleSolver, flag_names,
                             forward_markers, marker_embedding)
from facecap.runner import run_frames

from muscle_cases import ramping_controls


@pytest.fixture(scope="module")
def model_dir(anatomy, tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("model")
    anatomy.save(folder)
    return folder


@pytest.fixture(scope="module")
def truth(anatomy, model, layout):
    """A noise-free 5-frame take from known controls: muscles ramping, the jaw opening, the head turning."""
    e = marker_embedding(anatomy, layout.marker_vertices, layout.rest_markers)

    def cranium(s: float) -> np.ndarray:
        turn = np.radians(2 * s)
        return np.hstack([[[np.cos(turn), 0, np.sin(turn)], [0, 1, 0], [-np.sin(turn), 0, np.cos(turn)]],
                          [[s], [-s], [0.5 * s]]])

    # activations change by up to 0.15 a frame, the jaw by 1 degree
    controls = ramping_controls(model.n_muscles, 5, seed=21, peak=0.6, cranium=cranium,
                                jaw=lambda s: model.jaw.transform(np.radians(2 + 4 * s), 0, s))
    markers = [forward_markers(model, e, c).markers for c in controls]
    return controls, np.stack(markers)


def _stage(model_dir, layout, markers, **options) -> MuscleFrameStage:
    return MuscleFrameStage(model_dir, layout.marker_vertices, layout.rest_markers, markers,
                            options={"max_warm_steps": 4, **options})


def test_chunks_on_the_runner_give_back_the_controls(model_dir, layout, truth, anatomy, model, tmp_path) -> None:
    controls, markers = truth
    stage = _stage(model_dir, layout, markers)
    run = run_frames(stage, 5, tmp_path / "work", chunk_frames=3, scheduler="synchronous", progress=False)
    a = run.load("activations")
    assert a.shape == (5, model.n_muscles) and run.load("vertices").dtype == np.float32
    assert run.load("vertices").shape == (5,) + anatomy.scan_vertices.shape
    assert run.load("cranium").shape == (5, 3, 4) and run.load("mandible").shape == (5, 3, 4)
    assert run.load("marker_residual").shape == (5, layout.marker_vertices.size)
    # chunks of 3: frames 0 and 3 start cold, the others from the frame before
    assert run.load("cold").tolist() == [True, False, False, True, False]
    assert (run.load("steps")[[1, 2, 4]] <= 4).all()
    # noise-free markers: every frame back to the forward model's controls, skin and markers
    assert np.abs(a - np.stack([c.activations for c in controls])).max() < 1e-2
    assert np.abs(run.load("cranium") - np.stack([c.cranium for c in controls])).max() < 1e-3
    poses = np.array([model.jaw.pose(c.mandible) for c in controls])
    assert np.abs(run.load("jaw_pose") - poses).max() < 1e-3
    assert (run.load("rms_mm") < 0.01).all() and (run.load("flags") == 0).all()
    assert (run.load("inverted_tets") == 0).all() and run.load("constraint_violation").max() < 1e-4


def test_the_skin_is_the_forward_models(model_dir, layout, truth, anatomy, model) -> None:
    controls, markers = truth
    e = marker_embedding(anatomy, layout.marker_vertices, layout.rest_markers)
    arrays, state = _stage(model_dir, layout, markers)(3, 5, None)
    for j, c in zip((0, 1), controls[3:5]):
        skin = forward_markers(model, e, c).skin
        error = np.linalg.norm(arrays["vertices"][j] - skin, axis=1)
        assert error.mean() < 0.01 and error.max() < 0.1, (error.mean(), error.max())
    assert set(state) == {"activations", "cranium", "mandible", "nodes"}


def test_a_chained_segment_continues_as_one_loop(model_dir, layout, truth, tmp_path) -> None:
    """segment_chunks=None: chunk 2 starts from chunk 1's state, frame for frame what a single loop gives."""
    _, markers = truth
    stage = _stage(model_dir, layout, markers)
    run = run_frames(stage, 5, tmp_path / "work", chunk_frames=2, segment_chunks=None, scheduler="synchronous",
                     progress=False)
    assert run.load("cold").tolist() == [True, False, False, False, False]
    loop = stage.solve(0, 5)
    assert np.array_equal(run.load("activations"), np.stack([f.activations for f in loop]))
    assert np.array_equal(run.load("vertices"), np.stack([f.skin for f in loop]).astype(np.float32))


def test_the_stage_pickles_and_builds_its_solver_once_per_process(model_dir, layout, truth) -> None:
    _, markers = truth
    stage = _stage(model_dir, layout, markers)
    again = pickle.loads(pickle.dumps(stage))
    assert again.solver() is stage.solver()  # the module cache, keyed by the parameters
    assert json.loads(json.dumps(stage.parameters())) == again.parameters()
    other = _stage(model_dir, layout, markers, max_warm_steps=2)
    assert other.parameters() != stage.parameters() and other.solver() is not stage.solver()
    # a different take is another run but the same solver
    moved = _stage(model_dir, layout, markers + 0.01)
    assert moved.parameters()["markers_sha256"] != stage.parameters()["markers_sha256"]
    assert moved.solver() is stage.solver()


def test_flag_bits() -> None:
    assert flag_names(0) == ()
    assert flag_names(1 << FRAME_FLAGS.index("jaw_at_limit") | 1) == ("too_few_markers", "jaw_at_limit")


def test_every_flag_has_a_meaning_that_states_the_solver_default() -> None:
    import inspect

    assert set(FRAME_FLAG_MEANINGS) == set(FRAME_FLAGS)
    defaults = inspect.signature(MuscleSolver).parameters
    assert f"more than {defaults['flag_residual_mm'].default:g} mm" in FRAME_FLAG_MEANINGS["large_residual"]
    assert f"fewer than {defaults['min_markers'].default} markers" in FRAME_FLAG_MEANINGS["too_few_markers"]


def test_bad_input(model_dir, layout, truth) -> None:
    _, markers = truth
    with pytest.raises(InputError, match=r"\(T, 120, 3\)"):
        _stage(model_dir, layout, markers[:, :10])
    with pytest.raises(InputError, match="JSON"):
        _stage(model_dir, layout, markers, max_warm_steps=np.int64)
    with pytest.raises(InputError, match="0 <= start < stop"):
        _stage(model_dir, layout, markers).solve(4, 9)
    with pytest.raises(FileFormatError, match="anatomy.npz: missing"):
        _stage(model_dir / "missing", layout, markers)

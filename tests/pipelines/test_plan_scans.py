"""plan-scans records how it conditioned the take, and every later step replays it."""

import json

import numpy as np

from facecap.pipelines import replay_conditioning


def test_the_plan_records_its_head_pose_and_older_plans_replay_theirs(scan_workflow):
    # plan-scans has no map to tell the head band from the face, so it poses the head by the consensus of
    # all markers, and says so in plan.json; a plan written before that record existed replays the
    # most rigid set it was made with, whenever a step has to condition a take afresh
    from facecap.io import read_markers
    from facecap.io.conditioned_take import read_conditioned_take
    from facecap.markers import condition_take

    root, case, files, frames, scans = scan_workflow
    conditioning = json.loads((root / "plan.json").read_text())["conditioning"]
    assert conditioning["skin_head_pose"] == "consensus"
    take = read_markers(files.markers)
    saved, _ = read_conditioned_take(root / "plan.conditioned.npz")
    fresh = condition_take(take, stabilize=True, skin_head_pose="consensus")
    np.testing.assert_allclose(saved.head_rotations, fresh.head_rotations, atol=1e-9)
    older = {k: v for k, v in conditioning.items() if k != "skin_head_pose"}
    replayed = replay_conditioning(take, older)
    rigid_set = condition_take(take, stabilize=True, skin_head_pose="rigid_set")
    np.testing.assert_allclose(replayed.head_rotations, rigid_set.head_rotations, atol=1e-12)
    assert np.abs(replayed.head_rotations - fresh.head_rotations).max() > 1e-4  # the two poses differ


def test_a_cap_short_of_the_tolerance_says_what_it_costs(scan_workflow, tmp_path):
    # --max-scans below what the tolerance needs: the plan keeps the cap and records (and warns) how many
    # scans the tolerance would take, from the same greedy selection run on past the cap
    import pytest

    from facecap.blendshapes import select_scan_frames
    from facecap.errors import FacecapWarning
    from facecap.io.conditioned_take import read_conditioned_take
    from facecap.pipelines import plan_scans

    root, case, files, frames, scans = scan_workflow
    with pytest.warns(FacecapWarning, match="--max-scans 2 stops short of the tolerance"):
        plan = plan_scans(files.markers, tmp_path / "plan.json", tolerance=0.003, max_frames=2, progress=False)
    assert len(plan.frames) == 2 and not plan.converged
    cap = json.loads((tmp_path / "plan.json").read_text())["cap"]
    conditioned, _ = read_conditioned_take(tmp_path / "plan.conditioned.npz")
    uncapped = select_scan_frames(conditioned.positions, tolerance=0.003)
    assert uncapped.converged and len(uncapped.frames) > 2
    assert cap["scans_for_tolerance"] == len(uncapped.frames)
    assert list(uncapped.frames[:2]) == list(plan.frames)  # greedy: the cap's frames come first either way
    np.testing.assert_allclose(cap["worst_frame_error_after_each_uncapped_mm"], uncapped.worst_frame_after_each)
    assert cap["worst_frame_error_at_cap_mm"] == pytest.approx(plan.worst_frame_after_each[-1])
    assert cap["worst_frame_error_at_cap_mm"] > cap["tolerance_mm"] >= uncapped.worst_frame_after_each[-1]

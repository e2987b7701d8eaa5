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

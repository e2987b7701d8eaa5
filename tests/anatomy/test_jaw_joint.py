"""jaw_joint and is_mandible on the bundled ICT face's landmarks: condyles, the cranium-mandible cut."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.anatomy import anatomy_landmarks, is_mandible, jaw_joint
from facecap.io.ict_sample import load_ict_sample


def test_mandible_cut_and_condyles_from_the_ict_landmarks() -> None:
    sample = load_ict_sample()
    lm = anatomy_landmarks(sample.mesh)
    joint = jaw_joint(lm)
    left, right = joint.condyles
    # the ICT face is mirror-symmetric (to its float32 storage): the condyles mirror each other; in front of the ears, behind the eyes
    assert left[0] > 30 and right[0] < -30 and left[0] == pytest.approx(-right[0], abs=1e-3)
    assert lm.point("exocanthion_L")[2] - 30 > left[2] > lm.point("supraglenoid_L")[2] - 10
    # at the height of the orbitale (Frankfort horizontal)
    assert lm.local(left)[1] == pytest.approx(lm.local(lm.point("suborbital_L"))[1], abs=1e-9)
    pts = np.array([lm.point(n) for n in ("pogonion", "menton", "labrale_inferius", "gonion_L",
                                          "labrale_superius", "nasion", "zygomatic_L", "supraorbital_R")])
    assert is_mandible(pts, joint).tolist() == [True] * 4 + [False] * 4

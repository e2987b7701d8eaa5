"""MuscleControls: packing round trip and bad input."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.muscles import MuscleControls


def test_vector_round_trip() -> None:
    rng = np.random.default_rng(0)
    c = MuscleControls(rng.uniform(size=5), rng.normal(size=(3, 4)), rng.normal(size=(3, 4)))
    v = c.as_vector()
    assert v.shape == (29,)
    back = MuscleControls.from_vector(v, 5)
    assert np.array_equal(back.activations, c.activations)
    assert np.array_equal(back.cranium, c.cranium) and np.array_equal(back.mandible, c.mandible)
    # layout: [a, vec(M_c) row-major, t_c, vec(M_m), t_m]
    assert np.array_equal(v[5:14], c.cranium[:, :3].ravel()) and np.array_equal(v[14:17], c.cranium[:, 3])
    assert np.array_equal(v[17:26], c.mandible[:, :3].ravel()) and np.array_equal(v[26:], c.mandible[:, 3])


def test_rest_is_identity() -> None:
    c = MuscleControls.rest(4)
    assert np.array_equal(c.activations, np.zeros(4))
    assert np.array_equal(c.cranium, np.eye(3, 4)) and np.array_equal(c.mandible, np.eye(3, 4))


def test_bad_input() -> None:
    with pytest.raises(InputError, match="cranium"):
        MuscleControls(np.zeros(2), np.eye(3), np.eye(3, 4))
    with pytest.raises(InputError, match="mandible"):
        MuscleControls(np.zeros(2), np.eye(3, 4), np.full((3, 4), np.nan))
    with pytest.raises(InputError, match="activations"):
        MuscleControls(np.array([np.inf]), np.eye(3, 4), np.eye(3, 4))
    with pytest.raises(InputError, match="expected 26"):
        MuscleControls.from_vector(np.zeros(10), 2)

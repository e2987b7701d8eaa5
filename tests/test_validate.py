import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facecap.errors import InputError
from facecap.validate import as_count, as_frame_index, as_rigid_transform


def _rigid(angle_deg=30.0, t=(1.0, 2.0, 3.0)):
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", [angle_deg, 10.0, -5.0], degrees=True).as_matrix()
    T[:3, 3] = t
    return T


def test_a_rigid_transform_passes_unchanged():
    T = _rigid()
    np.testing.assert_array_equal(as_rigid_transform(T.tolist(), name="T"), T)


@pytest.mark.parametrize("bad, message", [
    (np.eye(3), "shape"),
    (np.full((4, 4), np.nan), "finite"),
    (np.diag([1.0, 1.0, -1.0, 1.0]), "det"),          # a reflection
    (np.diag([2.0, 1.0, 1.0, 1.0]), "orthonormal"),    # a scale
    ("not a matrix", "rigid transform"),
])
def test_what_is_not_rigid_is_named(bad, message):
    with pytest.raises(InputError, match=f"mocap_frame: .*{message}"):
        as_rigid_transform(bad, name="mocap_frame")


def test_project_gives_the_nearest_rotation():
    T = _rigid()
    drifted = T.copy()
    drifted[:3, :3] += 1e-3 * np.random.default_rng(0).normal(size=(3, 3))
    R = as_rigid_transform(drifted, name="init", project=True)[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) > 0
    # the orthogonal Procrustes solution: scipy's polar decomposition gives the same rotation
    from scipy.linalg import polar
    np.testing.assert_allclose(R, polar(drifted[:3, :3])[0], atol=1e-12)


def test_as_positive_range():
    from facecap.validate import as_positive_range

    assert as_positive_range((0.25, 0.6), name="r") == (0.25, 0.6)
    for bad, message in (((0.6, 0.25), "low <= high"), (0.3, r"\(low, high\)"), ((1.0, 2.0, 3.0), r"\(low, high\)"),
                         ((-1.0, 2.0), "positive")):
        with pytest.raises(InputError, match=message):
            as_positive_range(bad, name="r")


@pytest.mark.parametrize("good, minimum", [(3, 1), (np.int64(7), 1), (0, 0), (np.uint8(1), 1)])
def test_as_count_takes_any_integer_type(good, minimum):
    count = as_count(good, name="n", minimum=minimum)
    assert count == int(good) and type(count) is int


@pytest.mark.parametrize("bad, minimum", [(0, 1), (-1, 0), (2.0, 1), (True, 0), ("3", 1), (None, 1), (np.float64(4), 1)])
def test_as_count_names_what_is_not_a_count(bad, minimum):
    with pytest.raises(InputError, match=rf"^n_frames: expected an integer >= {minimum}, got "):
        as_count(bad, name="n_frames", minimum=minimum)


def test_as_frame_index_takes_integers_inside_the_take():
    assert as_frame_index(0, 5, name="f") == 0
    assert type(as_frame_index(np.int32(4), 5, name="f")) is int
    for bad in (True, np.bool_(False), 2.0, "1", None):
        with pytest.raises(InputError, match="rest_frame: expected an integer frame index"):
            as_frame_index(bad, 5, name="rest_frame")
    for outside in (-1, 5):
        with pytest.raises(InputError, match=r"f: expected a frame index in \[0, 5\)"):
            as_frame_index(outside, 5, name="f")

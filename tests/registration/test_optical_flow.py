"""Tests for facecap.registration.optical_flow: known sub-pixel shifts recovered, OpenCV's flows as called."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from facecap.errors import InputError
from facecap.registration.optical_flow import optical_flow


def _texture(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """A smooth random pattern of unit scale (waves 10-25 px long), defined at any sub-pixel position."""
    rng = np.random.default_rng(11)
    angle = rng.uniform(0, np.pi, 12)
    k = 2 * np.pi / rng.uniform(10.0, 25.0, 12)
    phase = rng.uniform(0, 2 * np.pi, 12)
    waves = np.cos(k * (np.cos(angle) * x[..., None] + np.sin(angle) * y[..., None]) + phase)
    return 0.4 * waves.sum(axis=-1) / np.sqrt(12 / 2)  # RMS 0.4, within +-1 almost everywhere


@pytest.mark.parametrize("method", ["dis", "farneback"])
@pytest.mark.parametrize("shift", [(2.0, -1.0), (-0.6, 1.4)])
def test_a_known_sub_pixel_shift_is_recovered_with_the_documented_sign(method, shift):
    y, x = np.mgrid[0:96, 0:128].astype(np.float64)
    prev = _texture(x, y)
    nxt = _texture(x - shift[0], y - shift[1])  # the content moved by shift: prev(x) = nxt(x + shift)
    flow = optical_flow(prev, nxt, method=method)
    assert flow.shape == (96, 128, 2) and flow.dtype == np.float64
    inner = flow[16:-16, 16:-16].reshape(-1, 2)
    np.testing.assert_allclose(np.median(inner, axis=0), shift, atol=0.1)
    assert np.mean(np.linalg.norm(inner - shift, axis=1)) < 0.3


def test_the_same_image_does_not_move():
    y, x = np.mgrid[0:64, 0:80].astype(np.float64)
    image = _texture(x, y)
    assert np.abs(optical_flow(image, image, method="dis")).max() == 0.0
    # Farneback's polynomial fits leave a little motion within a window of the border only
    assert np.abs(optical_flow(image, image, method="farneback")[12:-12, 12:-12]).max() < 0.01


def test_dis_is_opencv_on_the_eight_bit_features():
    # features of unit scale go to 128 + 127 x, clipped (here x reaches +-2), rounded to 8 bits
    y, x = np.mgrid[0:64, 0:80].astype(np.float64)
    prev, nxt = 5.0 * _texture(x, y), 5.0 * _texture(x - 1.5, y)
    grey = [np.rint(np.clip(128 + 127 * im, 0, 255)).astype(np.uint8) for im in (prev, nxt)]
    dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    dis.setFinestScale(0)
    np.testing.assert_array_equal(optical_flow(prev, nxt), dis.calc(*grey, None))


def test_refuses_images_of_different_shapes_and_unknown_methods():
    with pytest.raises(InputError, match="same shape"):
        optical_flow(np.zeros((8, 8)), np.zeros((8, 9)))
    with pytest.raises(InputError, match="same shape"):
        optical_flow(np.zeros((8, 8, 3)), np.zeros((8, 8, 3)))
    with pytest.raises(InputError, match="method"):
        optical_flow(np.zeros((8, 8)), np.zeros((8, 8)), method="horn")  # type: ignore[arg-type]

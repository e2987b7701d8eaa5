"""Optical flow against the rest frame puts a sample back on its skin point where the layer below misplaces it."""

import cv2
import numpy as np
import pytest

from facecap.errors import InputError
from facecap.sfs.follow_skin import follow_skin


def _skin(shape=(240, 320), seed=0):
    """Mottled skin with freckles: texture at a few pixels, as footage of skin has."""
    rng = np.random.default_rng(seed)
    base = cv2.GaussianBlur(rng.uniform(0.2, 0.8, shape).astype(np.float32), (0, 0), 3.0)
    dots = (rng.uniform(size=shape) > 0.995).astype(np.float32)
    return np.clip(base - 0.4 * cv2.GaussianBlur(dots, (0, 0), 1.2) * 10, 0.02, 1.0).astype(np.float32)


def _warp(image, shift):
    """The image with its content moved by the smooth field ``shift(x, y)`` (pixels)."""
    H, W = image.shape
    y, x = np.mgrid[0:H, 0:W].astype(np.float32)
    dx, dy = shift(x, y)
    # content at p moves to p + d: read the new image at q from q - d (d slowly varying)
    return cv2.remap(image, x - dx, y - dy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


def test_a_known_sliding_is_recovered_from_the_layers_wrong_prediction():
    rest = _skin()
    head = (12.0, -5.0)  # the head's motion, which the layer below gets right

    def slide(x, y):  # plus a smooth slide along the skin it misses, up to 2.5 px
        return (head[0] + 2.5 * np.sin(x / 60.0), head[1] + 1.5 * np.cos(y / 45.0))

    frame = _warp(rest, slide) * 0.8 + 0.05  # and the shading changed: darker, an offset
    rng = np.random.default_rng(1)
    at = np.c_[rng.uniform(60, 260, 400), rng.uniform(50, 190, 400)]
    truth = at.copy()
    for _ in range(30):  # where the rest point p is now: q with q - d(q) = p
        truth = at + np.stack(slide(truth[:, 0], truth[:, 1]), axis=1)
    predicted = at + np.array(head)
    pixels, followed = follow_skin(rest, frame, at, predicted)
    before = np.linalg.norm(predicted - truth, axis=1)
    after = np.linalg.norm(pixels - truth, axis=1)
    assert followed.mean() > 0.95
    assert np.median(before) > 1.5 and np.median(after) < 0.25  # measured 2.08 -> 0.11 px


def test_a_correction_beyond_the_limit_keeps_the_prediction():
    rest = _skin(seed=2)
    frame = _warp(rest, lambda x, y: (np.full_like(x, 6.0), np.zeros_like(y)))
    at = np.c_[np.linspace(80, 240, 50), np.full(50, 120.0)]
    pixels, followed = follow_skin(rest, frame, at, at, limit_px=4.0)
    assert not followed.any() and np.array_equal(pixels, at)
    pixels, followed = follow_skin(rest, frame, at, at, limit_px=8.0)
    assert followed.all() and np.median(pixels[:, 0] - at[:, 0]) == pytest.approx(6.0, abs=0.2)


def test_mismatched_inputs_are_refused():
    rest = _skin((40, 50))
    with pytest.raises(InputError, match="images"):
        follow_skin(rest, rest[:30], np.zeros((3, 2)), np.zeros((3, 2)))
    with pytest.raises(InputError, match="pixels"):
        follow_skin(rest, rest, np.zeros((3, 2)), np.zeros((4, 2)))

"""BilateralHeights: analytic fields (constant and linear kept inside a grid), a noisy step kept sharp where a
Gaussian of the same width smears it, frames filtered one by one, bad input named."""

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.sfs import DEFAULT_BILATERAL_MM, BilateralHeights

SPACING = 0.05


def grid(k=50):
    x, y = np.meshgrid(np.arange(k) * SPACING, np.arange(k) * SPACING)
    return np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]


def test_constant_and_linear_fields_are_kept_inside_the_grid():
    X = grid()
    flt = BilateralHeights(X, 0.11)  # a reach (0.22 mm) at no lattice distance: every offset has its mirror
    np.testing.assert_array_equal(flt(np.full(len(X), -0.02)), np.full(len(X), -0.02))
    ramp = 0.03 * X[:, 0] - 0.01 * X[:, 1]
    inside = np.all((X[:, :2] > 0.25) & (X[:, :2] < 49 * SPACING - 0.25), axis=1)  # every neighbour within reach
    np.testing.assert_allclose(flt(ramp)[inside], ramp[inside], atol=1e-12)


def test_a_noisy_step_keeps_its_edge_where_a_gaussian_smears_it():
    rng = np.random.default_rng(1)
    X = grid()
    step = np.where(X[:, 0] > 1.225, -0.1, 0.0)  # between two grid columns
    noisy = step + rng.normal(scale=0.005, size=step.size)
    bilateral = BilateralHeights(X, 0.1)(noisy)
    gaussian = BilateralHeights(X, 0.1, range_scale=1e6)(noisy)  # a range kernel this wide is flat
    edge = np.abs(X[:, 0] - 1.225) < 0.03
    away = np.abs(X[:, 0] - 1.225) > 0.3
    assert np.std((bilateral - step)[away]) < 0.5 * np.std((noisy - step)[away])
    assert np.mean(np.abs(bilateral - step)[edge]) < 0.01  # the step is 0.1 deep
    assert np.mean(np.abs(gaussian - step)[edge]) > 0.02


def test_frames_are_filtered_one_by_one():
    rng = np.random.default_rng(2)
    X = grid(20)
    flt = BilateralHeights(X, 0.1)
    frames = rng.normal(scale=0.01, size=(3, len(X)))
    np.testing.assert_allclose(flt(frames), np.stack([flt(f) for f in frames]))
    assert flt(np.zeros((2, len(X)))).shape == (2, len(X))


def test_the_command_line_default_is_the_module_default():
    from facecap.cli import build_parser

    args = build_parser().parse_args(["detail", "--result", "r", "--cameras", "c", "--video", "v", "--lights", "l",
                                      "--out", "o", "--bilateral"])
    assert args.bilateral == DEFAULT_BILATERAL_MM


def test_bad_input_is_named():
    X = grid(5)
    with pytest.raises(InputError, match="positions"):
        BilateralHeights(X[:, :2])
    with pytest.raises(InputError, match="sigma_mm"):
        BilateralHeights(X, 0.0)
    with pytest.raises(InputError, match="heights"):
        BilateralHeights(X, 0.1)(np.zeros(len(X) + 1))

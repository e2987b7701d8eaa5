"""Tests for facecap.synth.smoothstep."""

from __future__ import annotations

import numpy as np

from facecap.synth.smoothstep import smoothstep


def test_is_the_quintic_with_zero_velocity_and_acceleration_at_its_ends():
    x = np.linspace(0.0, 1.0, 101)
    np.testing.assert_allclose(smoothstep(x), 6 * x**5 - 15 * x**4 + 10 * x**3, atol=1e-15)
    # s(x) = P(x): P'(x) = 30 x^2 (x - 1)^2 and P''(x) = 60 x (x - 1)(2x - 1), both 0 at 0 and 1
    p = np.polynomial.Polynomial([0, 0, 0, 10, -15, 6])
    for derivative in (p.deriv(1), p.deriv(2)):
        np.testing.assert_allclose(derivative([0.0, 1.0]), 0.0, atol=1e-12)
    assert smoothstep(np.array(0.5)) == 0.5
    np.testing.assert_allclose(smoothstep(x) + smoothstep(1.0 - x), 1.0, atol=1e-15)  # odd about (1/2, 1/2)
    assert np.all(np.diff(smoothstep(x)) > 0)


def test_is_clipped_outside_the_ramp():
    np.testing.assert_array_equal(smoothstep(np.array([-3.0, -1e-9, 1.0 + 1e-9, 7.0])), [0.0, 0.0, 1.0, 1.0])

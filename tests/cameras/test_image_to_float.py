"""image_to_float, srgb_to_linear and linear_to_srgb: integer ranges to [0, 1], the sRGB standard's values, round trips."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.cameras import image_to_float, linear_to_srgb, srgb_to_linear
from facecap.errors import InputError


def test_image_to_float_and_srgb() -> None:
    np.testing.assert_array_equal(image_to_float(np.array([0, 255], np.uint8)), [0.0, 1.0])
    np.testing.assert_array_equal(image_to_float(np.array([0, 65535], np.uint16)), [0.0, 1.0])
    assert image_to_float(np.array([0.25], np.float64)).dtype == np.float32
    with pytest.raises(InputError, match="uint8, uint16 or float"):
        image_to_float(np.array([1], np.int32))
    # IEC 61966-2-1 reference points: sRGB 0.5 is linear 0.2140; the curve joins at 0.04045
    np.testing.assert_allclose(srgb_to_linear(np.array([0.0, 0.04045, 0.5, 1.0])),
                               [0.0, 0.04045 / 12.92, 0.21404114, 1.0], rtol=1e-6)
    x = np.linspace(0, 1, 1001)
    np.testing.assert_allclose(linear_to_srgb(srgb_to_linear(x)), x, atol=2e-6)


def test_srgb_matches_the_standard_and_keeps_a_computations_precision() -> None:
    # IEC 61966-2-1: 0.5 linear encodes to 0.735357; 0.0031308 sits at the knee (12.92 x)
    np.testing.assert_allclose(linear_to_srgb(np.array([0.0, 0.0031308, 0.18, 0.5, 1.0])),
                               [0.0, 0.04044994, 0.46135612, 0.73535698, 1.0], atol=1e-7)
    x = np.linspace(0, 1, 1001)
    assert srgb_to_linear(x).dtype == np.float64 and linear_to_srgb(x).dtype == np.float64
    np.testing.assert_allclose(srgb_to_linear(linear_to_srgb(x)), x, atol=1e-12)  # float64 in, float64 through
    assert srgb_to_linear(x.astype(np.float32)).dtype == np.float32
    assert srgb_to_linear(np.array([0, 255], np.uint8)).dtype == np.float32

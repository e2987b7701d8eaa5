"""Length units: names, factors, and how the size checks write lengths."""

from __future__ import annotations

import pytest

from facecap.errors import InputError
from facecap.units import mm_per_unit, normalize_unit, three_figures


def test_normalize_and_factor():
    assert normalize_unit(" Metres ") == "m" and mm_per_unit("in") == 25.4
    with pytest.raises(InputError, match="furlong"):
        normalize_unit("furlong")


def test_three_figures_keeps_three_significant_figures():
    assert [three_figures(x) for x in (24.8, 248.4, 24813.0, 0.24813, float("nan"))] == [
        "24.8", "248", "24,800", "0.248", "nan"]

"""Tests for facecap._processes: work spread over worker processes, as if done in this one."""

from __future__ import annotations

import math
import operator
import warnings

import pytest

from facecap._processes import process_map
from facecap._threads import available_cores
from facecap.errors import FacecapWarning


@pytest.mark.parametrize("workers", [1, 2])
def test_results_come_back_in_order_with_the_workers_warnings(workers):
    items = [(float(i), float(i * i)) for i in range(7)]
    with process_map(workers) as each:
        assert each.workers == min(workers, available_cores())  # capped at the cores this process has
        assert each(operator.add, items, desc="add") == [a + b for a, b in items]
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            each(warnings.warn, [("first", FacecapWarning), ("second", UserWarning)], desc="warn")
    assert [(w.category, str(w.message)) for w in caught] == [(FacecapWarning, "first"), (UserWarning, "second")]


@pytest.mark.parametrize("workers", [1, 2])
def test_a_workers_error_is_raised_here(workers):
    with process_map(workers) as each, pytest.raises(ValueError, match="math domain error"):
        each(math.sqrt, [(4.0,), (-1.0,), (9.0,)], desc="sqrt")

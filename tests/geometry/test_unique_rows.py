"""`unique_rows` is numpy's unique over rows, by Python's sort for few rows and numpy's for many."""

from __future__ import annotations

import numpy as np
import pytest

from trajcache.geometry.validation.segments import _FEW_ROWS, unique_rows


@pytest.mark.parametrize("count", [1, 2, 9, _FEW_ROWS, _FEW_ROWS + 1, 3 * _FEW_ROWS])
@pytest.mark.parametrize("width", [2, 3])
def test_unique_rows_are_numpy_s_sorted_rows_and_their_inverse(count: int, width: int) -> None:
    rng = np.random.default_rng(count * width)
    rows = rng.integers(0, 6, (count, width)).astype(np.int64)
    unique, where = unique_rows(rows)
    expected, inverse = np.unique(rows, axis=0, return_inverse=True)
    np.testing.assert_array_equal(unique, expected)
    np.testing.assert_array_equal(where, inverse.reshape(-1))
    np.testing.assert_array_equal(unique[where], rows)
    assert unique.dtype == np.int64 and where.dtype.kind == "i"

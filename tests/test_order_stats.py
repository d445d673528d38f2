"""The fast order statistics give numpy's own median and percentile (linear method)."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from signlane import order_stats

values = st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=1, max_size=60)


@settings(max_examples=200, deadline=None)
@given(values, st.floats(0.0, 1.0))
def test_quantiles_are_numpys(xs, q):
    a = np.array(xs)
    want = float(np.percentile(a, 100 * q))
    assert order_stats.quantile(a, q) == pytest.approx(want, rel=1e-12, abs=1e-9)
    assert order_stats.sorted_quantile(np.sort(a), q) == pytest.approx(want, rel=1e-12, abs=1e-9)


@settings(max_examples=200, deadline=None)
@given(values)
def test_medians_are_numpys(xs):
    a = np.array(xs)
    assert order_stats.median(a) == float(np.median(a))
    assert order_stats.sorted_median(np.sort(a)) == float(np.median(a))


def test_integer_columns_and_the_input_left_alone():
    a = np.array([7, 1, 4, 9, 2], np.int64)
    assert order_stats.median(a) == 4.0 and order_stats.quantile(a, 0.02) == pytest.approx(1.08)
    assert a.tolist() == [7, 1, 4, 9, 2]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(*(st.integers(0, 255),) * 3), min_size=1, max_size=80))
def test_row_medians_of_a_colour_patch_are_numpys(rows):
    a = np.array(rows, np.int16)
    assert np.array_equal(order_stats.median_rows(a), np.median(a, axis=0))
    assert np.array_equal(order_stats.median_rows(a.astype(np.uint8)), np.median(a, axis=0))

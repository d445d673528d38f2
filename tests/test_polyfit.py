"""The boundary fit's least squares (lanes/geometry.polyfit) against numpy's: the same curve on
weighted and unweighted points, short and long spans, and points on too few rows."""
import warnings

import numpy as np
import pytest

from signlane.lanes.geometry import fit_boundary, polyfit


@pytest.mark.parametrize("order", [1, 2])
def test_the_fit_is_numpys(order):
    rng = np.random.default_rng(3)
    worst = 0.0
    for k in range(300):
        n = int(rng.integers(3, 150))
        y = rng.uniform(0.5, 25.0, n) if k % 2 else rng.uniform(3.0, 4.5, n)
        x = 0.02 * y ** 2 - 0.3 * y + 1.5 + rng.normal(0, 0.2, n)
        w = rng.uniform(0.1, 4.0, n) if k % 3 == 0 else None
        want = np.polyfit(y, x, order, w=None if w is None else np.sqrt(w))
        got = polyfit(y, x, order, w)
        worst = max(worst, float(np.abs(np.polyval(want, y) - np.polyval(got, y)).max()))
    assert worst < 1e-9


def test_points_on_fewer_rows_than_coefficients_fit_as_numpy_does():
    y = np.array([2.0, 2.0, 6.0, 6.0, 6.0, 2.0])
    x = np.array([1.0, 1.2, 0.4, 0.5, 0.6, 1.1])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # numpy's RankWarning
        want = np.polyfit(y, x, 2)
        got = polyfit(y, x, 2)
    assert np.allclose(np.polyval(want, y), np.polyval(got, y), atol=1e-9)


def test_a_boundary_of_a_bend_keeps_its_curvature():
    y = np.linspace(1.0, 12.0, 40)
    b = fit_boundary(np.column_stack([0.05 * y ** 2 - 0.2 * y + 1.8, y]))
    assert np.allclose(b.coeffs, [0.05, -0.2, 1.8], atol=1e-12) and b.support == 40

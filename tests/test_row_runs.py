"""The carriageway scan's runs of road per row (road_edges.row_runs) are each row's runs as a
walk along it finds them, for any mask (edges, single pixels, empty and full rows)."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from signlane.lanes.road_edges import row_runs


def _walk(mask: np.ndarray):
    starts, ends, bounds = [], [], [0]
    for row in mask:
        inside = False
        for col, v in enumerate(row.tolist()):
            if v and not inside:
                starts.append(col)
            if inside and not v:
                ends.append(col - 1)
            inside = v
        if inside:
            ends.append(len(row) - 1)
        bounds.append(len(starts))
    return starts, ends, bounds


@settings(max_examples=200, deadline=None)
@given(arrays(np.bool_, st.tuples(st.integers(1, 12), st.integers(1, 12))))
def test_row_runs_are_a_walk_along_each_row(mask):
    assert row_runs(mask) == _walk(mask)


def test_row_runs_of_a_road_mask():
    mask = np.zeros((3, 8), bool)
    mask[0, 2:5] = True  # one run
    mask[1, [0, 1, 3, 7]] = True  # runs at both edges and a lone pixel
    assert row_runs(mask) == ([2, 0, 3, 7], [4, 1, 3, 7], [0, 1, 4, 4])

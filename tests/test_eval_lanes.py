"""`signlane eval lanes`: the shared-frames median that makes methods comparable."""
import math

import numpy as np
import pytest

from signlane.evaluate import add_common_errors, eval_lanes


def test_the_shared_median_is_over_the_frames_every_method_found():
    rows = [{"method": "a"}, {"method": "b"}]
    # a finds frames 0-3 (frame 3 hard), b only 0-2: a's own median carries the hard frame
    errors = [{0: 0.01, 1: 0.02, 2: 0.03, 3: 0.5}, {0: 0.04, 1: 0.05, 2: 0.06}]
    add_common_errors(rows, errors)
    assert rows[0]["offset_err_median_common"] == pytest.approx(0.02)
    assert rows[1]["offset_err_median_common"] == pytest.approx(0.05)
    assert rows[0]["common_frames"] == rows[1]["common_frames"] == 3
    rows = [{"method": "a"}, {"method": "b"}]
    add_common_errors(rows, [{0: 0.1}, {1: 0.1}])  # nothing shared: no number rather than a wrong one
    assert math.isnan(rows[0]["offset_err_median_common"]) and rows[0]["common_frames"] == 0


def test_eval_lanes_hands_back_each_found_frames_error():
    errors: dict[int, float] = {}
    row = eval_lanes("sliding-window", n=6, seed=1000, progress=False, errors=errors)
    assert len(errors) == round(row["found_pct"] / 100 * 6)
    assert all(0 <= e < 1 for e in errors.values())
    assert float(np.median(list(errors.values()))) == pytest.approx(row["offset_err_median"])


def test_the_cli_prints_the_shared_column(capsys):
    from signlane.cli import main
    assert main(["eval", "lanes", "--n", "4", "--method", "sliding-window", "--method", "canny-scan"]) == 0
    out = capsys.readouterr().out
    assert "off med shared" in out and "frames that every method above found" in out

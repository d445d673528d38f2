"""The one place pixels become model input (onnx_model.prepare_input): its area shrink made as
halvings where the frame is an even multiple of the input size."""
import cv2
import numpy as np
import pytest

from signlane.onnx_model import InputSpec, halved, prepare_input


def _frame(w: int, h: int) -> np.ndarray:
    rng = np.random.default_rng(w * h)
    noise = rng.integers(0, 256, (h, w, 3), np.uint8)
    # texture at every scale: fine noise over smooth gradients and hard edges
    yy, xx = np.mgrid[0:h, 0:w]
    smooth = np.stack([(xx * 255 // w), (yy * 255 // h), ((xx // 37 + yy // 23) % 2) * 255], -1).astype(np.uint8)
    return cv2.addWeighted(noise, 0.5, smooth, 0.5, 0)


@pytest.mark.parametrize("size, steps", [((640, 480), 2), ((1280, 720), 1), ((320, 240), 1), ((500, 375), 0)])
def test_halvings_stay_within_a_grey_level_of_one_area_resize(size, steps):
    f = _frame(*size)
    h = halved(f, 160, 120)
    assert h.shape[1] == size[0] >> steps and h.shape[0] == size[1] >> steps  # halved only while exact
    fast = cv2.resize(h, (160, 120), interpolation=cv2.INTER_AREA)
    direct = cv2.resize(f, (160, 120), interpolation=cv2.INTER_AREA)
    diff = np.abs(fast.astype(int) - direct.astype(int))
    assert diff.max() <= 1 and diff.mean() < 0.5
    if steps == 0:
        assert np.array_equal(fast, direct)


def test_model_input_of_a_640x480_frame_matches_the_direct_resize():
    spec = InputSpec(160, 120, "RGB", "NCHW", 1.0 / 255.0, (0.45, 0.45, 0.45), (0.25, 0.25, 0.25))
    f = _frame(640, 480)
    x = prepare_input([f], spec)[0]
    direct = cv2.cvtColor(cv2.resize(f, (160, 120), interpolation=cv2.INTER_AREA), cv2.COLOR_BGR2RGB)
    ref = (direct.transpose(2, 0, 1) / 255.0 - 0.45) / 0.25
    assert x.shape == (3, 120, 160)
    assert np.abs(x - ref).max() <= 1.0 / 255.0 / 0.25 + 1e-5  # one grey level

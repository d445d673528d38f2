"""Fixtures shared by the lane-method tests (scenes are built once per module that asks)."""
import pytest

from lane_helpers import CLEAN, clean_samples, drive_stretches, loop_scene
from signlane.world.sampling import DriveSampler


@pytest.fixture(scope="module")
def lane_loop():
    """(route, renderer) on the bundled loop_demo map."""
    return loop_scene()


@pytest.fixture(scope="module")
def clean_frames():
    return clean_samples()


@pytest.fixture(scope="module")
def drive():
    """A clean drive whose route has a straight, a right bend and a left bend (the first seed
    from 4 on whose random walk has all three)."""
    for seed in range(4, 60):
        d = DriveSampler(seed, CLEAN)
        try:
            drive_stretches(d)
            return d
        except AssertionError:
            continue
    raise AssertionError("no drive seed with a straight, a right and a left bend")


@pytest.fixture(scope="module")
def stretches(drive):
    return drive_stretches(drive)

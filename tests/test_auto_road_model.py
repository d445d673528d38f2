"""auto with a road model: the carriageway and the paint come from the model's maps instead of
colour rules. Given the renderer's truth as the model's output, random looks whose verge the
colour rules take for road (VIA style) or whose road they cannot find (painted) give the lane."""
import numpy as np
import pytest

from signlane.camera import via_camera
from signlane.lanes import seg_model
from signlane.lanes.auto import AutoParams, AutoState, auto
from signlane.lanes.seg_model import FrameMaps, output_to_frame
from signlane.sim.simulator import SimConfig, Simulator
from signlane.world.maps import load_track


def _start_frame(style: str, seed: int):
    """The simulator's first frame of a random-looks track, rendered with its truth."""
    sim = Simulator(load_track("random", style, seed), SimConfig(random_looks=True, looks_seed=seed))
    pose = sim._ahead(sim.config.camera_forward_m + sim.vehicle.params.wheelbase_m / 2)
    return sim.renderer.render(pose, sim.camera)


class _TruthModel:
    """A stand-in road model whose maps are the renderer's truth (at the model's 160x120)."""

    has_drivable = True

    def __init__(self, sample):
        import cv2
        self.road = cv2.resize((sample.truth.drivable_mask > 0).astype(np.float32), (160, 120), cv2.INTER_AREA)
        self.paint = cv2.resize((sample.truth.marking_mask > 0).astype(np.float32), (160, 120), cv2.INTER_AREA)

    def frame_maps(self, image_bgr, threshold=seg_model.MASK_THRESHOLD):
        h, w = image_bgr.shape[:2]
        return FrameMaps(self.paint, self.road, output_to_frame(self.road.shape, w, h), threshold)


def _drive(sample, monkeypatch, frames=4, model_paint=False):
    monkeypatch.setattr(seg_model, "load", lambda path, threads=1: _TruthModel(sample))
    h, w = sample.image.shape[:2]
    cam, state, est = via_camera(w, h), None, None
    for _ in range(frames):  # the car stands: the same frame again
        est, state = auto(sample.image, cam, AutoParams(model="truth.onnx", model_paint=model_paint), state)
    return est, state


@pytest.mark.parametrize("seed", [5, 10])
def test_kerbed_road_on_a_road_coloured_verge_is_the_models_carriageway(seed, monkeypatch):
    est, state = _drive(_start_frame("via", seed), monkeypatch)
    assert isinstance(state, AutoState) and not state.two_lane
    assert est.found and est.basis == "edges"
    assert abs(state.road.width_m - 4.0) < 0.4, state.road.width_m  # VIA's 4 m carriageway (colour rules: 8 m)
    assert abs(est.offset) < 0.06 and abs(est.heading) < 0.03  # the car starts on its middle
    assert state.road.scan is not None and state.road.scan.road is not None  # junctions read this scan


@pytest.mark.parametrize("model_paint", [False, True])
@pytest.mark.parametrize("seed", [8, 18])
def test_painted_road_the_colour_rules_cannot_find_keeps_the_right_lane(seed, model_paint, monkeypatch):
    est, state = _drive(_start_frame("painted", seed), monkeypatch, frames=6, model_paint=model_paint)
    assert state.two_lane  # the model's paint shows the centre line
    assert est.found and est.basis == "paint"
    assert abs(est.offset) < 0.1 and abs(est.heading) < 0.05  # the car starts on its lane's centre

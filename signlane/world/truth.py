"""Ground truth of a rendered frame: masks, ego-lane polylines, pose in lane, signs, junction."""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from signlane.angles import wrap_pi
from signlane.camera import Camera
from signlane.world.art import SIGN_NAMES
from signlane.world.objects import DrawnObject
from signlane.world.route import Pose, Route

LOOKAHEAD_M = 60.0
# the renderer's paint ids: 0 off-road, 1 asphalt, 2-5 paint (white, yellow, faded white/yellow), 6 kerb
_MARKING_LUT = np.zeros(256, np.uint8)
_MARKING_LUT[2:6] = 255
_DRIVABLE_LUT = np.zeros(256, np.uint8)
_DRIVABLE_LUT[1:6] = 255
_KERB_LUT = np.zeros(256, np.uint8)
_KERB_LUT[6] = 255
POLYLINE_STEP_M = 0.5
CURVATURE_WINDOW_M = (2.0, 15.0)


@dataclass(frozen=True)
class SignTruth:
    label: str
    box: tuple[int, int, int, int]  # x, y, w, h of the visible face pixels
    distance: float  # metres, on the ground, camera to sign
    occluded: float  # fraction of in-image face pixels hidden by nearer objects
    truncated: float  # fraction of the face outside the image


@dataclass(frozen=True)
class JunctionTruth:
    distance: float  # metres along the route to the junction's edge
    exits: tuple[str, ...]  # turns available there: left / right / straight
    chosen: str  # the turn this route takes


@dataclass(frozen=True)
class GroundTruth:
    camera: Camera
    pose: Pose
    marking_mask: np.ndarray  # uint8 (H, W) 0/255: visible lane paint
    drivable_mask: np.ndarray  # uint8 (H, W) 0/255: road surface
    kerb_mask: np.ndarray  # uint8 (H, W) 0/255: kerbs (VIA's white kerb stripes beside the road)
    left: np.ndarray  # (N, 2) float image pixels, near to far; ego-lane left boundary
    right: np.ndarray
    center: np.ndarray
    offset: float = 0.0  # fraction of lane width, + = car right of centre
    heading: float = 0.0  # radians, + = car points right of the lane
    curvature: float = 0.0  # 1/m ahead, + = bends right
    lane_width_m: float = 0.0
    signs: tuple[SignTruth, ...] = ()
    junction: JunctionTruth | None = None
    distractors: tuple[tuple[str, tuple[int, int, int, int]], ...] = field(default=())
    nominal_camera: Camera | None = None  # the camera before per-frame pose jitter (what a user calibrates)

    def to_label(self) -> dict:
        """The dataset contract's lane/sign fields (JSON-serialisable)."""
        def pl(a):
            return [[round(float(x), 2), round(float(y), 2)] for x, y in a]
        out = {"lane": {"left": pl(self.left), "right": pl(self.right), "center": pl(self.center),
                        "offset": round(self.offset, 5), "heading": round(self.heading, 5),
                        "curvature": round(self.curvature, 6), "lane_width_m": round(self.lane_width_m, 3)},
               "signs": [{"label": s.label, "box": list(s.box), "distance": round(s.distance, 3),
                          "occluded": round(s.occluded, 3), "truncated": round(s.truncated, 3)} for s in self.signs],
               "pose": {"x": round(self.pose.x, 4), "y": round(self.pose.y, 4), "heading": round(self.pose.heading, 6)},
               "camera": {"hfov_deg": self.camera.hfov_deg, "height_m": round(self.camera.height_m, 4),
                          "pitch_deg": round(self.camera.pitch_deg, 4), "roll_deg": round(self.camera.roll_deg, 4),
                          "yaw_deg": round(self.camera.yaw_deg, 4)}}
        if self.junction is not None:
            out["junction"] = {"distance": round(self.junction.distance, 3), "exits": list(self.junction.exits),
                               "chosen": self.junction.chosen}
        return out


def compute_truth(scene, pose: Pose, camera: Camera, paint_ids: np.ndarray, drawn: list[DrawnObject],
                  route: Route | None, s_hint: float | None) -> GroundTruth:
    marking = cv2.LUT(paint_ids, _MARKING_LUT)
    drivable = cv2.LUT(paint_ids, _DRIVABLE_LUT)
    kerb = cv2.LUT(paint_ids, _KERB_LUT)
    signs, others = _objects_truth(drawn, camera)
    empty = np.zeros((0, 2), np.float32)
    if route is None:
        return GroundTruth(camera, pose, marking, drivable, kerb, empty, empty, empty, signs=signs, distractors=others)
    s, lateral = route.project(pose.x, pose.y, s_hint)
    lw = route.track.style.lane_width
    heading = wrap_pi(route.pose_at(s).heading - pose.heading)
    idx = route.ahead(s - 2.0, LOOKAHEAD_M)
    step = max(1, int(POLYLINE_STEP_M / max(route.length / len(route.s), 1e-6)))
    idx = idx[::step]
    lane, right = route.lane[idx], route.right[idx]
    lines = [_image_polyline(pose, camera, lane + k * (lw / 2) * right) for k in (-1, 1, 0)]
    win = route.ahead(s + CURVATURE_WINDOW_M[0], CURVATURE_WINDOW_M[1] - CURVATURE_WINDOW_M[0])
    curvature = float(np.mean(route.curvature[win])) if len(win) else 0.0
    return GroundTruth(camera, pose, marking, drivable, kerb, *lines, offset=lateral / lw, heading=heading,
                       curvature=curvature, lane_width_m=lw, signs=signs, junction=_junction(route, s),
                       distractors=others)


def _image_polyline(pose: Pose, camera: Camera, world: np.ndarray) -> np.ndarray:
    """World points -> image pixels, keeping the run in front of the camera and inside the frame."""
    g = pose.to_ground(world)
    pix, depth = camera.project(np.column_stack([g, np.zeros(len(g))]))
    inside = (depth > 0.5) & (pix[:, 0] >= 0) & (pix[:, 0] <= camera.width - 1) \
        & (pix[:, 1] >= 0) & (pix[:, 1] <= camera.height - 1)
    if not inside.any():
        return np.zeros((0, 2), np.float32)
    # the first contiguous run of visible points (near to far)
    first = int(np.argmax(inside))
    stop = first + int(np.argmin(inside[first:])) if not inside[first:].all() else len(inside)
    return pix[first:stop].astype(np.float32)


def _junction(route: Route, s: float) -> JunctionTruth | None:
    """The junction the car is in, up to halfway through it (distance 0: a T-junction's block
    is three cells long, so the car can be in it well before its branch), else the next one
    ahead within one lap (or the route's end)."""
    legs = route.legs
    cur = route.leg_at(s)
    k = legs.index(cur)
    here = s % route.length if route.closed else s
    end = legs[k + 1].s0 if k + 1 < len(legs) else route.length
    for j in range(0 if here < (cur.s0 + end) / 2 else 1, len(legs) + 1):
        if not route.closed and k + j >= len(legs):
            return None
        leg = legs[(k + j) % len(legs)]
        if leg.tile.junction:
            dist = 0.0 if j == 0 else leg.s0 - here
            if dist < 0:
                dist += route.length
            exits = tuple(sorted(route.track.turn_of(leg.entry, p)
                                 for p in route.track.viable_exits(leg.tile, leg.entry)))  # no dead ends
            return JunctionTruth(float(dist), exits, leg.turn)
    return None


def _objects_truth(drawn: list[DrawnObject], camera: Camera):
    H, W = camera.height, camera.width
    owner = np.zeros((H, W), np.int32)  # index+1 of the nearest face drawn at each pixel
    for k, d in enumerate(drawn):  # drawn far to near: later ones occlude
        x0, y0, x1, y1 = d.box_roi
        owner[y0:y1, x0:x1][d.face] = k + 1
    signs, others = [], []
    for k, d in enumerate(drawn):
        x0, y0, x1, y1 = d.box_roi
        mine = d.face.sum()
        if mine == 0:
            continue
        ys, xs = np.nonzero(d.face)
        box = (int(x0 + xs.min()), int(y0 + ys.min()), int(xs.max() - xs.min() + 1), int(ys.max() - ys.min() + 1))
        visible = int((owner[y0:y1, x0:x1][d.face] == k + 1).sum())
        occluded = 1.0 - visible / mine
        truncated = float(np.clip(1.0 - mine / max(d.total_px, 1.0), 0.0, 1.0))
        if d.obj.kind in SIGN_NAMES and d.front:
            signs.append(SignTruth(d.obj.kind, box, d.distance, float(occluded), truncated))
        else:
            others.append((d.obj.kind, box))
    return tuple(signs), tuple(others)

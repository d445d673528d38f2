"""`signlane autolabel lanes`: a lane method on a user's own images and videos; its confident
frames become a pseudo-labelled lane dataset in the synthetic sets' layout, so training can mix
them (classical filtering produces labels; the network then learns to generalise them).

The mask of a kept frame is the method's debug mask: for sliding-window the lane-paint pixels of
the two ego boundaries it fitted (other lanes' paint is labelled background, so keep such sets a
minority beside synthetic ones); for segnet its whole marking mask (self-training). Frames are
kept only when the method found the lane with `min_confidence` and painted pixels to learn from.
The mask is class ids (signlane.label_masks): 1 on that paint, 0 below and beside it, and 255
(ignore) on every row farther than the farthest paint it labelled: the method says nothing about
what lies beyond the lines it followed (sliding-window looks 8 m ahead, 16 m when that shows no
line), so paint there is unknown, not background.

Beside the paint, each kept frame where `road-edges` finds both edges of the carriageway
confidently gets a road-surface mask, drivable/<id>.png (ids: 1 road, 0 not, 255 outside what it
looked at; its label gains "drivable"), so a road model learns the drivable area from the
footage too. With camera.estimate "auto" each input's camera is measured from its own frames
(signlane/camera_estimate.py), as `signlane infer` does.

Layout of `out/`: images/<id>.jpg, masks/<id>.png (ids 0/1/255), drivable/<id>.png, labels.jsonl (the lane contract;
"pseudo": {"method", "confidence"} added), sheet.png (kept frames; ignored rows darkened),
rejected.png (a sample of the dropped ones), manifest.json (written last; "mask_encoding").
"""
from __future__ import annotations

import itertools
import logging
import sys
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from signlane_data.common import DatasetError, atomic_imwrite, atomic_write_text, write_manifest
from signlane_data.lanes import JPEG_QUALITY, teacher_steering
from signlane.draw import contact_sheet
from signlane_data.preview import lane_overlay
from signlane import label_masks, lanes
from signlane.camera import Camera
from signlane.camera_estimate import choose_camera
from signlane.config import CameraConfig
from signlane.media import MediaError, expand, iter_frames
from signlane.types import LaneEstimate

log = logging.getLogger(__name__)
SHEET_MAX = 48
MIN_MASK_PX = 30  # a kept frame must have at least this much paint labelled
ESTIMATE_FRAMES = 48  # an input's camera is measured on its first sampled frames (camera.estimate auto)


def lane_record(sid: str, est: LaneEstimate, width: int, height: int, method: str) -> dict:
    """The labels.jsonl object of a pseudo-labelled frame (the lane dataset contract)."""
    def pl(a):
        return [] if a is None else [[round(float(x), 2), round(float(y), 2)] for x, y in a]
    return {"id": sid, "image": f"images/{sid}.jpg", "mask": f"masks/{sid}.png", "width": width, "height": height,
            "lane": {"left": pl(est.left), "right": pl(est.right), "center": pl(_center(est.left, est.right)),
                     "offset": round(float(est.offset), 5), "heading": round(float(est.heading), 5),
                     "curvature": round(float(est.curvature), 6)},
            "signs": [], "steering": teacher_steering(est.offset, est.heading, est.curvature),
            "pseudo": {"method": method, "confidence": round(float(est.confidence), 3)}}


def autolabel_lanes(paths: list[str], out: str | Path, method: str = "sliding-window",
                    camera: CameraConfig = CameraConfig(), min_confidence: float = 0.7, every: int = 10,
                    progress: bool = True) -> dict:
    """Write the confident frames of `paths` as a lane dataset; returns counts and failed inputs."""
    import json
    out = Path(out)
    if out.exists() and any(out.iterdir()):
        raise DatasetError(f"{out} is not empty; choose a new or empty folder")
    lanes.params_for(method)  # an unknown method fails before any work
    sources, failed = expand(paths)
    for e in failed:
        print(f"signlane autolabel: {e}", file=sys.stderr)
    records, kept_tiles, rejected_tiles, seen, roads, cameras = [], [], [], 0, 0, {}
    for src in tqdm(sources, desc="autolabel lanes", unit="input", disable=not progress or len(sources) < 2):
        try:
            frames = iter_frames(src, every)
            cam_cfg = camera
            if camera.estimate == "auto":  # the input's own camera, as infer measures it
                head = list(itertools.islice(frames, ESTIMATE_FRAMES))
                choice = choose_camera([f for _, f in head], camera)
                cam_cfg, cameras[str(src.path)] = choice.camera, choice.describe()
                frames = itertools.chain(head, frames)
            for index, frame in frames:
                seen += 1
                h, w = frame.shape[:2]
                cam = cam_cfg.camera(w, h)
                est = lanes.get(method, camera=cam)(frame)  # fresh state: frames stand alone
                mask = pseudo_mask(est.debug_mask if est.debug_mask is not None else np.zeros((h, w), np.uint8))
                if not (est.found and est.confidence >= min_confidence and np.count_nonzero(mask == 1) >= MIN_MASK_PX):
                    if len(rejected_tiles) < SHEET_MAX:
                        rejected_tiles.append(lane_overlay(frame, mask, {"left": _pts(est.left), "right": _pts(est.right)}))
                    continue
                sid = f"{src.path.stem}_{index:06d}"
                atomic_imwrite(out / "images" / f"{sid}.jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
                atomic_imwrite(out / "masks" / f"{sid}.png", mask)
                rec = lane_record(sid, est, w, h, method)
                road = road_pseudo_mask(frame, cam, min_confidence)
                if road is not None:
                    atomic_imwrite(out / "drivable" / f"{sid}.png", road)
                    rec["drivable"] = f"drivable/{sid}.png"
                    roads += 1
                records.append(rec)
                if len(kept_tiles) < SHEET_MAX:
                    kept_tiles.append(lane_overlay(frame, mask, rec["lane"]))
        except MediaError as e:
            print(f"signlane autolabel: {e}", file=sys.stderr)
            failed.append(str(e))
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "labels.jsonl", "".join(json.dumps(r) + "\n" for r in records))
    for name, tiles in (("sheet.png", kept_tiles), ("rejected.png", rejected_tiles)):
        if tiles:
            atomic_imwrite(out / name, contact_sheet(tiles, 6, (240, 180), list(_ids(records, name, len(tiles))), gap=0))
    counts = {"seen": seen, "kept": len(records), "drivable": roads}
    config = {"method": method, "min_confidence": min_confidence, "every": every, "camera": camera.__dict__,
              "cameras": cameras, "inputs": [str(p) for p in paths]}
    write_manifest(out, "autolabel_lanes", 0, counts, config, **{label_masks.MANIFEST_KEY: label_masks.IDS})
    log.info("%s: kept %d of %d frames", out, len(records), seen)  # `signlane autolabel` says when none
    return {"counts": counts, "failed": failed}


def road_pseudo_mask(frame: np.ndarray, cam: Camera, min_confidence: float) -> np.ndarray | None:
    """The road surface as `road-edges` sees it, as ids, where it found both edges of the
    carriageway with min_confidence: 1 on road-coloured ground between the edges it scanned, 0
    on ground it saw that is not road-coloured and above the horizon (sky is no road), 255
    elsewhere: road-coloured ground outside the edges (another lane, or a verge that looks like
    road: it cannot tell) and ground outside its bird's-eye view or beyond the rows it scanned.
    None when it is not confident (the frame then has no road label)."""
    method = lanes.get("road-edges", camera=cam)
    est = method(frame)
    state = method.state
    bev, scan = getattr(state, "bev", None), getattr(state, "scan", None)
    if not (est.found and est.confidence >= min_confidence) or est.drivable_mask is None or bev is None \
            or scan is None or len(scan.y) < 2:
        return None
    seen = bev.unwarp(np.full((bev.size[1], bev.size[0]), 255, np.uint8), cv2.INTER_NEAREST) > 0
    outline = np.concatenate([np.column_stack([scan.edge_l, scan.y]), np.column_stack([scan.edge_r, scan.y])[::-1]])
    between = np.zeros(frame.shape[:2], np.uint8)
    cv2.fillPoly(between, [np.round(cam.ground_to_image(outline)).astype(np.int32)], 1)
    road = est.drivable_mask > 0
    on = road & seen & (between > 0)
    ids = label_masks.encode(on, cam.ground_mask(0.0) & ~(seen & ~road) & ~on)
    return ids


def pseudo_mask(debug_mask: np.ndarray) -> np.ndarray:
    """A method's debug mask uint8 (H, W), nonzero = the paint it labelled -> uint8 (H, W) ids:
    1 on that paint, 255 on the rows above (farther than) its farthest pixel, 0 elsewhere (all 0
    when it labelled nothing)."""
    paint = debug_mask > 0
    rows = np.flatnonzero(paint.any(axis=1))
    beyond = np.zeros_like(paint)
    if len(rows):
        beyond[:rows[0]] = True
    return label_masks.encode(paint, beyond)


def _center(left, right) -> np.ndarray | None:
    """Midpoints of the boundaries row by row (image rows; the polylines' points do not pair up
    by index once each was clipped to the frame)."""
    if left is None or right is None or len(left) < 2 or len(right) < 2:
        return None
    order = np.argsort(right[:, 1])
    ry, rx = right[order, 1], right[order, 0]
    keep = (left[:, 1] >= ry[0]) & (left[:, 1] <= ry[-1])
    if keep.sum() < 2:
        return None
    return np.column_stack([0.5 * (left[keep, 0] + np.interp(left[keep, 1], ry, rx)), left[keep, 1]])


def _pts(a) -> list:
    return [] if a is None else a.tolist()


def _ids(records: list[dict], sheet: str, n: int) -> list[str]:
    """Tile captions: the ids of kept frames (rejected ones are not written, so no captions)."""
    return [r["id"] for r in records[:n]] if sheet == "sheet.png" else [""] * n

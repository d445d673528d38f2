"""`signlane demo`: a short drive on the bundled map (or a seeded procedural track), for people.

Writes `drive.mp4` (camera view beside the same view with ground truth drawn on it),
`contact_sheet.png` (evenly spaced annotated frames) and `track.png` (the track from above with
the driven path). The closed-loop drive replaces the scripted path once the driving stack lands.
"""
from __future__ import annotations

import json
import logging
from importlib import resources
from pathlib import Path

import numpy as np
from tqdm import tqdm

from signlane.draw import VideoOut, contact_sheet, draw_boxes, draw_hud, draw_lane, overlay_mask, write_image
from signlane.world.sampling import DriveSampler, SamplerConfig
from signlane.world.topdown import draw_topdown
from signlane.world.track import Track
from signlane.world.truth import GroundTruth

log = logging.getLogger(__name__)


def annotate_truth(image: np.ndarray, truth: GroundTruth, t: float | None = None) -> np.ndarray:
    """A copy of image with the ground truth drawn on it (masks, lane lines, signs, HUD)."""
    out = overlay_mask(image.copy(), truth.marking_mask, alpha=0.45)
    draw_lane(out, truth.left, truth.right, truth.center)
    draw_boxes(out, [(s.label, None, s.box) for s in truth.signs])
    hud = [f"offset {truth.offset:+.2f} lane  heading {np.degrees(truth.heading):+.1f} deg",
           f"curvature {truth.curvature:+.4f} 1/m"]
    if truth.junction is not None:
        j = truth.junction
        hud.append(f"junction in {j.distance:.0f} m: {'/'.join(j.exits)} -> {j.chosen}")
    if t is not None:
        hud.insert(0, f"t {t:5.2f} s")
    return draw_hud(out, hud)


def bundled_map(name: str = "loop_demo") -> Track:
    """A map shipped in signlane/world/maps."""
    return Track.from_via(json.loads(resources.files("signlane.world").joinpath(f"maps/{name}.json").read_text()),
                          source=name)


def run_demo(out: str | Path, seed: int = 0, seconds: float = 20.0, fps: float = 20.0,
             width: int = 640, height: int = 480, speed_mps: float = 9.0, track: Track | None = None) -> dict:
    """Render the drive (on the bundled loop_demo map unless a track is given); returns the
    paths written and the frame count."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    sampler = DriveSampler(seed, SamplerConfig(width=width, height=height, effects="clean", randomise=False),
                           speed_mps=speed_mps, fps=fps, track=track or bundled_map())
    n = max(1, int(round(seconds * fps)))
    picks = set(np.linspace(0, n - 1, 12).astype(int).tolist())
    sheet, path = [], []
    with VideoOut(out / "drive.mp4", fps, (2 * width, height)) as video:
        for i in tqdm(range(n), desc="demo drive", unit="frame"):
            smp = sampler.sample(i)
            ann = annotate_truth(smp.image, smp.truth, i / fps)
            video.write(np.hstack([smp.image, ann]))
            path.append((smp.truth.pose.x, smp.truth.pose.y))
            if i in picks:
                sheet.append(ann)
    write_image(out / "contact_sheet.png", contact_sheet(sheet, cols=4, tile=(width // 2, height // 2)))
    write_image(out / "track.png", draw_topdown(sampler.renderer.scene, path_xy=np.array(path)))
    files = {"video": str(out / "drive.mp4"), "contact_sheet": str(out / "contact_sheet.png"),
             "track": str(out / "track.png")}
    return {"frames": n, "files": files}

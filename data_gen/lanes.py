"""Lane dataset: rendered frames, lane-marking masks and labels (the design's lane contract).

Layout of `out/`:
    images/<id>.jpg      uint8 BGR frame, JPEG quality 95
    masks/<id>.png       uint8 class ids, the frame's size: 0 background, 1 lane marking
    drivable/<id>.png    uint8 class ids: 0 off the road, 1 road surface (only with drivable=True)
    (kerbs are 255, no label, in both masks; so is paint the frame does not show, in masks/)
    labels.jsonl         one JSON object per frame, in id order (see `frame_label`)
    manifest.json        written last: the folder is complete iff it exists; its
                         "mask_encoding" is signlane.label_masks.IDS ("ids-0-1-255ignore")

The masks' only 255s (ignore) are kerbs (VIA style, see `write_frame`) and, in masks/, paint
that the frame's effects and look leave the colour of the road beside it
(signlane.paint_visibility): the renderer labels every other pixel it draws. The sky holds no paint
and is background (a model must learn not to find paint there); beyond the renderer's view range
it draws neither paint nor road, in the image as in the masks.
"""
from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

from signlane_data.common import (PARTIAL, atomic_imwrite, atomic_write_json, atomic_write_text, file_intact,
                                  partial_dir, prepare_output, run_indexed, sample_id, write_manifest)
from signlane import label_masks
from signlane.paint_visibility import unseen_paint
from signlane.world.render import Sample
from signlane.world.sampling import PRESETS, FrameSampler, SamplerConfig
from signlane.world.truth import GroundTruth

log = logging.getLogger(__name__)

JPEG_QUALITY = 95
# Teacher steering from the true pose, as a fraction of full lock (positive = right):
#   K_OFFSET   per lane width off-centre: 0.4 lane widths right of centre -> 0.4 left
#   K_HEADING  per radian of heading error: 0.1 rad (6 deg) pointing right -> 0.2 left
#   K_CURV     per 1/m of road curvature: the feed-forward a bicycle model needs, wheelbase /
#              max steer angle ~ 2.5 m / 0.5 rad, so a 10 m radius bend asks for 0.5
K_OFFSET = 1.0
K_HEADING = 2.0
K_CURV = 5.0


def teacher_steering(offset: float, heading: float, curvature: float) -> float:
    """Steering in [-1, 1] (positive right) that steers back to the lane centre (left when the
    car is right of centre or points right) and follows the bend ahead."""
    s = -(K_OFFSET * offset + K_HEADING * heading) + K_CURV * curvature
    return round(float(np.clip(s, -1.0, 1.0)), 5)


def frame_label(sid: str, truth: GroundTruth, width: int, height: int, drivable: bool = False) -> dict:
    """The labels.jsonl object of one frame: the contract's keys first, then extras from the truth
    (lane_width_m, sign occlusion/truncation, pose, camera, junction)."""
    lab = truth.to_label()
    out = {"id": sid, "image": f"images/{sid}.jpg", "mask": f"masks/{sid}.png", "width": width, "height": height}
    if drivable:
        out["drivable"] = f"drivable/{sid}.png"
    out.update(lane=lab.pop("lane"), signs=lab.pop("signs"),
               steering=teacher_steering(truth.offset, truth.heading, truth.curvature))
    out.update(lab)
    return out


def write_frame(out: Path, sid: str, sample: Sample, drivable: bool, extra: dict | None = None) -> None:
    """Write one frame's image, mask(s) and per-sample label (the label last: it marks the frame done)."""
    truth = sample.truth
    h, w = sample.image.shape[:2]
    atomic_imwrite(out / "images" / f"{sid}.jpg", sample.image, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    # a kerb is neither paint nor road surface, but it is a bright stripe along the road's edge
    # that looks like an edge line; labelled 0 it taught the road model that white stripes on
    # asphalt are off-road (it then missed a real highway's dashes and edge lines), so it
    # carries no label in either mask
    kerb = truth.kerb_mask > 0
    # paint that night, fog, glare or a pale look left the road's own colour is not in the image:
    # called paint, it would teach guessing and score every method against what nobody could see
    paint = truth.marking_mask > 0
    unseen = unseen_paint(sample.image, paint, ~paint & ~kerb)
    atomic_imwrite(out / "masks" / f"{sid}.png", label_masks.encode(paint & ~unseen, kerb | unseen))
    if drivable:
        atomic_imwrite(out / "drivable" / f"{sid}.png", label_masks.encode(truth.drivable_mask > 0, kerb))
    label = frame_label(sid, truth, w, h, drivable)
    label.update(extra or {})
    atomic_write_json(partial_dir(out, "labels") / f"{sid}.json", label, pretty=False)


def frame_done(out: Path, sid: str, drivable: bool) -> bool:
    """True when every file of frame `sid` exists and reads back whole."""
    names = [f"images/{sid}.jpg", f"masks/{sid}.png", f"{PARTIAL}/labels/{sid}.json"]
    if drivable:
        names.append(f"drivable/{sid}.png")
    return all((out / p).exists() and file_intact(out / p) for p in names)


def merge_labels(out: Path, n: int) -> int:
    """Merge `.partial/labels/<id>.json` into `labels.jsonl` in id order; return the sign-box count."""
    lines, signs = [], 0
    for i in range(n):
        line = (out / PARTIAL / "labels" / f"{sample_id(i, n)}.json").read_text().strip()  # already one line
        signs += len(json.loads(line)["signs"])
        lines.append(line)
    atomic_write_text(out / "labels.jsonl", "\n".join(lines) + "\n")
    return signs


@lru_cache(maxsize=2)
def _sampler(seed: int, config: SamplerConfig) -> FrameSampler:
    # one per process (and per config): it caches the current track between calls
    return FrameSampler(seed, config)


@dataclass(frozen=True)
class LaneJob:
    """Renders and writes frame i; picklable, so worker processes get their own copy."""

    out: str
    n: int
    seed: int
    sampler: SamplerConfig
    drivable: bool

    def done(self, i: int) -> bool:
        return frame_done(Path(self.out), sample_id(i, self.n), self.drivable)

    def __call__(self, i: int) -> None:
        write_frame(Path(self.out), sample_id(i, self.n), _sampler(self.seed, self.sampler).sample(i), self.drivable)


def lanes_config(n: int, seed: int, sampler: SamplerConfig, drivable: bool) -> dict:
    """The resolved options that determine the dataset's bytes (saved in the manifest)."""
    return {"n": int(n), "seed": int(seed), "sampler": sampler.recorded(), "drivable": drivable,
            "jpeg_quality": JPEG_QUALITY, label_masks.MANIFEST_KEY: label_masks.IDS,
            "steering": {"k_offset": K_OFFSET, "k_heading": K_HEADING, "k_curv": K_CURV}}


def generate_lanes(out: str | Path, n: int, seed: int, width: int = 320, height: int = 240, workers: int = 1,
                   resume: bool = False, preview: bool = False, effects: str = "mixed", randomise: bool = True,
                   drivable: bool = False, preset: str = "default", style: str = "painted",
                   junctions: float = 0.0) -> dict:
    """Write a lane dataset of `n` frames to `out` (layout in the module docstring); return its
    manifest. Frame i depends only on (seed, i), so `workers` never changes the bytes written.
    preset 'heavy' replaces `effects` with the sampler's HEAVY randomisation (night, rain, strong
    wear and shadows, wider camera spread, 16:9 frames among the 4:3 ones); 'world' adds cameras
    of any height, pitch and field of view (sampling.WORLD). `junctions`: the share of frames
    placed just before a junction of the route (SamplerConfig.junctions).
    Raises DatasetError if `out` is not empty and is not this dataset or, without `resume`,
    holds an unfinished run."""
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    out = Path(out)
    if preset not in PRESETS:
        raise ValueError(f"preset must be one of {', '.join(PRESETS)}, not {preset!r}")
    if not 0.0 <= junctions <= 1.0:
        raise ValueError(f"junctions is a share of the frames, 0..1, not {junctions}")
    extra = dict(PRESETS[preset]) if preset != "default" else {"effects": effects}
    sampler = SamplerConfig(width=width, height=height, randomise=randomise, style=style,
                            junctions=float(junctions), **extra)
    config = lanes_config(n, seed, sampler, drivable)
    manifest = prepare_output(out, "lanes", config, resume)
    if manifest is None:
        for d in ("images", "masks") + (("drivable",) if drivable else ()):
            (out / d).mkdir(exist_ok=True)
        job = LaneJob(str(out), n, seed, sampler, drivable)
        run_indexed(n, job, workers, desc="lane frames", done_fn=job.done, chunk=sampler.frames_per_track)
        signs = merge_labels(out, n)
        manifest = write_manifest(out, "lanes", seed, {"frames": n, "sign_boxes": signs}, config,
                                  **{label_masks.MANIFEST_KEY: label_masks.IDS})
        log.info("%s: wrote %d lane frames", out, n)
    if preview:
        from signlane_data.preview import write_lane_preview
        write_lane_preview(out)
    return manifest

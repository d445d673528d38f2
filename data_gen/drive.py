"""A recorded drive: consecutive frames along one track, in the lane dataset layout, plus video.

Layout of `out/`: images/<id>.jpg, masks/<id>.png (class ids as in `gen lanes`: 0 background,
1 lane marking, 255 kerbs), labels.jsonl (the lane contract plus "t", seconds since the first frame),
drive.mp4 (H.264, `fps`, the JPEG frames in order), manifest.json (with "mask_encoding").
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import cv2

from signlane import label_masks
from signlane.video_out import VideoOut
from signlane.world.sampling import DriveSampler, SamplerConfig
from signlane_data.common import prepare_output, run_indexed, sample_id, write_manifest
from signlane_data.lanes import JPEG_QUALITY, K_CURV, K_HEADING, K_OFFSET, frame_done, merge_labels, write_frame

log = logging.getLogger(__name__)

VIDEO = "drive.mp4"


@lru_cache(maxsize=2)
def _sampler(seed: int, config: SamplerConfig, speed_mps: float, fps: float) -> DriveSampler:
    return DriveSampler(seed, config, speed_mps, fps)  # one per process: it builds the track once


@dataclass(frozen=True)
class DriveJob:
    """Renders and writes frame i of the drive; picklable for worker processes."""

    out: str
    n: int
    seed: int
    sampler: SamplerConfig
    speed_mps: float
    fps: float

    def done(self, i: int) -> bool:
        return frame_done(Path(self.out), sample_id(i, self.n), False)

    def __call__(self, i: int) -> None:
        sample = _sampler(self.seed, self.sampler, self.speed_mps, self.fps).sample(i)
        write_frame(Path(self.out), sample_id(i, self.n), sample, False, {"t": round(i / self.fps, 6)})


def write_video(out: Path, n: int, fps: float) -> Path:
    """Encode images/<id>.jpg (uint8 BGR, all one size) in id order into `out/drive.mp4`."""
    first = cv2.imread(str(out / "images" / f"{sample_id(0, n)}.jpg"), cv2.IMREAD_COLOR)
    h, w = first.shape[:2]
    path = out / VIDEO
    with VideoOut(path, float(fps), (w, h)) as video:
        for i in range(n):
            video.write(cv2.imread(str(out / "images" / f"{sample_id(i, n)}.jpg"), cv2.IMREAD_COLOR))
    return path


def generate_drive(out: str | Path, n: int, seed: int, width: int = 640, height: int = 480, fps: float = 20,
                   resume: bool = False, preview: bool = False, speed_mps: float = 8.0, effects: str = "clean",
                   workers: int = 1, style: str = "via") -> dict:
    """Write `n` consecutive frames of a drive at `speed_mps` along one seeded track to `out`
    (layout in the module docstring) and return the manifest. Raises DatasetError if `out` is
    not empty and is not this dataset or, without `resume`, holds an unfinished run."""
    if n < 1 or fps <= 0:
        raise ValueError(f"need n >= 1 and fps > 0 (got {n}, {fps})")
    out = Path(out)
    sampler = SamplerConfig(width=width, height=height, effects=effects, style=style)
    config = {"n": int(n), "seed": int(seed), "fps": float(fps), "speed_mps": float(speed_mps),
              "sampler": sampler.recorded(), "jpeg_quality": JPEG_QUALITY,
              "steering": {"k_offset": K_OFFSET, "k_heading": K_HEADING, "k_curv": K_CURV}, "video": "h264",
              label_masks.MANIFEST_KEY: label_masks.IDS}
    manifest = prepare_output(out, "drive", config, resume)
    if manifest is None:
        for d in ("images", "masks"):
            (out / d).mkdir(exist_ok=True)
        job = DriveJob(str(out), n, seed, sampler, float(speed_mps), float(fps))
        run_indexed(n, job, workers, desc="drive frames", done_fn=job.done)
        signs = merge_labels(out, n)
        write_video(out, n, fps)
        counts = {"frames": n, "sign_boxes": signs, "seconds": round(n / fps, 3)}
        manifest = write_manifest(out, "drive", seed, counts, config, **{label_masks.MANIFEST_KEY: label_masks.IDS})
        log.info("%s: wrote a %d-frame drive and %s", out, n, VIDEO)
    if preview:
        from signlane_data.preview import write_lane_preview
        write_lane_preview(out, stride=max(1, n // 32))
    return manifest

"""`signlane infer`: the pipeline on images, folders and videos; annotated output and JSON lines.

A video is a drive: its frames go through the closed-loop drive stack that `drive`, `sim` and
`run` use (lanes, junctions, signs placed by odometry, the behaviour's stops and turns) on the
video's own clock, the car taken to do what it was told (a recording reports no speed). Images
have no clock: each goes through the open-loop Pipeline (signlane/pipeline.py), as videos do with
`open_loop`.

One bad input never stops the batch: it gets one line on stderr and the run's exit code
becomes 1. JSON records follow the contract in DESIGN.md.
"""
from __future__ import annotations

import itertools
import json
import sys
from collections import Counter
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Iterator

import cv2
import numpy as np
from tqdm import tqdm

from signlane.camera_estimate import CameraChoice, choose_camera
from signlane.config import CameraConfig, Config
from signlane.drive.stack import DriveStack, ToldCar
from signlane.draw import contact_sheet, draw_boxes, draw_hud, draw_lane, write_image
from signlane.fileio import atomic_open_text, atomic_write_text
from signlane.imagecheck import DEFAULT_MAX_PIXELS
from signlane.lanes import seg_model
from signlane.lanes.sharp_marking import sharpen_marking
from signlane.media import MediaError, Source, expand, iter_video, read_image, video_info
from signlane.tables import pairs
from signlane.video_out import VideoOut
from signlane.pipeline import Pipeline
from signlane.types import Command, Frame, Perception

LANE_FILL_BGR = (0, 160, 0)
ESTIMATE_FRAMES = 48  # a video's camera is measured on its first frames (2 s at 25 fps)
SHEET_TILES = 16  # a video's contact sheet (<stem>_sheet.png): this many frames spread over it
SUMMARY_CAMERAS = 8  # the summary names each input's camera up to this many inputs


@dataclass
class Summary:
    frames: int = 0
    lanes_found: int = 0
    signs: Counter = field(default_factory=Counter)
    states: Counter = field(default_factory=Counter)  # the command's state per frame
    timing: dict[str, list[float]] = field(default_factory=dict)
    failed: list[str] = field(default_factory=list)
    cameras: list[tuple[str, CameraChoice]] = field(default_factory=list)  # (input, its camera)

    def add(self, p: Perception, cmd: Command) -> None:
        self.frames += 1
        self.lanes_found += int(p.lane.found)
        self.signs.update(s.label for s in p.signs)
        self.states[cmd.state] += 1
        for k, v in p.timing_ms.items():
            self.timing.setdefault(k, []).append(v)

    def table(self) -> str:
        rows = [("frames", str(self.frames)),
                ("lanes found", f"{100.0 * self.lanes_found / max(self.frames, 1):.1f} %"),
                ("inputs failed", str(len(self.failed)))]
        rows += self._camera_rows()
        rows += [(f"signs: {k}", str(v)) for k, v in sorted(self.signs.items())]
        rows += [(f"state: {k}", f"{v} frames") for k, v in self.states.most_common()]
        rows += [(f"ms {k} (median)", f"{np.median(v):.2f}") for k, v in self.timing.items()]
        return pairs(rows)


    def _camera_rows(self) -> list[tuple[str, str]]:
        if not self.cameras:
            return []
        if len(self.cameras) <= SUMMARY_CAMERAS:
            return [(f"camera: {name}", choice.describe()) for name, choice in self.cameras]
        used = [c for _, c in self.cameras if c.used]
        row = f"estimated for {len(used)} of {len(self.cameras)} inputs"
        if used:
            row += (f"; median pitch {np.median([c.camera.pitch_deg for c in used]):+.1f} deg, "
                    f"height {np.median([c.camera.height_m for c in used]):.2f} m")
        return [("camera", row)]


def _at_size(mask: np.ndarray, w: int, h: int) -> np.ndarray:
    """A mask as uint8 0/255 at the input's size (a method may work on a scaled copy)."""
    m = (mask > 0).astype(np.uint8) * 255
    return m if m.shape[:2] == (h, w) else cv2.resize(m, (w, h), interpolation=cv2.INTER_NEAREST)


def record(source: str, index: int, p: Perception, cmd: Command) -> dict:
    """The per-frame JSON object of the infer contract."""
    h, w = p.frame.image_bgr.shape[:2]
    lane = p.lane

    def pl(a):
        return [] if a is None else [[round(float(x), 2), round(float(y), 2)] for x, y in a]
    return {"source": source, "frame": index, "width": int(w), "height": int(h),
            "lane": {"method": lane.method, "found": bool(lane.found), "offset": round(float(lane.offset), 4),
                     "heading": round(float(lane.heading), 5), "curvature": round(float(lane.curvature), 6),
                     "confidence": round(float(lane.confidence), 3), "left": pl(lane.left), "right": pl(lane.right)},
            "signs": [{"label": s.label, "score": round(float(s.score), 4), "box": [int(v) for v in s.box]}
                      for s in p.signs],
            "control": {"steering": round(float(cmd.steering), 4), "throttle": round(float(cmd.throttle), 4),
                        "state": cmd.state},
            "timing_ms": {k: round(v, 3) for k, v in p.timing_ms.items()}}


def annotate(p: Perception, cmd: Command) -> np.ndarray:
    """The frame with the lane (boundaries and the area between), sign boxes and a HUD."""
    out = p.frame.image_bgr.copy()
    lane = p.lane
    if lane.found and lane.left is not None and lane.right is not None and len(lane.left) > 1 and len(lane.right) > 1:
        poly = np.concatenate([lane.left, lane.right[::-1]]).astype(np.int32)
        fill = out.copy()
        cv2.fillPoly(fill, [poly], LANE_FILL_BGR)
        out = cv2.addWeighted(fill, 0.3, out, 0.7, 0)  # S2's blend of the lane area
    draw_lane(out, lane.left, lane.right)
    draw_boxes(out, [(s.label if not s.color else f"{s.label}:{s.color}", s.score, s.box) for s in p.signs])
    status = f"offset {lane.offset:+.2f} heading {np.degrees(lane.heading):+.1f}" if lane.found else "no lane"
    return draw_hud(out, [f"{lane.method}: {status}",
                          f"steer {cmd.steering:+.2f} throttle {cmd.throttle:.2f} {cmd.state}"])


class VideoDrive:
    """The drive stack on a video's frames at the video's own clock (see the module docstring)."""

    def __init__(self, config: Config):
        self.stack = DriveStack(config, sync_signs=True)  # signs in step with the frame: repeatable
        self.car = ToldCar(config.drive.max_speed)
        self.fps = 30.0

    @property
    def config(self) -> Config:
        return self.stack.config

    def start(self, fps: float) -> None:
        """The next video's frame rate (its clock); _run_source resets the stack for it."""
        self.fps = fps if fps > 0 else 30.0

    def step(self, frame: Frame) -> tuple[Perception, Command]:
        p, cmd = self.stack.drive(frame.image_bgr, self.car.speed_mps, self.car.wheel_deg, frame.seq / self.fps)
        self.car.told(cmd)
        return p, cmd

    def use_camera(self, camera: CameraConfig) -> None:
        self.stack.use_camera(camera)

    def reset(self) -> None:
        self.stack.reset()
        self.car.reset()

    def close(self) -> None:
        self.stack.close()


class OutputError(ValueError):
    """An output (--out, --json) that cannot be written: the run stops with this one line."""


def _frames(src: Source, max_pixels: int) -> Iterator[np.ndarray]:
    if src.kind == "image":
        yield read_image(src.path, max_pixels)
    else:
        yield from iter_video(src.path, max_pixels)


class Writer:
    """Annotated images/videos and lane masks under `out`; JSON lines to a stream."""

    def __init__(self, out: Path | None, save_masks: bool, json_stream: IO[str] | None, marking_size: tuple = ()):
        """marking_size: (w, h) of the segmentation model's maps when the lane method is `segnet`
        (its lane mask, the model's marking brought up to the frame, is sharpened on the frame's
        own pixels: lanes/sharp_marking.py); () otherwise."""
        self.out, self.save_masks, self.json = out, save_masks, json_stream
        self.marking_size = marking_size
        self._video: VideoOut | None = None
        self._sheet: list[tuple[int, np.ndarray]] = []  # a video's frames for its contact sheet
        self._sheet_every, self._sheet_path = 1, None
        self.camera: dict | None = None  # the current input's camera, when infer measured it


    def frame(self, src: Source, index: int, p: Perception, cmd: Command) -> None:
        if self.json is not None:
            rec = record(str(src.path), index, p, cmd)
            if self.camera is not None:
                rec["camera"] = self.camera
            self.json.write(json.dumps(rec) + "\n")
        if self.out is None:
            return
        stem = src.path.stem
        image = annotate(p, cmd)
        if src.kind == "image":
            suffix = src.path.suffix.lower() if src.path.suffix.lower() in (".png", ".jpg", ".jpeg") else ".png"
            write_image(self.out / f"{stem}{suffix}", image)
        else:
            if self._video is None:
                h, w = image.shape[:2]
                fps, count = video_info(src.path)
                self._video = VideoOut(self.out / f"{stem}.mp4", fps if fps > 0 else 30.0, (w, h))  # 0: not stated
                self._sheet_every = max(1, (count or 1) // SHEET_TILES)
                self._sheet, self._sheet_path = [], self.out / f"{stem}_sheet.png"
            self._video.write(image)
            if index % self._sheet_every == 0 and len(self._sheet) < SHEET_TILES:
                self._sheet.append((index, image))
        if self.save_masks:
            h, w = p.frame.image_bgr.shape[:2]
            lane = p.lane.with_masks()  # (segnet puts its frame-sized masks off until they are asked for)
            mask = lane.debug_mask if lane.debug_mask is not None else np.zeros((h, w), np.uint8)
            name = f"{stem}_lane.png" if src.kind == "image" else f"{stem}_{index:06d}_lane.png"
            mask = _at_size(mask, w, h)
            if self.marking_size and lane.method == "segnet":
                mask = sharpen_marking(mask, p.frame.image_bgr, self.marking_size)
            write_image(self.out / name, mask)
            if lane.drivable_mask is not None:  # the method has a road output
                write_image(self.out / name.replace("_lane.png", "_drivable.png"), _at_size(lane.drivable_mask, w, h))

    def end_source(self, ok: bool) -> None:
        if self._video is not None:
            if ok:
                self._video.close()
                if self._sheet:
                    tile = (480, round(480 * self._sheet[0][1].shape[0] / self._sheet[0][1].shape[1]))
                    write_image(self._sheet_path, contact_sheet([im for _, im in self._sheet], cols=4, tile=tile,
                                                                captions=[f"frame {i}" for i, _ in self._sheet]))
            else:
                self._video.discard()
            self._video = None


def run_infer(paths: list[str], config: Config, out: Path | None = None, json_path: str | None = None,
              save_masks: bool = False, progress: bool = True, max_pixels: int = DEFAULT_MAX_PIXELS,
              open_loop: bool = False) -> Summary:
    """Run the pipeline over every input; returns the summary (summary.failed lists bad inputs).
    The JSON lines file appears under its name once the run ends; OutputError if an output
    cannot be written. open_loop: videos frame by frame through the Pipeline too."""
    if save_masks and out is None:
        raise ValueError("--save-masks writes masks beside the annotated images: give --out DIR")
    sources, errors = expand(paths)
    summary = Summary(failed=list(errors))
    for e in errors:
        print(f"signlane infer: {e}", file=sys.stderr)
    with ExitStack() as stack:
        if out is not None:
            try:
                out.mkdir(parents=True, exist_ok=True)
                atomic_write_text(out / "config.json", json.dumps(config.to_dict(), indent=1))
            except OSError as e:
                raise OutputError(f"--out {out}: cannot write there ({e.strerror or e})") from None
        stream = None
        if json_path == "-":
            stream = sys.stdout
        elif json_path is not None:
            try:
                stream = stack.enter_context(atomic_open_text(json_path))
            except OSError as e:
                raise OutputError(f"--json {json_path}: cannot write there ({e.strerror or e})") from None
        marking_size = ()
        if save_masks and config.lanes.method == "segnet":
            spec = seg_model.load(seg_model.resolve(config.lanes.model)).spec  # (its maps are at its input's size)
            marking_size = (spec.width, spec.height)
        writer = Writer(out, save_masks, stream, marking_size)
        bar = stack.enter_context(tqdm(total=len(sources), desc="infer", unit="input", file=sys.stderr,
                                       disable=not progress or len(sources) < 2))
        pipe = stack.enter_context(Pipeline(config))
        video_drive = None  # built for the first video
        for src in sources:
            if src.kind == "video" and not open_loop:
                if video_drive is None:
                    video_drive = VideoDrive(config)
                    stack.callback(video_drive.close)
                video_drive.start(video_info(src.path)[0])
                ok = _run_source(src, video_drive, writer, summary, progress, max_pixels)
            else:
                ok = _run_source(src, pipe, writer, summary, progress, max_pixels)
            writer.end_source(ok)
            bar.update(1)
    return summary


def _head(frames: Iterator[np.ndarray], n: int) -> tuple[list[np.ndarray], MediaError | None]:
    """The first n frames, and the error that ended the input sooner (its frames still count)."""
    head: list[np.ndarray] = []
    try:
        for img in frames:
            head.append(img)
            if len(head) == n:
                break
    except MediaError as e:
        return head, e
    return head, None


def _raising(error: Exception) -> Iterator[np.ndarray]:
    raise error
    yield  # a generator: raises where the frames would go on


def _run_source(src: Source, pipe: Pipeline | VideoDrive, writer: Writer, summary: Summary, progress: bool,
                max_pixels: int) -> bool:
    pipe.reset()
    frames = _frames(src, max_pixels)
    if src.kind == "video" and progress:
        frames = tqdm(frames, total=video_info(src.path)[1] or None, desc=src.path.name, unit="frame",
                      leave=False, file=sys.stderr)
    try:
        if pipe.config.camera.estimate == "auto":
            # the input's own camera, measured on its first frames, reads all of them
            head, failure = _head(frames, ESTIMATE_FRAMES)
            if not head and failure is not None:
                raise failure  # unreadable: no camera to speak of
            choice = choose_camera(head, pipe.config.camera)
            pipe.use_camera(choice.camera)
            summary.cameras.append((src.path.name, choice))
            writer.camera = choice.to_dict()
            frames = itertools.chain(head, _raising(failure) if failure is not None else frames)
        for i, img in enumerate(frames):
            p, cmd = pipe.step(Frame(img, seq=i))
            summary.add(p, cmd)
            try:
                writer.frame(src, i, p, cmd)
            except OSError as e:
                writer.end_source(False)
                raise OutputError(f"cannot write the output for {src.path} ({e.strerror or e})") from None
        return True
    except MediaError as e:
        print(f"signlane infer: {e}", file=sys.stderr)
        summary.failed.append(str(e))
        return False

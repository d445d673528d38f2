"""The end-to-end pilot: an ONNX net that maps a camera frame (and the planner's chosen exit, the
"desire") to steering, trained on the autopilot's own drives (`signlane train pilot`).

Contract (signlane/onnx_model.py, task "pilot"): one image input as its metadata says, one
output (N, classes). The classes name what each output column is:
- `steering`: one steering value in [-1, 1] (+ right) whatever the desire: S3's PilotNet.
- `steering/left`, `steering/straight`, `steering/right`: one steering branch per desire
  (conditional imitation: the planner picks the branch), and `speed`: the teacher's target
  speed in m/s, predicted beside it.
The one pre-processing for training, export parity, evaluation and the runtime is
`preprocess_frames`; `desire_of` maps the behaviour's state (and its steering, with the lane
lost) to a desire, in one place.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from signlane.onnx_model import InputSpec, ModelError, OnnxModel, prepare_input
from signlane.types import LaneEstimate

TASK = "pilot"
DESIRES = ("left", "straight", "right")
STEERING = "steering"
SPEED = "speed"
BRANCHES = tuple(f"{STEERING}/{d}" for d in DESIRES)
PILOTNET_CLASSES = (STEERING,)
BRANCHED_CLASSES = BRANCHES + (SPEED,)
# S3: HSV scaled to [0, 1] (OpenCV's hue runs 0..179: its std of 180/255 makes it h / 180)
PILOTNET_SPEC = InputSpec(160, 120, "HSV", "NCHW", 1.0 / 255.0, (0.0, 0.0, 0.0), (180.0 / 255.0, 1.0, 1.0))
SMALL_SPEC = InputSpec(96, 72, "HSV", "NCHW", 1.0 / 255.0, (0.0, 0.0, 0.0), (180.0 / 255.0, 1.0, 1.0))
DEFAULT_MODEL = Path(__file__).resolve().parent / "models" / "pilot.onnx"


# with the lane lost, a course this sharp is a turn (VIA's car: 7.5 degrees of wheel, a 15 m
# radius; `eval pilot`'s "turn" bin starts at 17 m)
LOST_TURN_STEERING = 0.3


def desire_of(state: str, steering: float = 0.0) -> str:
    """The desire the planner feeds the pilot for a behaviour state and its own steering: the
    exit of a planned junction (`junction-left` -> left); with the lane lost, the side its
    course along the centre line it last traced turns to, where that is a turn (a tight bend
    leaves the view sideways, and a pilot that sees only verge there eases off: VIA seed 0's
    corner); else straight on along the lane."""
    if state.startswith("junction-"):
        turn = state.split("-", 1)[1]
        if turn in DESIRES:
            return turn
    if state == "lost" and abs(steering) >= LOST_TURN_STEERING:
        return "right" if steering > 0 else "left"
    return "straight"


def flip_desire(desire: str) -> str:
    """The desire in a mirrored frame: left and right swap."""
    return {"left": "right", "right": "left"}.get(desire, desire)


def preprocess_frames(frames_bgr: list[np.ndarray], spec: InputSpec) -> np.ndarray:
    """uint8 BGR frames (H, W, 3), any size -> float32 (N, 3, spec.height, spec.width) input."""
    return prepare_input(frames_bgr, spec, "frame")


@dataclass(frozen=True)
class PilotOutput:
    steering: float  # [-1, 1], + right, for the desire asked
    speed: float | None  # m/s, where the model predicts it


def read_outputs(row: np.ndarray, classes: list[str] | tuple[str, ...], desire: str) -> PilotOutput:
    """One output row (classes,) -> the steering for `desire` (clamped to [-1, 1]) and the
    speed where the model has one."""
    names = list(classes)
    key = f"{STEERING}/{desire}"
    col = names.index(key) if key in names else names.index(STEERING)
    speed = float(row[names.index(SPEED)]) if SPEED in names else None
    return PilotOutput(float(np.clip(row[col], -1.0, 1.0)), speed)


def check_classes(classes: list[str], where: str) -> None:
    """A pilot's outputs are PilotNet's one steering or the three desire branches (+ speed)."""
    if tuple(classes) not in (PILOTNET_CLASSES, BRANCHES, BRANCHED_CLASSES):
        raise ModelError(f"{where}: pilot outputs {classes} are neither {list(PILOTNET_CLASSES)} nor "
                         f"{list(BRANCHED_CLASSES)}")


class PilotModel:
    """The pilot with its contract read from the ONNX metadata. A lane or sign model given as a
    pilot (or a pilot given as one of them) is refused by its task, in one line."""

    def __init__(self, path: str | Path = DEFAULT_MODEL, threads: int = 1):
        self.model = OnnxModel(path, TASK, threads, output_rank=2)
        check_classes(self.model.classes, str(path))
        self.spec = self.model.input
        self.classes = tuple(self.model.classes)
        self.branched = BRANCHES[0] in self.classes

    def predict(self, frames_bgr: list[np.ndarray]) -> np.ndarray:
        """float32 (N, classes) raw outputs."""
        return self.model.run(preprocess_frames(frames_bgr, self.spec))

    def step(self, frame_bgr: np.ndarray, desire: str = "straight") -> PilotOutput:
        return read_outputs(self.predict([frame_bgr])[0], self.classes, desire)


@lru_cache(maxsize=4)
def load(path: str, threads: int = 1) -> PilotModel:
    """One session per (file, threads) per process."""
    return PilotModel(path, threads)


def from_config(pilot_cfg) -> PilotModel | None:
    """The pilot a config names (signlane.config.PilotConfig), or None where it names none.
    ModelError (one line) for a file that is missing or not a pilot."""
    spec = pilot_cfg.model.strip()
    if not spec:
        return None
    path = DEFAULT_MODEL if spec == "shipped" else Path(spec)
    return load(str(path), pilot_cfg.threads)


class PilotSteering:
    """The pilot's place in the drive stack: given the frame and what the behaviour decided,
    the steering sent. The planner's speed and state stay; at a planned junction the pilot is
    told the exit (its desire), or the planner's path steers there (junctions = "planner")."""

    def __init__(self, model: PilotModel, junctions: str = "planner"):
        self.model, self.junctions = model, junctions
        self.last: PilotOutput | None = None
        self.settling = False  # out of a planner-steered junction, not yet lined up with the exit lane

    def steer(self, frame_bgr: np.ndarray, state: str, planner_steering: float,
              lane: LaneEstimate | None = None) -> float:
        """planner_steering: the behaviour layer's own (its path in a junction, the lane
        follower's elsewhere); lane: the frame's lane estimate, which says when a car leaving a
        planner-steered junction is lined up with the exit lane again."""
        if self.junctions == "planner":
            in_junction = state.startswith("junction-")
            if in_junction:
                # the path hands back with the car still turning (up to ~0.5 rad off the exit
                # lane), a view the recordings show the pilot too little of, while the lane
                # follower reads the heading error directly: it finishes the exit
                self.settling = lane is not None
            elif self.settling:
                self.settling = not lined_up(lane)
            if in_junction or self.settling:
                self.last = None
                return planner_steering
        self.last = self.model.step(frame_bgr, desire_of(state, planner_steering))
        return self.last.steering

    def reset(self) -> None:
        self.last, self.settling = None, False


SETTLED_HEADING_RAD = 0.12  # about the largest heading the shift augmentation shows the pilot (7 deg)
SETTLED_OFFSET = 0.25  # lane widths from the lane's centre


def lined_up(lane: LaneEstimate | None) -> bool:
    """Is the car lined up with its lane: the lane found, the heading within what the pilot was
    trained on and the car near the centre."""
    return (lane is not None and lane.found and abs(lane.heading) <= SETTLED_HEADING_RAD
            and abs(lane.offset) <= SETTLED_OFFSET)


SPLIT_BLOCK = 50  # consecutive recorded frames share a side of the train/val split (neighbours look alike)


@dataclass(frozen=True)
class PilotFrame:
    """One recorded frame as the pilot sees it: the image, the teacher's steering (the label),
    the planner's desire, the teacher's target speed and lane curvature, and where it is from."""
    image: Path
    steering: float  # the teacher's, [-1, 1]
    desire: str
    speed: float  # the teacher's target speed, m/s
    curvature: float  # the teacher's lane estimate, 1/m (for error by curvature bin)
    drive: str  # the recording folder's name
    key: str  # for the split: drive folder + block of SPLIT_BLOCK frames


def read_pilot_frames(roots: list[str | Path]) -> list[PilotFrame]:
    """Every labelled frame of every drive recording under the roots (signlane/sim/drive_record.py),
    in order; ValueError naming a root with none, a broken recording or a frame without a label.
    Frames where the teacher had lost the lane (state "lost") are left out: its steering there only
    decays toward straight while the car stands, a label that says nothing about the picture."""
    from signlane.sim.drive_record import RecordError, read_recording, recording_folders
    items: list[PilotFrame] = []
    for root in map(Path, roots):
        folders = recording_folders(root)
        if not folders:
            raise ValueError(f"{root}: no drive recording (drive.jsonl + manifest.json) in or under it")
        for folder in folders:
            try:
                rec = read_recording(folder)
            except RecordError as e:
                raise ValueError(str(e)) from None
            max_speed = float(rec.manifest.get("config", {}).get("drive", {}).get("max_speed", 13.41))
            for n, f in enumerate(rec.frames):
                try:
                    teacher = f.get("teacher") or f["command"]
                    if teacher.get("state") == "lost":
                        continue
                    desire = f.get("desire", "straight")
                    items.append(PilotFrame(rec.image_path(f), float(f["steering"]),
                                            desire if desire in DESIRES else "straight",
                                            float(teacher["throttle"]) * max_speed,
                                            float((f.get("lane") or {}).get("curvature", 0.0)),
                                            folder.name, f"{folder.name}/{n // SPLIT_BLOCK}"))
                except (KeyError, TypeError, ValueError) as e:
                    raise ValueError(f"{folder}/drive.jsonl: frame {f.get('id')!r} lacks {e}") from None
    if not items:
        raise ValueError(f"{', '.join(map(str, roots))}: the recordings hold no frames")
    return items

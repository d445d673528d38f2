"""One nested dataclass config: defaults defined once, a TOML file and `--set a.b=v` override it.

The resolved config is saved beside outputs (`Config.to_dict()` as JSON) so a run can be
repeated exactly.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import asdict, dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Any

from signlane.camera import VIA_CAMERA_AHEAD_OF_AXLE_M, VIA_WHEELBASE_M, Camera


# camera settings a user measures: giving any of them keeps the configured camera as it is
# (camera.estimate off); the field of view is not among them, the estimate uses it
MEASURED_CAMERA_KEYS = {"pitch_deg", "height_m", "roll_deg"}


@dataclass(frozen=True)
class CameraConfig:
    """The camera the images come from; size is taken from each image. The defaults are VIA's
    camera (signlane/camera.py via_camera): 60 degrees vertical at 4:3 is 75.18 horizontal, in
    effect 2.9 m above the road, pitched 11.8 degrees down."""

    hfov_deg: float = 75.18
    height_m: float = 2.9
    pitch_deg: float = 11.8
    roll_deg: float = 0.0
    # where the camera stands ahead of the car's rear axle (what the car steers about): what the
    # camera measures is this much further from the axle. VIA: 0.1 m ahead of the car's origin,
    # midway along its 1.957 m wheelbase
    forward_m: float = round(VIA_CAMERA_AHEAD_OF_AXLE_M, 2)  # metres from the rear axle forward to the camera
    # infer on footage from an unknown camera: "auto" measures pitch and height from each input's
    # own frames (signlane/camera_estimate.py) and uses them where its horizon disagrees with
    # this camera's; "off" trusts these values. Setting pitch_deg, height_m or roll_deg turns it off
    estimate: str = "auto"  # auto | off: measure pitch and height from the frames

    def camera(self, width: int = 320, height: int = 240) -> Camera:
        return Camera(width, height, self.hfov_deg, self.height_m, self.pitch_deg, self.roll_deg)


@dataclass(frozen=True)
class LanesConfig:
    method: str = "auto"  # road-edges on a kerbed carriageway, sliding-window on painted lanes (lanes/auto.py)
    variant: str = "robust"  # robust | published
    model: str = ""  # a learned model's ONNX file: segnet's ("" = the shipped signlane/models/lanes.onnx), or a road
    # model for auto ("" = colour rules; "shipped" = signlane/models/lanes.onnx)

    def overrides(self) -> dict:
        """Method parameters the config sets beyond the variant's (a method without a `model`
        parameter rejects a model with a clear error)."""
        return {"model": self.model} if self.model else {}


@dataclass(frozen=True)
class SignsConfig:
    enabled: bool = True
    variant: str = "robust"  # proposal rules: robust | published
    model: str = ""  # ONNX classifier; "" = the shipped signlane/models/signs.onnx (proposals only if absent)
    min_score: float = 0.5  # classified signs below this score are dropped
    confirm_n: int = 3  # a sign is confirmed when seen in confirm_n of the last confirm_m frames
    confirm_m: int = 5
    # on a car (the drive stack's face rows, signs/face_rows.py): the rows are searched whole on
    # one frame in search_every, the frames between only around the frame before's proposals
    # (tracked); 1: whole on every frame. Stills and videos (infer) search every frame whole
    search_every: int = 5


@dataclass(frozen=True)
class ControlConfig:
    controller: str = "pure-pursuit"  # pure-pursuit | s1-proportional | s3-atan | s3-smoothed
    cruise: float = 0.5  # throttle while the lane is seen


@dataclass(frozen=True)
class PilotConfig:
    """The end-to-end pilot (signlane/pilot.py): with a model it steers in place of the lane
    follower; the behaviour layer keeps signs, stops, speed and junction choices."""
    model: str = ""  # pilot ONNX file; "" = no pilot (the lane follower steers); "shipped" = signlane/models/pilot.onnx
    junctions: str = "planner"  # who steers through a planned junction: planner (its path) | pilot (told the exit)
    threads: int = 1  # onnxruntime threads of the pilot
    # m/s the car keeps while the planner has lost the lane and the pilot steers (0: coast to a
    # stand, as with the lane follower). The pilot needs no lane estimate to steer, and a car
    # standing still with its view askew never finds the lane again (VIA seed 0: a pilot stood on
    # the road for the rest of a 600-s run, the road in view, steering toward it)
    lost_speed: float = 1.0


@dataclass(frozen=True)
class DriveConfig:
    """Closed-loop driving (`signlane drive`, `signlane sim --with-driver`): the speed planner
    and what the driver assumes of the car."""

    max_speed: float = 13.41  # VIA's 30 mph: throttle is a target fraction of it
    cruise_speed: float = 5.0
    approach_speed: float = 3.0  # after a confirmed sign, until it is dealt with
    stop_hold_s: float = 2.0
    # how fast the car slows at throttle 0 (there are no brakes), taken as constant by the stop
    # planner. VIA's car slows at 0.5 m/s^2 rolling + 0.1/s drag x speed (0.8 m/s^2 at 3 m/s),
    # so 0.4 is below it at every speed: the planned stop comes early, never late, with margin
    # for the rolling estimate and a reply applied a frame late.
    coast_decel: float = 0.4
    wheelbase_m: float = VIA_WHEELBASE_M  # VIA's car; for odometry and path following
    sign_size_m: float = 1.25  # sign face height, for the distance to a sign (VIA's: 1.25 m)
    sign_height_m: float = 2.42  # the face's centre above the road (VIA's: 2.42 m)
    # the sign search looks only at the image rows where a face at least this far ahead can be
    # (signs/face_rows.py): the road and ground below them and the sky above hold none (0 = every row)
    sign_search_near_m: float = 4.0
    # a square face seen at angle a is cos(a) as wide as tall: narrower than this, it faces
    # another road's traffic (0.55: more than about 57 degrees away)
    sign_min_aspect: float = 0.55
    sign_max_lateral_m: float = 9.0  # a sign further to the side stands beside another road
    lanes_width: int = 320  # lanes and junctions run on frames scaled to this width (0 = as sent)


@dataclass(frozen=True)
class Config:
    camera: CameraConfig = field(default_factory=CameraConfig)
    lanes: LanesConfig = field(default_factory=LanesConfig)
    signs: SignsConfig = field(default_factory=SignsConfig)
    control: ControlConfig = field(default_factory=ControlConfig)
    drive: DriveConfig = field(default_factory=DriveConfig)
    pilot: PilotConfig = field(default_factory=PilotConfig)

    def to_dict(self) -> dict:
        return asdict(self)

    def to_toml(self) -> str:
        """The config as a TOML file `load` reads back to the same config: one table per
        section, each setting with the comment the class gives it where it has one."""
        notes = _field_notes()
        out = []
        for section in fields(self):
            out.append(f"[{section.name}]")
            for f in fields(getattr(self, section.name)):
                value = getattr(getattr(self, section.name), f.name)
                line = f"{f.name} = {toml_value(value)}"
                note = notes.get((section.name, f.name))
                out.append(f"{line}  # {note}" if note else line)
            out.append("")
        return "\n".join(out)

    @classmethod
    def load(cls, path: str | Path | None = None, overrides: list[str] | None = None) -> "Config":
        """Defaults, then the TOML file's tables, then `section.key=value` overrides."""
        cfg = cls()
        given: set[str] = set()  # camera keys the file or --set gave
        if path is not None:
            p = Path(path)
            try:
                data = tomllib.loads(p.read_text())
            except OSError as e:
                raise ValueError(f"{p}: cannot read config ({e.strerror})") from None
            except tomllib.TOMLDecodeError as e:
                raise ValueError(f"{p}: invalid TOML ({e})") from None
            cfg = _merge(cfg, data, str(p))
            if isinstance(data.get("camera"), dict):
                given |= {k.replace("-", "_") for k in data["camera"]}
        for item in overrides or []:
            key, sep, value = item.partition("=")
            if not sep:
                raise ValueError(f"--set {item!r}: expected section.key=value")
            keys = key.strip().split(".")
            cfg = _merge(cfg, _nested(keys, _parse(value.strip())), f"--set {item}")
            if keys[0] == "camera" and len(keys) == 2:
                given.add(keys[1].replace("-", "_"))
        if given & MEASURED_CAMERA_KEYS and "estimate" not in given:
            cfg = replace(cfg, camera=replace(cfg.camera, estimate="off"))  # what the user measured wins
        cfg.validate()
        return cfg

    def validate(self) -> None:
        """Every value within its range (RANGES, CHOICES, ORDERED below); ValueError naming the
        key and what is allowed. `load` calls it once, on the resolved config."""
        for key, rule in RANGES.items():
            rule.check(key, _get(self, key))
        for key, choices in CHOICES.items():
            if _get(self, key) not in choices:
                raise ValueError(f"{key} = {_get(self, key)!r} is not one of {', '.join(choices)}")
        for small, big in ORDERED:
            if _get(self, small) > _get(self, big):
                raise ValueError(f"{small} = {_get(self, small)!r} is more than {big} = {_get(self, big)!r}")


def toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return repr(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        return repr(v) if math.isfinite(v) else ("inf" if v > 0 else "-inf")
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):  # an inline table (a Trainer's max_time = {hours = 1})
        return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"no TOML form for {v!r}")


def _field_notes() -> dict[tuple[str, str], str]:
    """(section, key) -> the comment beside the field in this file (the one place they are written)."""
    import ast
    import inspect
    import sys
    src = inspect.getsource(sys.modules[__name__])
    lines = src.splitlines()
    sections = {f.type if isinstance(f.type, str) else f.type.__name__: f.name for f in fields(Config)}
    notes = {}
    for node in ast.parse(src).body:
        if isinstance(node, ast.ClassDef) and node.name in sections:
            for stmt in node.body:
                if isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name):
                    text = lines[stmt.end_lineno - 1]
                    if "#" in text and text.index("#") > text.index("="):
                        notes[(sections[node.name], stmt.target.id)] = text.split("#", 1)[1].strip()
    return notes


def _nested(keys: list[str], value: Any) -> dict:
    return {keys[0]: _nested(keys[1:], value)} if len(keys) > 1 else {keys[0]: value}


def _parse(text: str) -> Any:
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text  # bare words are strings


def _merge(obj: Any, data: dict, where: str) -> Any:
    known = {f.name: f for f in fields(obj)}
    changes = {}
    for key, value in data.items():
        name = key.replace("-", "_")
        if name not in known:
            raise ValueError(f"{where}: unknown setting {key!r} (known: {', '.join(sorted(known))})")
        current = getattr(obj, name)
        if is_dataclass(current):
            if not isinstance(value, dict):
                raise ValueError(f"{where}: {key!r} is a section, not a value")
            changes[name] = _merge(current, value, where)
        else:
            changes[name] = _coerce(current, value, key, where)
    return replace(obj, **changes)


def _coerce(current: Any, value: Any, key: str, where: str) -> Any:
    if isinstance(current, int) and not isinstance(current, bool) and isinstance(value, float) \
            and not value.is_integer():
        raise ValueError(f"{where}: {key} = {value!r} is not a whole number")  # int() would truncate it
    try:
        if isinstance(current, bool):
            if isinstance(value, bool):
                return value
            raise ValueError
        if isinstance(current, int) and not isinstance(value, bool):
            return int(value)
        if isinstance(current, float) and not isinstance(value, bool):
            return float(value)
        if isinstance(current, str):
            return str(value)
    except (TypeError, ValueError):
        pass
    raise ValueError(f"{where}: {key} = {value!r} is not a {type(current).__name__}")


# --------------------------------------------------------------------------------------- ranges
@dataclass(frozen=True)
class Range:
    """Allowed values of a number: lo..hi (inclusive), finite; `off` is one more value outside
    the range that switches the feature off."""

    lo: float
    hi: float
    unit: str = ""
    off: float | None = None

    def check(self, key: str, value: float) -> None:
        if self.off is not None and value == self.off:
            return
        allowed = f"{self.lo:g}..{self.hi:g}{' ' + self.unit if self.unit else ''}"
        allowed += f" (or {self.off:g}: off)" if self.off is not None else ""
        if not math.isfinite(value):
            raise ValueError(f"{key} = {value!r} is not a finite number (allowed: {allowed})")
        if not self.lo <= value <= self.hi:
            raise ValueError(f"{key} = {value!r} is outside {allowed}")


# Physical limits, generous on purpose (any real car, camera or simulator fits; the defaults are
# not special): what lies outside makes no sense or breaks the geometry (hfov 0, height 0).
RANGES: dict[str, Range] = {
    "camera.hfov_deg": Range(1.0, 179.0, "degrees"),
    "camera.height_m": Range(0.05, 50.0, "m"),
    "camera.pitch_deg": Range(-89.0, 89.0, "degrees (positive: down)"),
    "camera.roll_deg": Range(-90.0, 90.0, "degrees"),
    "camera.forward_m": Range(-5.0, 10.0, "m"),
    "signs.min_score": Range(0.0, 1.0),
    "signs.confirm_n": Range(1, 1000, "frames"),
    "signs.confirm_m": Range(1, 1000, "frames"),
    "control.cruise": Range(0.0, 1.0, "(throttle)"),
    "drive.max_speed": Range(0.1, 100.0, "m/s"),
    "drive.cruise_speed": Range(0.0, 100.0, "m/s"),
    "drive.approach_speed": Range(0.0, 100.0, "m/s"),
    "drive.stop_hold_s": Range(0.0, 600.0, "s"),
    "drive.coast_decel": Range(0.01, 100.0, "m/s^2"),
    "drive.wheelbase_m": Range(0.05, 20.0, "m"),
    "drive.sign_size_m": Range(0.05, 10.0, "m"),
    "drive.sign_height_m": Range(0.0, 20.0, "m"),
    "drive.sign_search_near_m": Range(0.5, 1000.0, "m", off=0),
    "drive.sign_min_aspect": Range(0.0, 1.0, ""),
    "drive.sign_max_lateral_m": Range(0.5, 100.0, "m"),
    "drive.lanes_width": Range(32, 8192, "px", off=0),
    "pilot.threads": Range(1, 64, "threads"),
    "pilot.lost_speed": Range(0.0, 100.0, "m/s"),
}
CHOICES: dict[str, tuple[str, ...]] = {
    "camera.estimate": ("auto", "off"),
    "lanes.variant": ("robust", "published"),
    "signs.variant": ("robust", "published"),
    "pilot.junctions": ("pilot", "planner"),
}
ORDERED: list[tuple[str, str]] = [  # (a, b): a <= b
    ("signs.confirm_n", "signs.confirm_m"),
    ("drive.cruise_speed", "drive.max_speed"),
    ("drive.approach_speed", "drive.max_speed"),
    ("pilot.lost_speed", "drive.max_speed"),
]


def _get(cfg: Config, key: str) -> Any:
    section, name = key.split(".")
    return getattr(getattr(cfg, section), name)

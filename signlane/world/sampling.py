"""Seeded sampling of rendered frames: the one entry point datasets, tests and demos use.

`FrameSampler(seed, ...)` yields frame i as a pure function of (seed, i): the track, scene,
camera, pose and effects all come from generators seeded by (seed, i), so any number of
workers produce the same pixels. Frames are grouped `frames_per_track` to a track so the
track and scene are built once per group.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from signlane.camera import Camera, via_camera
from signlane.world.effects import Effects
from signlane.world.looks import random_style
from signlane.world.procedural import generate_map
from signlane.world.render import Renderer, Sample
from signlane.world.route import Route, random_policy
from signlane.world.scene import build_scene
from signlane.world.track import RoadStyle, Track

STYLES = ("painted", "via", "mixed")


# the cameras a user may bring (dashcams, phones, robot cars, other simulators): the world preset
# draws from these ranges, beside cameras near the road style's own
WORLD_HEIGHT_M = (0.2, 3.0)
WORLD_PITCH_DEG = (0.0, 25.0)
WORLD_HFOV_DEG = (50.0, 120.0)


def world_camera(rng: np.random.Generator, width: int, height: int) -> Camera:
    """Any camera a car might carry: height log-uniform over WORLD_HEIGHT_M (as many toy cars'
    as dashcams'), pitch and horizontal field of view uniform over their ranges."""
    lo, hi = np.log(WORLD_HEIGHT_M)
    return replace(Camera(width=width, height=height), height_m=float(np.exp(rng.uniform(lo, hi))),
                   pitch_deg=float(rng.uniform(*WORLD_PITCH_DEG)), hfov_deg=float(rng.uniform(*WORLD_HFOV_DEG)))


def random_camera(rng: np.random.Generator, width: int, height: int, wide: float = 1.0,
                  style: str = "painted") -> Camera:
    """A plausible small-car camera: FOV 60-100 deg, 0.9-1.8 m high, pitched 4-18 deg down
    (VIA-style worlds: around VIA's own camera, 2.9 m at 11.8 degrees). `wide` scales the spread
    (0 gives the default camera at this size)."""
    if style == "via":
        base = via_camera(width, height)
        if wide <= 0:
            return base
        return replace(base, hfov_deg=float(np.clip(base.hfov_deg + rng.uniform(-10, 10) * wide, 50, 110)),
                       height_m=float(np.clip(base.height_m + rng.uniform(-0.8, 0.4) * wide, 1.0, 3.5)),
                       pitch_deg=float(np.clip(base.pitch_deg + rng.uniform(-5, 5) * wide, 3, 22)))
    base = Camera(width=width, height=height)
    if wide <= 0:
        return base
    return replace(base, hfov_deg=float(np.clip(base.hfov_deg + rng.uniform(-30, 10) * wide, 50, 110)),
                   height_m=float(np.clip(base.height_m + rng.uniform(-0.4, 0.5) * wide, 0.6, 2.0)),
                   pitch_deg=float(np.clip(base.pitch_deg + rng.uniform(-6, 8) * wide, 3, 20)))


@dataclass(frozen=True)
class SamplerConfig:
    width: int = 320
    height: int = 240
    effects: str = "normal"  # clean | normal | hard | heavy | mixed (normal, hard: half each) | wild (a third each of normal, hard, heavy)
    randomise: bool = True  # road style, scene looks, camera spread, sign appearance
    frames_per_track: int = 25
    lateral_m: float = 0.6  # std of the car's lateral offset from the lane centre
    heading_deg: float = 4.0  # std of the car's heading error
    map_size: str = "medium"
    looks_strength: float = 1.0  # worn/faded paint and shadows; the hard test set uses 2
    focus: str = "none"  # none | signs: place the car 4-45 m before a sign facing it (sign datasets)
    camera_spread: float = 1.0  # scales random_camera's spread of FOV, height and pitch
    wide_prob: float = 0.0  # chance a frame is 16:9 (same width, fewer rows) instead of width x height
    style: str = "painted"  # painted (lanes and lines) | via (VIA's kerbed road) | mixed (half each, per track)
    world_cameras: float = 0.0  # share of frames whose camera is any car's (world_camera) rather than near the style's
    junctions: float = 0.0  # share of frames placed JUNCTION_AHEAD_M before a junction of the route (side roads in view)

    def recorded(self) -> dict:
        """The options as a dataset's manifest records them: options added since the first sets
        were made appear only when used, so that those sets' manifests still match their config."""
        out = asdict(self)
        if not out["junctions"]:
            del out["junctions"]
        return out


# training sets that must generalise past the renderer: wild effects, strong wear and shadows,
# cameras spread half as far again, a third of the frames wide
HEAVY = dict(effects="wild", looks_strength=2.5, camera_spread=1.5, wide_prob=0.3)
# and for models that meet cameras nobody measured: besides, half the frames from any camera
# (0.2-3 m high, pitched 0-25 degrees down, 50-120 degrees across). A frame's pixel count matters
# little to a model that sees every frame resized to its input; its aspect and its camera do
WORLD = dict(HEAVY, world_cameras=0.5)
PRESETS = {"default": {}, "heavy": HEAVY, "world": WORLD}
# a junction-focused frame sees the junction's first cell this far ahead: from where a side road
# is a sliver by the horizon to where it opens beside the car
JUNCTION_AHEAD_M = (1.0, 30.0)


class FrameSampler:
    """Frame i of a seeded synthetic dataset; see the module docstring."""

    def __init__(self, seed: int, config: SamplerConfig | None = None):
        self.seed = int(seed)
        self.config = config or SamplerConfig()
        self._group: int | None = None
        self._renderer: Renderer | None = None
        self._route: Route | None = None

    def _prepare(self, group: int) -> None:
        if self._group == group:
            return
        cfg = self.config
        rng = np.random.default_rng([self.seed, group, 1])
        kind = group_style(cfg.style, rng)
        self._kind = kind
        track = Track.from_via(generate_map(int(rng.integers(1 << 31)), size=cfg.map_size),
                               style=track_style(kind, rng, cfg.randomise))
        self._route = Route.drive(track, 2000.0, random_policy(rng), reverse=bool(rng.random() < 0.5))
        scene = build_scene(track, seed=int(rng.integers(1 << 31)), randomise=cfg.randomise,
                            looks_strength=cfg.looks_strength)
        self._renderer = Renderer(scene, sign_strength=0.7 if cfg.randomise else 0.0)
        self._sign_s = signs_along(self._route, scene.objects) if cfg.focus == "signs" else np.zeros(0)
        self._junction_s = junctions_along(self._route) if cfg.junctions else np.zeros(0)
        self._group = group

    def effects_for(self, rng: np.random.Generator) -> Effects:
        name = self.config.effects
        if name == "mixed":
            name = "hard" if rng.random() < 0.5 else "normal"
        elif name == "wild":
            name = ("normal", "hard", "heavy")[int(rng.integers(3))]
        return Effects.named(name)

    def sample(self, index: int) -> Sample:
        cfg = self.config
        self._prepare(index // cfg.frames_per_track)
        rng = np.random.default_rng([self.seed, index, 2])
        camera = random_camera(rng, cfg.width, cfg.height, cfg.camera_spread if cfg.randomise else 0.0, self._kind)
        if cfg.world_cameras and rng.random() < cfg.world_cameras:  # drawn only when enabled, as wide_prob
            camera = world_camera(rng, cfg.width, cfg.height)
        if cfg.wide_prob and rng.random() < cfg.wide_prob:  # drawn only when enabled: older sets keep their pixels
            camera = camera.with_size(cfg.width, max(16, round(cfg.width * 9 / 16)))
        route = self._route
        s = float(rng.uniform(0, route.length - 80.0))
        if len(self._sign_s):
            s = float(np.clip(self._sign_s[int(rng.integers(len(self._sign_s)))] - rng.uniform(4, 45), 0, None))
        elif len(self._junction_s) and rng.random() < cfg.junctions:  # drawn only when enabled
            s = float(np.clip(self._junction_s[int(rng.integers(len(self._junction_s)))]
                              - rng.uniform(*JUNCTION_AHEAD_M), 0, route.length - 80.0))
        lateral = float(np.clip(rng.normal(0, cfg.lateral_m), -1.2, 1.2))
        heading = float(np.radians(np.clip(rng.normal(0, cfg.heading_deg), -12, 12)))
        return self._renderer.render_on_route(route, s, camera, lateral, heading, self.effects_for(rng), rng)


def group_style(style: str, rng: np.random.Generator) -> str:
    """The road style of one track of a dataset: mixed draws painted or via, half each."""
    if style not in STYLES:
        raise ValueError(f"unknown style {style!r} ({', '.join(STYLES)})")
    if style == "mixed":
        return "via" if rng.random() < 0.5 else "painted"
    return style


def track_style(kind: str, rng: np.random.Generator, randomise: bool) -> RoadStyle:
    """A track's road style: VIA's own or painted lanes, randomised (painted on 10-16 m cells)."""
    if kind == "via":
        return random_style(rng, "via") if randomise else RoadStyle.via()
    style = random_style(rng) if randomise else RoadStyle()
    return replace(style, cell_m=float(rng.uniform(10, 16)) if randomise else 12.0)


def junctions_along(route: Route) -> np.ndarray:
    """Arc lengths along the route where it enters a junction tile (a T or a crossing), short of
    the route's last 80 m (frames are drawn before them)."""
    s = np.array([leg.s0 for leg in route.legs if leg.turn != "road"], float)
    return s[s < route.length - 80.0]


def signs_along(route: Route, objects) -> np.ndarray:
    """Arc lengths along the route of the signs that stand beside it facing its traffic."""
    from signlane.world.art import SIGN_NAMES
    out = []
    for o in objects:
        if o.kind not in SIGN_NAMES:
            continue
        s, lat = route.project(o.x, o.y)
        tangent = route.tangent[route.index_at(s)]
        facing = np.array([np.cos(o.facing), np.sin(o.facing)])
        if abs(lat) < 10.0 and float(facing @ tangent) < -0.5 and s > 50.0:
            out.append(s)
    return np.array(out)


class DriveSampler:
    """Consecutive frames along one track at a fixed speed (a recorded drive). The track is a
    seeded procedural one unless given; at junctions the route picks exits at random. The camera
    is the style's own (VIA's on a kerbed road, a 1.3 m one on a painted road) unless given: the
    simulator and the driver's default config see both styles through VIA's."""

    def __init__(self, seed: int, config: SamplerConfig | None = None, speed_mps: float = 8.0, fps: float = 20.0,
                 track: Track | None = None, camera: Camera | None = None):
        self.config = config or SamplerConfig(effects="clean")
        rng = np.random.default_rng([int(seed), 0, 3])
        cfg = self.config
        kind = group_style(cfg.style, rng)
        if track is None:
            track = Track.from_via(generate_map(int(rng.integers(1 << 31)), size=cfg.map_size),
                                   style=track_style(kind, rng, cfg.randomise))
        self.route = Route.drive(track, 5000.0, random_policy(rng))
        self.renderer = Renderer(build_scene(track, seed=int(rng.integers(1 << 31)), randomise=cfg.randomise))
        if camera is None:
            camera = via_camera(cfg.width, cfg.height) if track.style.kind == "via" else Camera(cfg.width, cfg.height)
        self.camera = camera
        self.step_m = speed_mps / fps
        self.seed = int(seed)

    def sample(self, index: int) -> Sample:
        rng = np.random.default_rng([self.seed, index, 4])
        s = 5.0 + index * self.step_m
        # a gentle weave inside the lane, as a human driver would leave it
        lateral = 0.3 * np.sin(s / 23.0)
        heading = (0.3 / 23.0) * np.cos(s / 23.0)  # the derivative of the weave
        effects = Effects.named(self.config.effects if self.config.effects != "mixed" else "normal")
        return self.renderer.render_on_route(self.route, s, self.camera, lateral, heading, effects, rng)

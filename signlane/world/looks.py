"""Scene colours and textures (`Looks`), VIA's own look, and seeded random looks and road styles.

Colours are BGR. VIA's look is taken from its camera images (../shared/via/look: asphalt about
RGB (93, 98, 101), grass (74, 109, 48), a pale blue sky) and its materials (../shared/VIA.md,
section 6: white kerbs, green barriers, brown ground for bg_id 1, walls at +-100 m).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from signlane.world.track import RoadStyle

BGR = tuple[int, int, int]

# VIA's ground under each bg_id as the camera sees it (the top-down renders show them darker)
VIA_GROUND: dict[str, BGR] = {"grass": (48, 109, 74), "ground": (31, 48, 66), "none": (87, 89, 94)}


@dataclass(frozen=True)
class Looks:
    """Scene colours (BGR) and texture strengths."""

    asphalt: BGR = (92, 92, 96)
    grass: BGR = (60, 120, 80)  # the ground off the road, whatever it is
    white: BGR = (235, 235, 235)
    yellow: BGR = (40, 190, 230)
    sky_top: BGR = (225, 170, 110)
    sky_horizon: BGR = (235, 215, 195)
    texture: float = 0.12  # multiplicative noise amplitude of the ground texture
    worn_prob: float = 0.0  # chance a paint piece is missing
    fade_prob: float = 0.0  # chance a paint piece is faded towards the asphalt
    shadows: int = 0  # number of world-fixed shadow polygons per tile-ish area
    kerb: BGR = (235, 235, 235)
    barrier: BGR = (60, 205, 60)
    road_texture: float = 1.0  # share of the texture's contrast the road surface gets
    scenery: str = "hills"  # hills (trees, buildings) | walls (VIA: grey walls far off)
    sign_gain: float = 1.0  # sign faces brighter than the scene (VIA lights them from the car)
    fog_m: tuple[float, float] = (40.0, 200.0)  # fog from the first to full at the second distance
    texture_m: float = 0.0  # metres one texture tile covers; 0 = drawn at random (4-10 m)
    distractors: float = 0.08  # roadside distractors per road cell


def via_looks(background: str = "grass") -> Looks:
    """VIA's own look for a track's bg_id (grass, ground, or none)."""
    return Looks(asphalt=(101, 98, 93), grass=VIA_GROUND.get(background, VIA_GROUND["none"]),
                 sky_top=(196, 158, 122), sky_horizon=(240, 236, 214), texture=0.16, kerb=(238, 238, 238),
                 barrier=(60, 205, 60), road_texture=0.15, scenery="walls", sign_gain=1.25,
                 fog_m=(100.0, 600.0), texture_m=2.0, distractors=0.0)


def default_looks(style: RoadStyle, background: str = "grass") -> Looks:
    return via_looks(background) if style.kind == "via" else Looks()


def _jitter(rng: np.random.Generator, c, amount: float) -> BGR:
    return tuple(int(np.clip(v + rng.normal(0, amount), 0, 255)) for v in c)


def random_looks(rng: np.random.Generator, strength: float = 1.0, style: RoadStyle | None = None) -> Looks:
    """Seeded random colours and wear; VIA-style roads keep VIA's materials but vary their look."""
    if style is not None and style.kind == "via":
        return _random_via_looks(rng, strength)
    grey = float(rng.uniform(60, 130))
    asphalt = tuple(int(np.clip(grey + rng.normal(0, 6 * strength), 0, 255)) for _ in range(3))
    grass_options = [(60, 120, 80), (70, 140, 150), (110, 150, 160), (90, 100, 90), (50, 90, 60)]
    grass = _jitter(rng, grass_options[int(rng.integers(len(grass_options)))], 15 * strength)
    return Looks(asphalt=asphalt, grass=grass, white=_jitter(rng, (235, 235, 235), 12 * strength),
                 yellow=_jitter(rng, (40, 190, 230), 15 * strength), sky_top=_jitter(rng, (225, 170, 110), 25 * strength),
                 sky_horizon=_jitter(rng, (235, 215, 195), 20 * strength), texture=float(rng.uniform(0.04, 0.2)),
                 worn_prob=float(min(0.6, rng.uniform(0, 0.25) * strength)),
                 fade_prob=float(min(0.8, rng.uniform(0, 0.3) * strength)),
                 shadows=int(round(rng.integers(0, 4) * strength)))


def _random_via_looks(rng: np.random.Generator, strength: float) -> Looks:
    """Around VIA's look: asphalt from VIA's material value (about 45) to its camera value (about
    100) and beyond, grass, brown ground or none, paler or darker kerbs, skies and lighting."""
    grey = float(rng.uniform(38, 120))
    asphalt = tuple(int(np.clip(grey + rng.normal(0, 4 * strength), 0, 255)) for _ in range(3))
    ground = ["grass", "grass", "ground", "none"][int(rng.integers(4))]
    base = via_looks(ground)
    return replace(base, asphalt=asphalt, grass=_jitter(rng, base.grass, 14 * strength),
                   kerb=_jitter(rng, (232, 232, 232), 14 * strength), barrier=_jitter(rng, base.barrier, 30 * strength),
                   sky_top=_jitter(rng, base.sky_top, 25 * strength), sky_horizon=_jitter(rng, base.sky_horizon, 15 * strength),
                   texture=float(rng.uniform(0.05, 0.25)), road_texture=float(rng.uniform(0.0, 0.6)),
                   sign_gain=float(rng.uniform(1.0, 1.4)), shadows=int(round(rng.integers(0, 3) * strength)),
                   distractors=float(rng.uniform(0.0, 0.08)), texture_m=float(rng.uniform(1.5, 4.0)))


def random_style(rng: np.random.Generator, kind: str = "painted") -> RoadStyle:
    """A seeded random road style of a kind: painted lanes and lines, or VIA's kerbed road with
    kerbs, barriers and width varied a little (VIA-like simulators differ in these)."""
    if kind == "via":
        barrier = float(rng.uniform(1.5, 3.0)) if rng.random() < 0.7 else -1.0
        return RoadStyle.via(lane_width=float(rng.uniform(3.6, 4.4)), kerb_m=float(rng.uniform(0.12, 0.3)),
                             barrier_gap_m=barrier)
    lanes = 2 if rng.random() < 0.8 else 1
    centre = ["dashed", "dashed", "solid", "double", "none"][int(rng.integers(5))]
    centre_color = "yellow" if rng.random() < 0.35 else "white"
    return RoadStyle(lane_width=float(rng.uniform(2.8, 3.8)), lanes=lanes,
                     shoulder=float(rng.uniform(0.2, 0.9)), line_width=float(rng.uniform(0.1, 0.25)),
                     edge_line="dashed" if rng.random() < 0.1 else "solid", centre_line=centre,
                     edge_color="yellow" if rng.random() < 0.1 else "white", centre_color=centre_color,
                     dash_m=float(rng.uniform(1.5, 4.0)), gap_m=float(rng.uniform(1.5, 6.0)))

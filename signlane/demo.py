"""`signlane demo`: a complete closed-loop drive on a bundled map, for people.

The local simulator drives the car with signlane's own driver (lanes, junctions, signs with the
shipped classifier, the sign-aware behaviour), in lockstep, and writes `drive.mp4` (what the
driver saw and did), `path.png` (the driven path over the map from above), `report.json` and
the score table.
"""
from __future__ import annotations

from pathlib import Path

from signlane.config import Config
from signlane.world.maps import BUNDLED_MAPS, bundled_map  # noqa: F401 (re-exported)
from signlane.world.track import Track


def run_demo(out: str | Path, track: Track | None = None, laps: int = 1, width: int = 640, height: int = 480,
             config: Config | None = None, max_seconds: float = 600.0) -> dict:
    """Drive `laps` laps closed-loop; returns the report with the files written under "files"."""
    from signlane.sim.session import run_session
    from signlane.sim.simulator import SimConfig
    out = Path(out)
    rep = run_session(track or bundled_map("via_town"), SimConfig(width=width, height=height, laps=laps,
                                                                  max_seconds=max_seconds),
                      out, config, lockstep=True, video=True)
    rep["files"] = {"video": str(out / "drive.mp4"), "path": str(out / "path.png"), "report": str(out / "report.json")}
    return rep

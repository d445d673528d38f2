"""`signlane gen pilot`: many short teacher drives over procedural tracks, for the pilot.

Each drive is signlane's own driver (the teacher) in the local simulator, in lockstep, on the
procedural track of one seed and one road style, recorded exactly as `signlane sim --record`
does (signlane/sim/drive_record.py: images/, drive.jsonl, manifest.json with the track, style
and looks), with the applied steering perturbed (signlane/sim/teacher.py) so the recording
shows recoveries. Layout of `out/`: drives/<style>-seed<N>/ (one recording each) and
manifest.json (the options, and per drive its frames and score). A drive whose folder has no
manifest was cut short: --resume drives it again.

With `student` (a pilot ONNX file) each drive is a DAgger drive: the student steers (the teacher
takes over for a moment where they disagree by more than `takeover`), the teacher labels every
frame; record them on seeds of their own (--first-seed after the teacher drives': more tracks)
and train on both sets together.

Train on other seeds than the closed-loop acceptance's (benchmarks/closed_loop.py: 0-19); the
default first seed is 1000.
"""
from __future__ import annotations

import json
import logging
import shutil
from dataclasses import dataclass
from pathlib import Path

from signlane.sim.drive_record import recording_folders  # noqa: F401  (the readers' way to find drives)
from signlane_data.common import prepare_output, run_indexed, write_manifest

log = logging.getLogger(__name__)

DRIVES = "drives"
LOOKS = ("default", "random", "mixed")


@dataclass(frozen=True)
class PilotDriveJob:
    """Drives and records drive i (picklable for worker processes)."""

    out: str
    names: tuple[tuple[str, int, bool], ...]  # (style, seed, random looks) per drive
    seconds: float
    perturb: float
    every: int
    fps: float
    student: str = ""  # a pilot ONNX file: DAgger drives (module docstring); "" = the teacher drives
    takeover: float = 0.25

    def folder(self, i: int) -> Path:
        style, seed, _ = self.names[i]
        return Path(self.out) / DRIVES / f"{style}-seed{seed}"

    def done(self, i: int) -> bool:
        return (self.folder(i) / "manifest.json").is_file()

    def __call__(self, i: int) -> dict:
        import cv2
        cv2.setNumThreads(1)
        from signlane.config import Config
        from signlane.sim.session import run_session
        from signlane.sim.simulator import SimConfig
        from signlane.sim.teacher import NoiseParams, SteeringNoise, Takeover, TakeoverParams
        from signlane.world.maps import load_track
        style, seed, random_looks = self.names[i]
        folder = self.folder(i)
        shutil.rmtree(folder, ignore_errors=True)  # a drive cut short starts again
        sim = SimConfig(fps=self.fps, laps=100, max_seconds=self.seconds, random_looks=random_looks, looks_seed=seed)
        noise = SteeringNoise(NoiseParams(scale=self.perturb), seed) if self.perturb > 0 else None
        config = Config.load(None, [f"pilot.model={self.student}"]) if self.student else Config()
        takeover = Takeover(TakeoverParams(margin=self.takeover)) if self.student else None
        rep = run_session(load_track("random", style, seed), sim, None, config, lockstep=True,
                          show_progress=False, record=folder, noise=noise, record_every=self.every, takeover=takeover)
        return {"folder": folder.name, "offroad_events": rep["offroad_events"], "cte_mean": rep["cte_mean"],
                "distance_m": rep["distance_m"], **({"takeover_share": rep["takeover_share"]} if self.student else {})}


def drive_names(first_seed: int, n: int, styles: list[str], looks: str) -> tuple[tuple[str, int, bool], ...]:
    """(style, seed, random looks) of every drive: each seed in each style; with looks "mixed"
    every other seed has random looks."""
    if looks not in LOOKS:
        raise ValueError(f"looks {looks!r}: one of {', '.join(LOOKS)}")
    return tuple((style, s, looks == "random" or (looks == "mixed" and (s - first_seed) % 2 == 1))
                 for s in range(first_seed, first_seed + n) for style in styles)


def generate_pilot_drives(out: str | Path, n: int, first_seed: int = 1000, styles: tuple[str, ...] = ("via", "painted"),
                          seconds: float = 30.0, perturb: float = 0.3, every: int = 2, looks: str = "mixed",
                          fps: float = 30.0, workers: int = 1, resume: bool = False, student: str | Path = "",
                          takeover: float = 0.25) -> dict:
    """Record n seeds x len(styles) teacher drives of `seconds` simulated seconds into `out`
    (layout in the module docstring; with `student`, DAgger drives); returns the manifest."""
    if n < 1 or seconds <= 0 or every < 1 or not 0 <= perturb <= 1 or not 0 < takeover <= 2:
        raise ValueError(f"need n >= 1, seconds > 0, every >= 1, perturb in [0, 1] and takeover in (0, 2] "
                         f"(got {n}, {seconds}, {every}, {perturb}, {takeover})")
    student = str(student)
    if student:
        from signlane.pilot import PilotModel
        PilotModel(student)  # one clear line now for a missing file or a model that is no pilot
    out = Path(out)
    names = drive_names(first_seed, n, list(styles), looks)
    config = {"n": n, "first_seed": first_seed, "styles": list(styles), "seconds": seconds, "perturb": perturb,
              "every": every, "looks": looks, "fps": fps,
              **({"student": student, "takeover": takeover} if student else {})}
    manifest = prepare_output(out, "pilot", config, resume)
    if manifest is not None:
        return manifest
    job = PilotDriveJob(str(out), names, float(seconds), float(perturb), int(every), float(fps), student,
                        float(takeover))
    scores = run_indexed(len(names), job, workers, desc="student drives" if student else "teacher drives",
                         done_fn=job.done, chunk=1)
    drives = []
    for i in range(len(names)):
        m = json.loads((job.folder(i) / "manifest.json").read_text())
        score = {k: v for k, v in scores.get(i, {}).items() if k != "folder"}  # none for drives done before a resume
        drives.append({"folder": f"{DRIVES}/{job.folder(i).name}", "frames": m["counts"]["frames"], **m["drive"],
                       **score})
    counts = {"drives": len(drives), "frames": sum(d["frames"] for d in drives)}
    manifest = write_manifest(out, "pilot", first_seed, counts, config, drives=drives)
    log.info("%s: %d drives, %d frames", out, counts["drives"], counts["frames"])
    return manifest

